"""Millisecond stamps in a KF-GINS IMU file: `calibrate` applies the rule `fit` applies to a time column
(:func:`imunoise.io.time_column.infer_time_unit`): refused in one line naming the file and ``--time-unit ms``,
and read right with it."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from imunoise.cli import main
from imunoise.sim.drive import DriveConfig, simulate_drive


@pytest.fixture(scope="module")
def drive(tmp_path_factory) -> dict[str, Path]:
    """A 200 s simulated drive with a 40 s first stop and one more, its IMU file also with stamps in ms."""
    d = tmp_path_factory.mktemp("stamps")
    cfg = DriveConfig(duration_s=200.0, n_stops=1, stop_range_s=(25.0, 30.0), static_s=40.0, seed=4203)
    simulate_drive(cfg, "mems", seed=4203).write(d / "sim")
    data = np.loadtxt(d / "sim" / "imu.txt")
    ms = data.copy()
    ms[:, 0] *= 1000.0
    np.savetxt(d / "imu_s.txt", data, fmt="%.15g")
    np.savetxt(d / "imu_ms.txt", ms, fmt="%.15g")
    return {"s": d / "imu_s.txt", "ms": d / "imu_ms.txt", "root": d}


def test_calibrate_refuses_millisecond_stamps_read_as_seconds(drive, capsys):
    out = drive["root"] / "refused"
    code = main(["calibrate", str(drive["ms"]), "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert str(drive["ms"]) in err[0] and "0.1 Hz" in err[0] and err[0].endswith("give --time-unit ms")
    assert not out.exists() or not any(out.iterdir())
    # the same rule, the same advice, as fit on the same stamps
    code = main(["fit", str(drive["ms"]), "--column", "1", "--time-column", "0", "--model", "WN",
                 "--out", str(drive["root"] / "fit")])
    fit_err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and fit_err[-1].endswith("0.1 Hz, not an IMU rate; in ms it is 100 Hz: give --time-unit ms")
    assert err[0].endswith(fit_err[-1].split(": ", 2)[-1].split("': ", 1)[-1])


def test_calibrate_with_time_unit_ms_gives_the_model_of_the_seconds_file(drive, capsys):
    models = {}
    for name, extra in (("s", []), ("ms", ["--time-unit", "ms"])):
        out = drive["root"] / f"cal_{name}"
        assert main(["calibrate", str(drive[name]), *extra, "--out", str(out)]) == 0
        models[name] = json.loads((out / "imu_model.json").read_text())["axes"]
    capsys.readouterr()
    for axis, m in models["s"].items():
        for key, value in m["continuous"].items():
            # the stamps differ by the rounding of ×1000 then ×0.001 (1e-16 relative), nothing else
            assert models["ms"][axis]["continuous"][key] == pytest.approx(value, rel=1e-6), (axis, key)
