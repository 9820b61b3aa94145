"""scipy.linalg deferred (imunoise.cli.scipy_defer): numba's kernels, BLAS calls included, run without the
scipy.linalg package having run; the package runs, complete, when something uses it; `nav --no-plots` leaves
it unrun. Each check in a fresh interpreter (the deferral acts once per process)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
DRIVE = REPO / "data" / "drive_0708"
RAN = "scipy.linalg._basic"  # a module scipy.linalg's __init__ imports: present once the package has run


def _fresh(code: str) -> dict:
    env = dict(os.environ, PYTHONPATH=str(REPO / "src") + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_blas_kernels_run_before_the_package_and_the_package_runs_when_used():
    got = _fresh(
        "import json, sys\n"
        "from imunoise.cli.scipy_defer import defer_scipy_linalg\n"
        "first = defer_scipy_linalg()\n"
        "again = defer_scipy_linalg()\n"
        "import numpy as np\n"
        "from numba import njit\n"
        "f = njit(lambda a, b: a @ b)\n"  # a BLAS gemm through scipy.linalg.cython_blas
        "a = np.arange(9.0).reshape(3, 3)\n"
        "ok = bool((f(a, a) == a @ a).all())\n"
        f"before = {RAN!r} in sys.modules\n"
        "import scipy.linalg\n"
        "inv = scipy.linalg.inv(np.diag([2.0, 4.0])).tolist()\n"
        f"after = {RAN!r} in sys.modules\n"
        "same = scipy.linalg.cython_blas is sys.modules['scipy.linalg.cython_blas']\n"
        "print(json.dumps([first, again, ok, before, inv, after, same]))\n"
    )
    assert got == [True, False, True, False, [[0.5, 0.0], [0.0, 0.25]], True, True]


def test_nothing_changes_when_scipy_linalg_is_imported_already():
    got = _fresh(
        "import json, sys, scipy.linalg\n"
        "from imunoise.cli.scipy_defer import defer_scipy_linalg\n"
        "m = sys.modules['scipy.linalg']\n"
        "print(json.dumps([defer_scipy_linalg(), sys.modules['scipy.linalg'] is m]))\n"
    )
    assert got == [False, True]


@pytest.mark.skipif(not (DRIVE / "dataset.json").exists(), reason="data/drive_0708 not in this checkout")
def test_nav_no_plots_leaves_scipy_linalg_unrun(tmp_path):
    got = _fresh(
        "import json, sys\n"
        "import imunoise.cli\n"
        f"code = imunoise.cli.main(['nav', '--data', {str(DRIVE)!r}, '--no-plots', '--end', '243300', "
        f"'--out', {str(tmp_path / 'nav')!r}])\n"
        f"print(json.dumps([code, 'imunoise.nav.ekf' in sys.modules, {RAN!r} in sys.modules]))\n"
    )
    assert got == [0, True, False]
