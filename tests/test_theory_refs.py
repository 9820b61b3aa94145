"""The theory the code cites is in the repository: docs/guide/theory.rst.

Docstrings, comments, help texts and Markdown cite a section as ``docs/guide/theory.rst, 'Title'`` (several as
``'A' and 'B'``); reStructuredText pages use ``:ref:`theory-...```. Every such reference must name a section of
that page that carries a label, and no reference to the unshipped specification ("SPEC" followed by a section
sign) may remain anywhere in the repository.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
THEORY = ROOT / "docs" / "guide" / "theory.rst"
OLD = "SPEC " + "\u00a7"  # spelled in two pieces so that this file does not match itself
WRITTEN = re.compile(r"docs/guide/theory\.rst, '([^']+)'((?: and '[^']+')*)")
REF = re.compile(r":ref:`(?:[^`<]*<)?(theory[\w-]*)>?`")
TEXT_SUFFIXES = {".py", ".rst", ".md", ".txt", ".toml", ".cfg", ".yaml", ".yml", ".json", ".ini", ""}


def repo_files() -> list[Path]:
    """The tracked text files (git ls-files), or every file outside hidden and output folders without git."""
    try:
        out = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout
        paths = [ROOT / line for line in out.splitlines() if line]
    except (OSError, subprocess.CalledProcessError):
        paths = [p for p in ROOT.rglob("*") if not any(part.startswith(".") or part in ("out", "sim")
                                                     for part in p.relative_to(ROOT).parts[:1])]
    return [p for p in paths if p.is_file() and p.suffix in TEXT_SUFFIXES]


def sections() -> dict[str, str]:
    """{title: label} of every section of the theory page that has a label right above it."""
    lines = THEORY.read_text(encoding="utf-8").splitlines()
    out: dict[str, str] = {}
    for i in range(2, len(lines) - 1):
        title, under = lines[i], lines[i + 1]
        if title.strip() and re.fullmatch(r"([-=~^])\1+", under) and len(under) >= len(title):
            above = [x for x in lines[max(0, i - 3):i] if x.strip()]
            m = re.fullmatch(r"\.\. _([\w-]+):", above[-1]) if above else None
            if m:
                out[title] = m.group(1)
    return out


def labels() -> set[str]:
    return set(re.findall(r"^\.\. _([\w-]+):\s*$", THEORY.read_text(encoding="utf-8"), flags=re.MULTILINE))


def cited_titles(text: str) -> list[str]:
    titles = []
    for m in WRITTEN.finditer(text):
        titles.append(m.group(1))
        titles += re.findall(r"'([^']+)'", m.group(2))
    return titles


def test_the_theory_page_has_its_sections_and_is_in_the_guide():
    secs = sections()
    for title in ("Conventions", "Latent processes", "Wavelet variance", "GMWM estimator", "Model selection",
                  "Static detection", "Navigation filter"):
        assert title in secs, f"docs/guide/theory.rst lacks a labelled section {title!r}"
    assert "guide/theory" in (ROOT / "docs" / "index.rst").read_text(encoding="utf-8")


def test_no_reference_to_the_unshipped_specification_remains():
    hits = []
    for path in repo_files():
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue
        hits += [f"{path.relative_to(ROOT)}:{n}" for n, line in enumerate(text.splitlines(), 1) if OLD in line]
    assert not hits, f"{len(hits)} reference(s) to a document the repository does not ship: {hits[:20]}"


def test_every_theory_reference_points_to_an_existing_section():
    secs, labs = sections(), labels()
    bad, n_written, n_ref = [], 0, 0
    for path in repo_files():
        if path.resolve() == Path(__file__).resolve():  # its own examples of the pattern, wrong ones included
            continue
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue
        rel = path.relative_to(ROOT)
        for title in cited_titles(text):
            n_written += 1
            if title not in secs:
                bad.append(f"{rel}: '{title}' is not a labelled section title of docs/guide/theory.rst")
        for label in REF.findall(text):
            n_ref += 1
            if label not in labs:
                bad.append(f"{rel}: :ref:`{label}` has no label in docs/guide/theory.rst")
    assert not bad, "\n".join(bad)
    # the code cites the page hundreds of times: a pattern that matched nothing would make this test vacuous
    assert n_written > 100 and n_ref >= 3, (n_written, n_ref)


def test_the_reference_parser_reads_one_and_several_sections():
    assert cited_titles("(docs/guide/theory.rst, 'Conventions' and 'Wavelet variance'; Eq. 4)") == [
        "Conventions", "Wavelet variance"]
    assert cited_titles("docs/guide/theory.rst, 'No such section'") == ["No such section"]
    assert "No such section" not in sections()
