"""CLI start-up (architecture issue, acceptance 3): building the parser, which is all `imunoise --help` does,
imports no numerical library; the commands import them when they run. Checked in a fresh interpreter,
because this test process has imported numpy long ago."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src"
HEAVY = ("numpy", "scipy", "numba", "matplotlib", "dask", "rosbags")


def _modules_after(code: str) -> set[str]:
    env = dict(os.environ, PYTHONPATH=str(SRC) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    probe = code + "\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))\n"
    out = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, check=True).stdout
    return set(json.loads(out.strip().splitlines()[-1]))


def _heavy(modules: set[str]) -> list[str]:
    return sorted(m for m in modules if m.split(".")[0] in HEAVY)


def test_build_parser_imports_no_numerical_library():
    modules = _modules_after("import imunoise.cli\nparser = imunoise.cli.build_parser()")
    assert "imunoise.cli.fit" in modules and "imunoise.cli.nav" in modules  # every command was registered
    assert _heavy(modules) == []


def test_help_of_every_command_imports_no_numerical_library():
    # `imunoise CMD --help` exits from argparse before any handler: still nothing heavy
    code = (
        "import contextlib, io, imunoise.cli\n"
        "parser = imunoise.cli.build_parser()\n"
        "cmds = parser._subparsers._group_actions[0].choices\n"
        "assert len(cmds) >= 10, sorted(cmds)\n"
        "for cmd in cmds:\n"
        "    with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):\n"
        "        imunoise.cli.main([cmd, '--help'])\n"
    )
    assert _heavy(_modules_after(code)) == []


def test_probe_sees_a_heavy_import():
    # the check above can fail: a lazy export of the package does load numpy when used
    modules = _modules_after("import imunoise\nimunoise.WN(sigma2=1.0)")
    assert "numpy" in _heavy(modules)


@pytest.mark.parametrize("name", ["AR1", "Model", "as_model", "gmwm"])
def test_lazy_exports_are_the_objects_of_their_modules(name):
    import importlib

    import imunoise

    home = {"AR1": "imunoise.noise.processes", "Model": "imunoise.noise.model", "as_model": "imunoise.noise.model"}
    module = importlib.import_module(home.get(name, "imunoise.noise.estimator"))
    assert getattr(imunoise, name) is getattr(module, name)


DRIVE = SRC.parent / "data" / "drive_0708"


@pytest.mark.skipif(not (DRIVE / "dataset.json").exists(), reason="data/drive_0708 not in this checkout")
def test_nav_no_plots_imports_no_plotting_and_no_scipy_routine(tmp_path):
    # `nav --no-plots` draws nothing and calls no scipy routine: matplotlib stays out, and of scipy only what
    # numba itself loads for its BLAS/LAPACK bindings (scipy.linalg, at its first kernel call) is there
    code = (
        "import imunoise.cli\n"
        f"code = imunoise.cli.main(['nav', '--data', {str(DRIVE)!r}, '--no-plots', '--end', '243300', "
        f"'--out', {str(tmp_path / 'nav')!r}])\n"
        "assert code == 0, code\n"
    )
    modules = _modules_after(code)
    assert "imunoise.nav.ekf" in modules  # the filter ran
    assert not any(m.split(".")[0] == "matplotlib" for m in modules)
    numba_scipy = {"linalg", "_lib", "__config__", "version", "_distributor_init", "_distributor_init_local",
                   "_cyutility"}
    scipy = [m.split(".") for m in modules if m.split(".")[0] == "scipy"]
    extra = sorted(".".join(p) for p in scipy if len(p) > 1 and p[1] not in numba_scipy)
    assert extra == [], extra
