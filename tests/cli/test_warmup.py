"""`imunoise warm-up` and the cold-cache notice (issue "Performance where users wait", first run).

The notice is checked both ways in fresh interpreters sharing one new ``NUMBA_CACHE_DIR``: the first process
compiles one small kernel (the Allan variance sums) and says so once on stderr; the second loads it from the
cache and says nothing. The warm-up's coverage of the real commands' kernel signatures is measured by
benchmarks/bench_first_run.py (a full warm-up compiles for minutes, too long for a test).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src"

PROBE = """
import sys
import numpy as np
from imunoise.cli.kernel_cache import announce_cold_cache
installed = announce_cold_cache(sys.argv[1])
from imunoise.noise.allan.variance import _avar_sums
c = np.concatenate([[0.0], np.cumsum(np.arange(64.0))])
out = _avar_sums(c, np.array([1, 2, 4], dtype=np.int64))
print(installed, "numba" in sys.modules, float(np.sum(out)))
"""


def _probe(command: str, cache: Path) -> subprocess.CompletedProcess:
    path = str(SRC) + os.pathsep + os.environ.get("PYTHONPATH", "")
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), PYTHONPATH=path)
    return subprocess.run([sys.executable, "-c", PROBE, command], env=env, capture_output=True, text=True,
                          timeout=600, check=True)


def test_cold_cache_notice_once_then_silent(tmp_path):
    from imunoise.cli.kernel_cache import COMPILE_ESTIMATE_S

    cold = _probe("allan", tmp_path)
    expected = (f"imunoise allan: compiling kernels (one time, ~{COMPILE_ESTIMATE_S['allan']} s; "
                "`imunoise warm-up` does it ahead)")
    assert cold.stderr.splitlines() == [expected]
    assert cold.stdout.split()[:2] == ["True", "True"]
    assert any(tmp_path.rglob("*.nbi")), "numba wrote no cache index into NUMBA_CACHE_DIR"

    warm = _probe("allan", tmp_path)  # same cache: loaded, not compiled
    assert warm.stderr == ""
    assert warm.stdout.split() == cold.stdout.split()  # same numbers from the cached machine code


def test_commands_without_kernels_install_nothing():
    from imunoise.cli.kernel_cache import announce_cold_cache

    assert announce_cold_cache("export") is False
    assert announce_cold_cache("warm-up") is False


def test_warm_up_groups_cover_every_command_that_runs_kernels():
    from imunoise.cli.kernel_cache import COMPILE_ESTIMATE_S
    from imunoise.cli.warmup import GROUPS

    covered = {c.strip() for _, commands, _ in GROUPS for c in commands.split(",")}
    assert {"nav", "online", "fit", "select", "calibrate", "experiment", "em", "allan"} <= covered
    assert covered <= set(COMPILE_ESTIMATE_S)  # each has an estimate for its notice


def test_a_failing_command_fails_the_warm_up(tmp_path):
    from imunoise.cli.warmup import _cli

    with pytest.raises(RuntimeError, match=r"`imunoise fit .*` exited 2"):
        _cli("fit", tmp_path / "missing.npy", "--freq", 100, "--model", "WN", "--out", tmp_path / "out")
    with pytest.raises(RuntimeError, match=r"`imunoise fit` exited 2"):
        _cli("fit")  # refused by argparse (SystemExit), reported the same way


def test_warm_up_is_a_command():
    from imunoise.cli import build_parser

    args = build_parser().parse_args(["warm-up", "--timings"])
    assert args.timings and args.func.__module__ == "imunoise.cli.warmup"


DEMO_ON_A_TINY_DRIVE = """
import sys
from pathlib import Path
root, cache_dir = Path(sys.argv[1]), Path(sys.argv[2])
from imunoise.sim import DriveConfig, simulate_drive
d = root / "drive"
simulate_drive(DriveConfig(duration_s=200.0, n_stops=1, stop_range_s=(25.0, 30.0), static_s=40.0,
                           outages=[(100.0, 15.0)], seed=3903), "mems", seed=3903).write(d)
def cache():
    return {str(p): p.stat().st_mtime_ns for p in cache_dir.rglob("*.nb*")}
before = cache()
from imunoise.cli.demo import run_online_demo
run_online_demo(root / "out", data=str(d), workers=1, evidence={"noise_seeds": (1,), "outages": "dense:15:20"})
after = cache()
print("NEW", *sorted(k for k in after if before.get(k) != after[k]))
"""


@pytest.mark.slow
def test_warm_up_covers_every_kernel_of_the_demo_and_the_default_methods(tmp_path):
    """After `imunoise warm-up`, the demo's methods (plain, AV, EM, GMWM, GMWM + ZUPT/ZARU and the dense-window
    evidence's static_var) on a tiny drive add nothing to numba's cache: no index or machine-code file is
    written or rewritten (numba rewrites a kernel's index when it compiles a new signature).

    The cache is a private ``NUMBA_CACHE_DIR`` (about a minute of compiling): in the checkout's own cache the
    suite's other workers compile kernels at the same time, and a rewrite of an index by one of them during
    the demo was read as the demo's own (a CI run failed that way on ``gnss_position_update``)."""
    cache_dir = tmp_path / "numba_cache"
    env = dict(os.environ, PYTHONPATH=str(SRC) + os.pathsep + os.environ.get("PYTHONPATH", ""),
               NUMBA_CACHE_DIR=str(cache_dir))
    subprocess.run([sys.executable, "-m", "imunoise", "warm-up"], env=env, capture_output=True, text=True,
                   timeout=3000, check=True)
    r = subprocess.run([sys.executable, "-c", DEMO_ON_A_TINY_DRIVE, str(tmp_path), str(cache_dir)], env=env,
                       capture_output=True, text=True, timeout=1800, check=True)
    assert any(cache_dir.rglob("*.nbi")), "the warm-up wrote no cache index into NUMBA_CACHE_DIR"
    new = r.stdout.strip().splitlines()[-1].split()
    assert new == ["NEW"], f"kernels the warm-up left cold: {new[1:]}"
