"""Every fenced example of README.md runs as written (issue "Trustworthy outputs", acceptance 3).

The README's fenced blocks are collected in order: ```` ```bash ````, ```` ``` ```` (plain, shell) and
```` ```python ````. Shell blocks run in ``bash -e`` from a scratch copy of the repository root (``data/`` is
linked, ``scripts/`` and ``../shared/data`` too when present), with ``imunoise`` and ``python`` on PATH resolving to the
interpreter running the tests; Python blocks run as scripts with that interpreter. Blocks run in README
order, so a later example may use what an earlier one wrote (``out/gyro.csv``, ``sim/d1``, …), as a reader
following the README would.

An HTML comment right before a block changes how it is run:

* ``<!-- readme-test: skip REASON -->``: not run; reported as a skipped test with the reason.
* ``<!-- readme-test: slow REASON -->``: run by :func:`test_readme_slow_examples` (marked slow).
* ``<!-- readme-test: needs-shared -->``: needs ``../shared/data``; run by :func:`test_readme_shared_examples`
  (marked slow), which skips when the folder is absent.
* ``<!-- readme-test: inputs NAME... (why) -->``: the block reads a recording of the user's own; the test
  writes a simulated static recording under that name first (:func:`_make_inputs`, known names only).
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from conftest import REPO, SHARED_DATA

README = REPO / "README.md"
SHELL_LANGS = {"", "bash", "sh", "shell", "console"}
TAG = re.compile(r"^<!--\s*readme-test:\s*(skip|slow|needs-shared|inputs)\b\s*(.*?)\s*-->\s*$")
FENCE = re.compile(r"^```\s*([A-Za-z0-9_+-]*)\s*$")
TIMEOUT_S = 600


@dataclass(frozen=True)
class Block:
    line: int  # 1-based line of the opening fence
    lang: str  # "shell" or "python"
    code: str
    tag: str  # "", "skip", "slow", "needs-shared", "inputs"
    note: str  # reason / input names

    @property
    def label(self) -> str:
        first = next((ln for ln in self.code.splitlines() if ln.strip() and not ln.startswith("#")), "")
        return f"README.md:{self.line} ({self.lang}) {first[:70]}"


def parse_readme(text: str) -> list[Block]:
    """The fenced shell and Python blocks of ``text`` in order, with the tag of the comment before each."""
    blocks: list[Block] = []
    lines = text.splitlines()
    i = 0
    pending: tuple[str, str] | None = None
    while i < len(lines):
        line = lines[i]
        tag = TAG.match(line)
        if tag:
            pending = (tag.group(1), tag.group(2))
            i += 1
            continue
        fence = FENCE.match(line)
        if fence:
            lang = fence.group(1).lower()
            j = i + 1
            while j < len(lines) and not lines[j].startswith("```"):
                j += 1
            if j == len(lines):
                raise AssertionError(f"README.md:{i + 1}: unclosed code fence")
            code = "\n".join(lines[i + 1 : j]) + "\n"
            kind = "shell" if lang in SHELL_LANGS else "python" if lang == "python" else None
            if kind is not None:
                t, note = pending or ("", "")
                blocks.append(Block(i + 1, kind, code, t, note))
            elif pending is not None:
                raise AssertionError(f"README.md:{i + 1}: readme-test tag before a ```{lang} block")
            pending = None
            i = j + 1
            continue
        if line.strip() and pending is not None:
            raise AssertionError(f"README.md:{i + 1}: a readme-test tag must come right before a code fence")
        i += 1
    return blocks


BLOCKS = parse_readme(README.read_text(encoding="utf-8"))


def _workdir(root: Path) -> Path:
    """A scratch 'repository root': data/ linked, ../shared/data linked when present, wrappers on PATH."""
    repo = root / "repo"
    repo.mkdir()
    (repo / "data").symlink_to(REPO / "data", target_is_directory=True)
    (repo / "scripts").symlink_to(REPO / "scripts", target_is_directory=True)  # README runs some scripts
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


def _static_imu(n: int, freq: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Simulated static IMU rates (gyro rad/s, accel m/s² with gravity on z): WN + RW per axis."""
    from imunoise.model import Model

    g = Model.parse("WN+RW").with_params({"WN.sigma2": (1.7e-4) ** 2 * freq, "RW.gamma2": (1.9e-5) ** 2 / freq})
    a = Model.parse("WN+RW").with_params({"WN.sigma2": (2e-3) ** 2 * freq, "RW.gamma2": (3e-4) ** 2 / freq})
    gyro = np.column_stack([g.simulate(n, seed=seed + k) for k in range(3)])
    accel = np.column_stack([a.simulate(n, seed=seed + 3 + k) for k in range(3)]) + [0.0, 0.0, 9.81]
    return gyro, accel


def _write_log(path: Path, n: int, seed: int) -> None:
    """CSV with a ns time stamp, gyro in deg/s and accel in g (the README's log.csv layout), 200 Hz."""
    gyro, accel = _static_imu(n, 200.0, seed)
    stamp = 1_700_000_000_000_000_000 + np.arange(n, dtype=np.int64) * 5_000_000
    with path.open("w") as fh:
        fh.write("stamp,gx,gy,gz,ax,ay,az\n")
        for k in range(n):
            g, a = np.degrees(gyro[k]), accel[k] / 9.80665
            fh.write(f"{stamp[k]},{g[0]:.9e},{g[1]:.9e},{g[2]:.9e},{a[0]:.9e},{a[1]:.9e},{a[2]:.9e}\n")


def _make_inputs(names: list[str], repo: Path) -> None:
    """Write the placeholder recordings a tagged block names (simulated static data, 200 Hz)."""
    from imunoise.io.rosbag import write_imu_bag

    for name in names:
        if name == "static_imu.mcap":
            n = 2**15
            gyro, accel = _static_imu(n, 200.0, seed=10)
            tmp = repo.parent / "bagtmp"
            written = write_imu_bag(tmp / "static_imu.mcap", 1.7e9 + np.arange(n) / 200.0, gyro, accel,
                                    topic="/imu0", frame_id="imu")
            shutil.move(str(written), repo / "static_imu.mcap")
        elif name == "log.csv":
            _write_log(repo / "log.csv", 2**14, seed=20)
        elif name == "logs/*.csv":
            (repo / "logs").mkdir(exist_ok=True)
            for k in range(3):
                _write_log(repo / "logs" / f"drive{k + 1}.csv", 2**13, seed=30 + 10 * k)
        else:
            raise AssertionError(f"the README test does not know how to write the input {name!r}")


def _input_names(note: str) -> list[str]:
    return [w for w in note.split("(")[0].split() if w]


def _run_block(block: Block, repo: Path) -> tuple[float, str | None]:
    """Run one block in ``repo``; (seconds, None) or (seconds, failure text)."""
    if block.tag == "inputs":
        _make_inputs(_input_names(block.note), repo)
    if block.lang == "shell":
        cmd = ["bash", "-e", "-o", "pipefail", "-c", block.code]
    else:
        script = repo.parent / f"readme_{block.line}.py"
        script.write_text(block.code)
        cmd = [sys.executable, str(script)]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, cwd=repo, env=_env(repo), capture_output=True, text=True, timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        return time.perf_counter() - t0, f"{block.label}: timed out after {TIMEOUT_S} s"
    dt = time.perf_counter() - t0
    if proc.returncode != 0:
        tail = "\n".join((proc.stdout + proc.stderr).strip().splitlines()[-15:])
        return dt, f"{block.label}: exit {proc.returncode}\n{tail}"
    return dt, None


def _run_all(blocks: list[Block], root: Path) -> None:
    assert blocks, "no README blocks of this kind: the tags changed?"
    repo = _workdir(root)
    failures, times = [], []
    for b in blocks:
        dt, err = _run_block(b, repo)
        times.append(f"{dt:6.1f} s  {b.label}")
        if err:
            failures.append(err)
    print("\n".join(times))
    assert not failures, "README examples failed:\n\n" + "\n\n".join(failures)


def test_readme_examples(tmp_path):
    """The untagged and 'inputs' blocks, in README order, in one scratch repository root."""
    _run_all([b for b in BLOCKS if b.tag in ("", "inputs")], tmp_path)


@pytest.mark.slow
def test_readme_slow_examples(tmp_path):
    """Blocks tagged slow (each replays the real drive several times)."""
    _run_all([b for b in BLOCKS if b.tag == "slow"], tmp_path)


@pytest.mark.slow
def test_readme_shared_examples(tmp_path, shared_data):
    """Blocks tagged needs-shared: they read ../shared/data (skipped when it is absent)."""
    shared_data()  # skips with the reason when ../shared/data is missing
    _run_all([b for b in BLOCKS if b.tag == "needs-shared"], tmp_path)


@pytest.mark.parametrize("block", [b for b in BLOCKS if b.tag == "skip"], ids=lambda b: f"line{b.line}")
def test_readme_skipped_blocks_are_reported(block):
    assert block.note, f"{block.label}: a skip tag needs a reason"
    pytest.skip(f"{block.label}: {block.note}")


def test_every_command_example_is_fenced():
    """An indented (unfenced) `imunoise` command would escape this test: there must be none."""
    in_fence = False
    for k, line in enumerate(README.read_text(encoding="utf-8").splitlines(), 1):
        if line.startswith("```"):
            in_fence = not in_fence
        elif not in_fence and re.match(r"^ {4,}(\$ )?(imunoise|python|make) ", line):
            raise AssertionError(f"README.md:{k}: command outside a fenced block: {line.strip()}")


def test_parser_reads_tags_and_languages():
    text = (
        "x\n<!-- readme-test: slow takes long -->\n```bash\nimunoise a\n```\n\n```python\nprint(1)\n```\n"
        "```yaml\nk: v\n```\n<!-- readme-test: inputs log.csv (your log) -->\n```\nimunoise b \\\n  c\n```\n"
    )
    got = parse_readme(text)
    assert [(b.line, b.lang, b.tag) for b in got] == [(3, "shell", "slow"), (7, "python", ""), (14, "shell", "inputs")]
    assert got[0].note == "takes long" and _input_names(got[2].note) == ["log.csv"]
    assert got[2].code == "imunoise b \\\n  c\n"
    with pytest.raises(AssertionError, match="right before"):
        parse_readme("<!-- readme-test: skip x -->\ntext\n```bash\nimunoise\n```\n")


# -- the fixes the README examples needed ------------------------------------------------------------------
def test_experiment_default_methods_pass_their_own_validation():
    """`imunoise experiment online --sim` used to fail on its own default list ('oracle')."""
    from imunoise.cli.experiment import select_methods
    from imunoise.errors import ImunoiseError
    from imunoise.experiments import denial, online_exp

    assert select_methods("online", True, None) == online_exp.MC_METHODS
    assert "oracle" in online_exp.MC_METHODS
    assert select_methods("online", False, None) == online_exp.METHODS
    assert select_methods("denial", True, None) == denial.METHODS
    assert select_methods("online", True, " plain, oracle ") == ("plain", "oracle")
    with pytest.raises(ImunoiseError, match=r"unknown method\(s\) \['oracle'\]"):
        select_methods("online", False, "plain,oracle")  # real data have no true model
    with pytest.raises(ImunoiseError, match="choose from"):
        select_methods("denial", True, "kalman")


def test_nav_model_accepts_a_one_axis_fit_and_the_simulator_truth(tmp_path):
    """`nav --model` with the model.json of `fit --column gyro_x`: that axis gets the fit, the rest the
    default; a fit of a column that names no axis is refused with what to do instead."""
    from imunoise.errors import ModelError
    from imunoise.nav.defaults import default_axis_models, load_axis_models

    fit = {
        "kind": "imunoise.fit",
        "model": "AR1 + WN",
        "params": {"AR1_1.phi": 0.99, "AR1_1.sigma2": 1e-8, "WN.sigma2": 1e-6},
        "freq_hz": 200.0,
        "unit": "rad/s",
        "extra": {"column": "gyro_y"},
    }
    default = default_axis_models(100.0)
    got = load_axis_models(fit, 100.0)
    assert str(got[1][0]) == "AR1 + WN" and got[1][1] == 200.0
    assert got[1][0].params == fit["params"]
    for a in (0, 2, 3, 4, 5):
        assert got[a][0].params == default[a][0].params and got[a][1] == 100.0
    with pytest.raises(ModelError, match=r"--columns gyro_x=COL.*imu_model\.json"):
        load_axis_models({**fit, "extra": {"column": "rate"}}, 100.0)
    truth = {"seed": 1, "models": {"gz": fit, "ax": {**fit, "unit": "m/s^2"}}}  # the layout of truth.json
    got = load_axis_models(truth, 100.0)
    assert str(got[2][0]) == "AR1 + WN" and str(got[3][0]) == "AR1 + WN"
    assert got[0][0].params == default[0][0].params
