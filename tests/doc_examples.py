"""Run the examples of the README (Markdown) and of the user guide (reStructuredText) as written.

Shared by ``test_readme.py`` and ``test_guide_examples.py``. Code blocks are collected in document order:
Markdown fences ```` ```bash ````, ```` ``` ```` (shell) and ```` ```python ````; reStructuredText
``.. code-block:: bash|sh|shell|console|python`` at the start of a line (other languages, e.g. ``yaml`` or
``text``, are shown, not run). Shell blocks run in ``bash -e -o pipefail`` from a scratch copy of the
repository root (``data/`` and ``scripts/`` linked, ``../shared/data`` too when present) with ``imunoise`` and
``python`` on PATH resolving to the interpreter running the tests; Python blocks run as scripts with that
interpreter. Blocks of one document run in order in one scratch root, so a later example may read what an
earlier one wrote, as a reader following the page would.

How a block is run is set by a tag right before it (an HTML comment in Markdown, a comment in RST), or, for
a template, by the block's own visible first line:

* ``readme-test: skip REASON``: not run (a long evidence run; the reason gives its duration); reported as
  skipped with the reason.
* ``readme-test: slow REASON``: run by the slow test (marked slow).
* ``readme-test: needs-shared``: reads ``../shared/data``; run by a slow test that skips when it is absent.
* ``readme-test: inputs DEST=SRC [DEST=SRC ...]``: run like an untagged block, after copying each repository
  file SRC (under ``tests/fixtures/``) to DEST (relative, inside the scratch root) when DEST is not there yet:
  the stand-ins for files the reader has of their own (e.g. another tool's settings file that the example
  rewrites in place). The block's visible text says what the files are.
* a block whose first line starts with ``# template:`` needs a file only the reader has; the line, visible on
  the page, says what to put in. Not run; reported as skipped.

A block that prints ``warning: OPTION is deprecated`` (the CLI's notice for an old option name) fails: the
examples show the current names.

Timeouts are hang guards only (:data:`HANG_GUARD_S` per block), far above any expected duration: no test here
depends on the machine's speed.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import textwrap
import time
from dataclasses import dataclass
from pathlib import Path

from conftest import REPO, SHARED_DATA

SHELL_LANGS = {"", "bash", "sh", "shell", "console"}
HANG_GUARD_S = 3600  # per block; the slowest example run by the tests takes about 2 minutes on 2 cores
TEST_TIMEOUT_S = 4 * 3600  # per test (overrides `make test`'s --timeout): a hang guard for a list of blocks
TEMPLATE = "# template:"
MD_TAG = re.compile(r"^<!--\s*readme-test:\s*(skip|slow|needs-shared|inputs)\b\s*(.*?)\s*-->\s*$")
MD_FENCE = re.compile(r"^```\s*([A-Za-z0-9_+-]*)\s*$")
RST_TAG = re.compile(r"^\.\. readme-test:\s*(skip|slow|needs-shared|inputs)\b\s*(.*?)\s*$")
FIXTURES = "tests/fixtures/"
DEPRECATED = re.compile(r"\S+ is deprecated; use \S+")
RST_CODE = re.compile(r"^(\s*)\.\. (code-block|code|sourcecode)::\s*(\S*)\s*$")


@dataclass(frozen=True)
class Block:
    source: str  # file name relative to the repository, for messages
    line: int  # 1-based line of the opening fence / directive
    lang: str  # "shell" or "python"
    code: str
    tag: str  # "", "skip", "slow", "needs-shared", "template" (an ``inputs`` tag leaves it "")
    note: str  # the reason / the template line
    inputs: tuple[tuple[str, str], ...] = ()  # (DEST, SRC) of an ``inputs`` tag, copied in before the block

    @property
    def label(self) -> str:
        first = next((ln for ln in self.code.splitlines() if ln.strip() and not ln.startswith("#")), "")
        return f"{self.source}:{self.line} ({self.lang}) {first[:70]}"


def _kind(lang: str) -> str | None:
    lang = lang.lower()
    return "shell" if lang in SHELL_LANGS else "python" if lang == "python" else None


def parse_inputs(spec: str, where: str = "") -> tuple[tuple[str, str], ...]:
    """The (DEST, SRC) pairs of an ``inputs`` tag: ``DEST=SRC`` separated by spaces, SRC a file under
    tests/fixtures/, DEST a relative path that stays inside the scratch root."""
    pairs = []
    for item in spec.split():
        dest, eq, src = item.partition("=")
        if not eq or not dest or not src:
            raise AssertionError(f"{where}: readme-test inputs: {item!r} is not DEST=SRC")
        if not src.startswith(FIXTURES) or ".." in Path(src).parts:
            raise AssertionError(f"{where}: readme-test inputs: {src!r} must be a file under {FIXTURES}")
        if Path(dest).is_absolute() or ".." in Path(dest).parts:
            raise AssertionError(f"{where}: readme-test inputs: {dest!r} must be relative, inside the scratch root")
        pairs.append((dest, src))
    if not pairs:
        raise AssertionError(f"{where}: readme-test inputs: name at least one DEST=SRC")
    return tuple(pairs)


def _block(source: str, line: int, kind: str, code: str, pending: tuple[str, str] | None) -> Block:
    first = next((ln.strip() for ln in code.splitlines() if ln.strip()), "")
    if first.startswith(TEMPLATE):
        return Block(source, line, kind, code, "template", first[len(TEMPLATE):].strip())
    tag, note = pending or ("", "")
    if tag == "inputs":
        return Block(source, line, kind, code, "", note, parse_inputs(note, f"{source}:{line}"))
    return Block(source, line, kind, code, tag, note)


def parse_markdown(text: str, source: str = "README.md") -> list[Block]:
    """The fenced shell and Python blocks of Markdown ``text`` in order, with the tag before each."""
    blocks: list[Block] = []
    lines = text.splitlines()
    i, pending = 0, None
    while i < len(lines):
        line = lines[i]
        tag = MD_TAG.match(line)
        if tag:
            pending = (tag.group(1), tag.group(2))
            i += 1
            continue
        fence = MD_FENCE.match(line)
        if fence:
            j = i + 1
            while j < len(lines) and not lines[j].startswith("```"):
                j += 1
            if j == len(lines):
                raise AssertionError(f"{source}:{i + 1}: unclosed code fence")
            code = "\n".join(lines[i + 1 : j]) + "\n"
            kind = _kind(fence.group(1))
            if kind is not None:
                blocks.append(_block(source, i + 1, kind, code, pending))
            elif pending is not None:
                raise AssertionError(f"{source}:{i + 1}: readme-test tag before a ```{fence.group(1)} block")
            pending = None
            i = j + 1
            continue
        if line.strip() and pending is not None:
            raise AssertionError(f"{source}:{i + 1}: a readme-test tag must come right before a code fence")
        i += 1
    return blocks


def parse_rst(text: str, source: str) -> list[Block]:
    """The ``code-block`` directives of reStructuredText ``text`` in order, with the tag comment before each.

    Only blocks at the start of a line are supported (an indented one, e.g. inside a list, is refused so that
    no example escapes the tests), and ``::`` literal blocks are refused for the same reason."""
    blocks: list[Block] = []
    lines = text.splitlines()
    i, pending = 0, None
    while i < len(lines):
        line = lines[i]
        tag = RST_TAG.match(line)
        if tag:
            pending = (tag.group(1), tag.group(2))
            i += 1
            continue
        code = RST_CODE.match(line)
        if code:
            if code.group(1) or code.group(2) != "code-block":
                raise AssertionError(f"{source}:{i + 1}: use '.. code-block:: LANG' at the start of a line")
            j = i + 1
            while j < len(lines) and re.match(r"^\s+:[\w-]+:", lines[j]):  # directive options
                j += 1
            body: list[str] = []
            while j < len(lines) and (not lines[j].strip() or lines[j].startswith((" ", "\t"))):
                body.append(lines[j])
                j += 1
            src = textwrap.dedent("\n".join(body)).strip("\n") + "\n"
            kind = _kind(code.group(3))
            if kind is not None:
                blocks.append(_block(source, i + 1, kind, src, pending))
            elif pending is not None:
                raise AssertionError(f"{source}:{i + 1}: readme-test tag before a {code.group(3)} block")
            pending = None
            i = j
            continue
        if line.rstrip().endswith("::") and not line.startswith(".. "):
            raise AssertionError(f"{source}:{i + 1}: a '::' literal block escapes the example tests; "
                                 "use '.. code-block:: LANG'")
        if line.strip() and pending is not None:
            raise AssertionError(f"{source}:{i + 1}: a readme-test tag must come right before a code-block")
        i += 1
    return blocks


def guide_pages() -> list[Path]:
    """The guide's pages in the order of the documentation's table of contents (docs/index.rst)."""
    index = (REPO / "docs" / "index.rst").read_text(encoding="utf-8")
    names = re.findall(r"^\s+(guide/[\w-]+)\s*$", index, flags=re.MULTILINE)
    return [REPO / "docs" / f"{n}.rst" for n in names]


def guide_blocks() -> list[Block]:
    out: list[Block] = []
    for page in guide_pages():
        out += parse_rst(page.read_text(encoding="utf-8"), page.relative_to(REPO).as_posix())
    return out


def _workdir(root: Path) -> Path:
    """A scratch 'repository root': data/, scripts/ and tests/fixtures/ linked, ../shared/data when present,
    wrappers on PATH."""
    repo = root / "repo"
    repo.mkdir()
    (repo / "data").symlink_to(REPO / "data", target_is_directory=True)
    (repo / "scripts").symlink_to(REPO / "scripts", target_is_directory=True)  # some examples run scripts
    (repo / "tests").mkdir()  # the stand-ins of other tools' files that examples copy visibly (export --into)
    (repo / "tests" / "fixtures").symlink_to(REPO / "tests" / "fixtures", target_is_directory=True)
    if SHARED_DATA.exists():
        (root / "shared").mkdir()
        (root / "shared" / "data").symlink_to(SHARED_DATA, target_is_directory=True)
    bindir = root / "bin"
    bindir.mkdir()
    for name, body in (("imunoise", f'exec "{sys.executable}" -m imunoise "$@"'),
                       ("python", f'exec "{sys.executable}" "$@"')):
        p = bindir / name
        p.write_text(f"#!/bin/sh\n{body}\n")
        p.chmod(0o755)
    return repo


def _env(repo: Path) -> dict:
    env = dict(os.environ)
    env["PATH"] = f"{repo.parent / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    src = str(REPO / "src")
    env["PYTHONPATH"] = src + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    env["MPLBACKEND"] = "Agg"
    return env


def _copy_inputs(block: Block, repo: Path) -> None:
    """Copy the block's ``inputs`` fixtures into ``repo`` (a file already there, e.g. from an earlier block
    sharing it, is kept: the page's later examples see what the earlier ones made of it)."""
    for dest, src in block.inputs:
        source = REPO / src
        assert source.is_file(), f"{block.label}: readme-test inputs: no file {src}"
        target = repo / dest
        if not target.exists():
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(source, target)


def _run_block(block: Block, repo: Path) -> tuple[float, str | None]:
    """Run one block in ``repo``; (seconds, None) or (seconds, failure text)."""
    _copy_inputs(block, repo)
    if block.lang == "shell":
        cmd = ["bash", "-e", "-o", "pipefail", "-c", block.code]
    else:
        script = repo.parent / f"example_{Path(block.source).stem}_{block.line}.py"
        script.write_text(block.code)
        cmd = [sys.executable, str(script)]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, cwd=repo, env=_env(repo), capture_output=True, text=True, timeout=HANG_GUARD_S)
    except subprocess.TimeoutExpired:
        return time.perf_counter() - t0, f"{block.label}: no end after {HANG_GUARD_S} s (hung?)"
    dt = time.perf_counter() - t0
    if proc.returncode != 0:
        tail = "\n".join((proc.stdout + proc.stderr).strip().splitlines()[-15:])
        return dt, f"{block.label}: exit {proc.returncode}\n{tail}"
    old = sorted(set(DEPRECATED.findall(proc.stdout + proc.stderr)))
    if old:
        return dt, f"{block.label}: uses deprecated option(s): {'; '.join(old)}"
    return dt, None


def run_all(blocks: list[Block], root: Path) -> None:
    """Run ``blocks`` in order in one scratch root; every failure is collected, then reported together."""
    assert blocks, "no blocks of this kind: the tags changed?"
    repo = _workdir(root)
    failures, times = [], []
    for b in blocks:
        dt, err = _run_block(b, repo)
        times.append(f"{dt:6.1f} s  {b.label}")
        if err:
            failures.append(err)
    print("\n".join(times))
    assert not failures, "examples failed:\n\n" + "\n\n".join(failures)
