"""dataset.json manifests (docs/guide/theory.rst, 'Interfaces')."""

from __future__ import annotations

import json

import pytest

from imunoise.errors import DataError
from imunoise.io.dataset import read_dataset


def test_shared_drive_manifest(shared_data):
    ds = read_dataset(shared_data("rtklibexplorer_drive0708"))
    assert ds.imu.name == "imu_body_inc.txt.gz" and ds.imu.exists()
    assert ds.ref is not None and ds.outages is not None
    assert ds.lever_arm_m == (0.0, -0.05, 0.0)
    assert ds.imu_time_offset_s == 0.0
    assert ds.extra["imu_rate_hz"] == 100.0


def test_manifest_validation(tmp_path):
    (tmp_path / "imu.txt").write_text("0 0 0 0 0 0 0\n")
    (tmp_path / "gnss.txt").write_text("0 0 0 0 1 1 1\n")
    good = {"name": "x", "imu": "imu.txt", "gnss": "gnss.txt", "lever_arm_m": [0.1, 0, -0.2]}
    (tmp_path / "dataset.json").write_text(json.dumps(good))
    ds = read_dataset(tmp_path / "dataset.json")
    assert ds.root == tmp_path.resolve() and ds.lever_arm_m == (0.1, 0.0, -0.2) and ds.ref is None
    for bad, msg in [
        ({**good, "ref": "missing.nav"}, "does not exist"),
        ({**good, "lever_arm_m": [0, 1]}, "lever_arm_m"),
        ({**good, "imu_kind": "counts"}, "imu_kind"),
        ({"name": "x", "imu": "imu.txt"}, "gnss"),
    ]:
        (tmp_path / "dataset.json").write_text(json.dumps(bad))
        with pytest.raises(DataError, match=msg):
            read_dataset(tmp_path)
    with pytest.raises(DataError, match="no dataset.json"):
        read_dataset(tmp_path / "nowhere")


def test_load_axis_models_reads_the_multi_axis_model_file(tmp_path):
    """The file written by `imunoise fit --columns ...` feeds `imunoise nav --model` axis by axis (through the one
    door: a Gauss-Markov process slower than the fold time of 1 s stays as fitted)."""
    from imunoise import AR1, WN
    from imunoise.nav.defaults import load_axis_models
    from imunoise.noise.estimator import gmwm
    from imunoise.noise.imu_model import ImuModel

    fits = {}
    for i, axis in enumerate(("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")):
        truth = AR1(phi=0.999, sigma2=1e-8 * (i + 1)) + WN(sigma2=1e-6 * (i + 1))
        fits[axis] = gmwm(truth.unknown(), truth.simulate(8192, seed=i), freq=100.0, unit="rad/s" if i < 3 else "m/s²")
    path = ImuModel.from_fits(fits).save(tmp_path / "imu_model.json")
    models = load_axis_models(str(path), 100.0)
    assert len(models) == 6
    from imunoise.nav.filter_model import AxisFit, filter_axis_models

    for model, axis in zip(models, fits):
        assert model.freq == 100.0
        fit = fits[axis]  # the file's fit, through the one door with the horizon of the WV it was fitted on
        (expected,) = filter_axis_models([AxisFit(fit.model, 100.0, float(fit.wv.scales[-1]))], 100.0, [None])
        assert model == expected and str(model) != ""
