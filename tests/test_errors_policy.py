"""Error policy (CONTRIBUTING, errors): imunoise raises the specific subclass of ImunoiseError, never the bare
base class or a bare ValueError, so callers can tell bad data from a bad model/option and the CLI can turn
every one of them into one line and exit 2."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import pytest

import imunoise
from imunoise import errors
from imunoise.errors import DataError, FitError, ImunoiseError, ModelError, UnitError

PACKAGE = Path(imunoise.__file__).parent
BANNED = {"ImunoiseError", "ValueError"}
# Explicit exemptions: module (relative to the package) -> banned names still raised there, with the reason.
EXEMPT: dict[str, set[str]] = {}


def _raised_names(tree: ast.AST) -> list[tuple[str, int]]:
    """(name, line) of every ``raise Name(...)`` / ``raise Name`` / ``raise mod.Name(...)`` in ``tree``."""
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Raise) and node.exc is not None:
            exc = node.exc.func if isinstance(node.exc, ast.Call) else node.exc
            name = exc.attr if isinstance(exc, ast.Attribute) else getattr(exc, "id", None)
            if name is not None:
                out.append((name, node.lineno))
    return out


def test_no_bare_base_or_value_error_is_raised():
    offenders = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).as_posix()
        for name, line in _raised_names(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if name in BANNED and name not in EXEMPT.get(rel, set()):
                offenders.append(f"{rel}:{line}: raise {name}")
    assert not offenders, "raise the specific imunoise.errors type instead:\n" + "\n".join(offenders)


def test_exemptions_are_still_needed():
    # an exemption that no longer matches anything would silently widen the policy: drop it instead
    for rel, names in EXEMPT.items():
        raised = {n for n, _ in _raised_names(ast.parse((PACKAGE / rel).read_text(encoding="utf-8")))}
        assert names <= raised, f"{rel}: exemption {sorted(names - raised)} is no longer needed"


def test_the_checker_sees_every_raise_form():
    src = "def f():\n    raise ValueError('x')\n    raise errors.ImunoiseError('y')\n    raise DataError\n"
    assert _raised_names(ast.parse(src)) == [("ValueError", 2), ("ImunoiseError", 3), ("DataError", 4)]


def test_every_specific_error_is_an_imunoise_error():
    specific = [c for _, c in inspect.getmembers(errors, inspect.isclass)
                if issubclass(c, Exception) and not issubclass(c, Warning) and c.__module__ == errors.__name__
                and c is not ImunoiseError]
    assert {DataError, ModelError, UnitError, FitError} <= set(specific)
    for cls in specific:
        assert issubclass(cls, ImunoiseError), cls
    # the value-type errors stay ValueErrors, so code catching ValueError around imunoise keeps working
    for cls in (DataError, ModelError, UnitError):
        assert issubclass(cls, ValueError)
    assert issubclass(FitError, RuntimeError)


def test_every_warning_class_lives_in_errors():
    """One warning path: the project's warning classes are defined in imunoise.errors (the readers re-export
    theirs under the old names), all ImunoiseWarnings and so UserWarnings."""
    import importlib

    defined = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).as_posix()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.ClassDef) and any(getattr(b, "id", getattr(b, "attr", "")).endswith("Warning")
                                                      for b in node.bases):
                defined.append(f"{rel}:{node.name}")
    assert defined and all(d.startswith("errors.py:") for d in defined), defined
    for mod, name in (("imunoise.io.kfgins", "DataWarning"), ("imunoise.io.time_stamps", "TimingWarning"),
                      ("imunoise.io.tabular", "TimingWarning"), ("imunoise.io.columns", "UnitWarning"),
                      ("imunoise.io.tabular", "UnitWarning"), ("imunoise.io.table", "CutLineWarning")):
        cls = getattr(importlib.import_module(mod), name)
        assert cls is getattr(errors, name) and issubclass(cls, errors.ImunoiseWarning)
        assert issubclass(cls, UserWarning)


def test_specific_types_on_converted_paths():
    from imunoise.online import OnlineConfig
    from imunoise.sim.drive import DriveConfig
    from imunoise.sim.static import simulate_static
    from imunoise.sim.trajectory import simpson_increments

    with pytest.raises(ModelError, match="dr must"):
        OnlineConfig(dr="x")
    with pytest.raises(ModelError, match="gnss_rate_hz 200 Hz exceeds imu_rate_hz 100 Hz"):
        DriveConfig(imu_rate_hz=100.0, gnss_rate_hz=200.0)
    with pytest.raises(ModelError, match="at least 2 samples, got 1"):
        simulate_static(None, duration_s=1.0, rate_hz=1.0)
    with pytest.raises(ModelError, match="sub=3"):
        simpson_increments(__import__("numpy").zeros((7, 3)), 0.1, 3)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["select", "x.csv", "--top", "0"], "--top must be ≥ 1"),
        (["em", "x.csv", "--model", "WN", "--init", "no-such.json"], "neither 'av' nor an existing"),
    ],
)
def test_cli_turns_them_into_one_line_and_exit_2(argv, message, tmp_path, capsys, monkeypatch):
    from imunoise.cli import main

    monkeypatch.chdir(tmp_path)
    (tmp_path / "x.csv").write_text("t,x\n" + "".join(f"{k / 100},{(-1) ** k}\n" for k in range(400)))
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err and "Traceback" not in err


@pytest.fixture(scope="module")
def drive_dir(tmp_path_factory):
    from imunoise.sim.drive import DriveConfig, simulate_drive

    cfg = DriveConfig(duration_s=120.0, n_stops=0, static_s=35.0, gnss_rate_hz=1.0, seed=3)
    return simulate_drive(cfg, "mems", seed=3).write(tmp_path_factory.mktemp("drive"))


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--outage-runs"], "--outage-runs needs --outages F"),  # the dataset has no outage file
        (["--start", "1"], "--start 1.000 is outside the IMU data"),
    ],
)
@pytest.mark.parametrize("command", ["nav", "online"])
def test_nav_and_online_share_one_start(drive_dir, tmp_path, capsys, command, extra, message):
    # cli.navrun.read_nav_inputs and options.check_nav_span: the same refusal, in the same words, from both
    from imunoise.cli import main

    assert main([command, "--data", str(drive_dir), *extra, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"imunoise {command}: error: ") and message in err and "\n" not in err


def test_nav_end_before_start(drive_dir, tmp_path, capsys):
    from imunoise.cli import main

    t0 = float((drive_dir / "imu.txt").read_text().split(None, 1)[0]) + 40.0  # 40 s into the IMU file
    argv = ["nav", "--data", str(drive_dir), "--start", str(t0), "--end", str(t0 - 1), "--out", str(tmp_path / "o")]
    assert main(argv) == 2
    assert "must be after the start" in capsys.readouterr().err


def test_mean_end_drift_skips_windows_without_reference():
    from imunoise.nav.metrics import mean_end_drift

    assert mean_end_drift([{"end_horizontal_m": 1.0}, {"end_horizontal_m": None}, {"end_horizontal_m": 4.0}]) == 2.5
    assert mean_end_drift([{"end_horizontal_m": None}]) is None
    assert mean_end_drift([]) is None
