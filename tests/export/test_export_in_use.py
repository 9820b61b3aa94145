"""In-use values in every export (imunoise.export.in_use): a model with an in-motion part writes the static pair
times its in-use/static factors, read back with each tool's own parser and reads (the readers reproduced in
tests/export/test_export_clients.py and tests/export/test_export_vins_lio.py, which cite the tools' source files
and lines); ``--noise static`` writes the static pair; a model without the part exports exactly as before."""

from __future__ import annotations

import copy
import shutil

import pytest
from test_export_clients import FIX
from test_export_vins_lio import KEYS
from tool_reads import carried_nk, tool_reads

from imunoise.cli import main
from imunoise.errors import ModelError
from imunoise.export import export_text, model_sensors, read_export, sensor_noise, update_into, write_export
from imunoise.export.in_use import InUseNoise, apply_noise
from imunoise.export.vins_lio import tool_values
from imunoise.noise.estimator import gmwm
from imunoise.noise.imu_model import ImuModel, load_model
from imunoise.noise.model import Model

F = 200.0
AXES = ["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"]
FACTORS = {  # (factor_N, ci), (factor_K, ci) per axis; accel_x's bias is bounded, accel_z has no estimate
    "gyro_x": ((2.0, (1.7, 2.4)), (3.0, (2.0, 4.5))),
    "gyro_y": ((2.5, (2.1, 3.0)), (1.5, (0.8, 2.6))),
    "gyro_z": ((1.2, (0.9, 1.6)), (1.1, (0.7, 1.9))),
    "accel_x": ((1.5, (1.3, 1.8)), None),
    "accel_y": ((1.1, (0.95, 1.3)), (2.0, (1.4, 2.9))),
}
BOUND = {"what": "bias", "upper": 4.0, "reason": "no turns: the bias wander is not separable from the attitude"}


@pytest.fixture(scope="module")
def static_model() -> ImuModel:
    fits = {}
    for i, a in enumerate(AXES):
        gyro = a.startswith("gyro")
        s = 1.0 + 0.1 * i
        p = {"WN.sigma2": (1e-6 if gyro else 4e-4) * s, "RW.gamma2": (1e-12 if gyro else 1e-9) * s}
        x = Model.parse("WN+RW").with_params(p).simulate(2**12, seed=3)
        fits[a] = gmwm("WN+RW", x, freq=F, unit="rad/s" if gyro else "m/s²", n_random=4, n_local=2)
    return ImuModel.from_fits(fits, source={"topic": "/sensors/imu"})


def _part() -> dict:
    axes = {}
    for a, (fn, fk) in FACTORS.items():
        axes[a] = {"factor_N": {"value": fn[0], "ci95": list(fn[1])}}
        if fk:
            axes[a]["factor_K"] = {"value": fk[0], "ci95": list(fk[1])}
    return {"axes": axes, "bounds": {"accel_x": dict(BOUND)},
            "evidence": {"drives": ["d1", "d2"], "hours_moving": 0.5, "gnss_sigma_m": 1.0, "method": "ML",
                         "freq_hz": F}}


@pytest.fixture(scope="module")
def model(static_model) -> ImuModel:
    m = copy.deepcopy(static_model)
    m.in_motion = _part()
    return m


def expected(static_model, sensor: str) -> tuple[float, float]:
    """The in-use (N, K) of a sensor by hand: per axis the static pair times its factor (1 where none), maximum."""
    sn = sensor_noise(static_model, sensor)
    n = max(a.N * FACTORS.get(a.axis, ((1.0, ()), None))[0][0] for a in sn.axes)
    k = max(a.K * ((FACTORS.get(a.axis) or (None, None))[1] or (1.0, ()))[0] for a in sn.axes)
    return n, k


def test_in_use_values_are_the_static_pair_times_the_factors(model, static_model):
    sensors = model_sensors(model, None, "max", None)
    for s in ("gyro", "accel"):
        assert isinstance(sensors[s], InUseNoise)
        assert (sensors[s].noise_density, sensors[s].random_walk) == pytest.approx(expected(static_model, s), rel=1e-12)
    g = sensors["gyro"].in_use
    st = sensor_noise(static_model, "gyro")
    assert g.factor_N.value == pytest.approx(sensors["gyro"].noise_density / st.noise_density, rel=1e-12)
    # the interval: the same maximum over each axis's interval end, over the static combined value
    lo = max(a.N * FACTORS[a.axis][0][1][0] for a in st.axes) / st.noise_density
    hi = max(a.N * FACTORS[a.axis][0][1][1] for a in st.axes) / st.noise_density
    assert (g.factor_N.lo, g.factor_N.hi) == pytest.approx((lo, hi), rel=1e-12)
    assert g.factor_N.lo <= g.factor_N.value <= g.factor_N.hi
    # the static side and the inflation: in-use x inflate, the static value beside it inflated alike
    infl = model_sensors(model, None, "max", {"white": 2.0, "rw": 3.0})["gyro"]
    assert infl.noise_density == pytest.approx(2.0 * sensors["gyro"].noise_density, rel=1e-12)
    assert infl.in_use.static.random_walk == pytest.approx(3.0 * st.random_walk, rel=1e-12)


@pytest.mark.parametrize("fmt", ["kalibr", "openvins", "orbslam3", "vins", "lio-sam", "fast-lio"])
def test_every_tool_reads_the_in_use_values(tmp_path, model, static_model, fmt):
    got = carried_nk(fmt, tool_reads(fmt, write_export(model, fmt, tmp_path / fmt)), F)
    rel = 1e-6 if fmt == "lio-sam" else 1e-9  # LIO-SAM: nh.param<float>
    for s in ("gyro", "accel"):  # the tool's covariance grows as the in-use continuous model's
        assert got[s] == pytest.approx(expected(static_model, s), rel=rel)


def test_each_key_says_both_values_and_the_factor_with_its_interval(model, static_model):
    text = export_text(model, "kalibr")
    st = sensor_noise(static_model, "gyro")
    line = next(ln for ln in text.splitlines() if ln.startswith("gyroscope_noise_density:"))
    g = model_sensors(model, None, "max", None)["gyro"].in_use.factor_N
    assert f"in-use N = {g.value:.3g}x static (95 % CI {g.lo:.3g}-{g.hi:.3g})" in line
    assert float(line.split("; static ")[1].split(" ")[0]) == st.noise_density
    # the bounded axis: static value written, the bound and its reason said
    acc_k = next(ln for ln in text.splitlines() if ln.startswith("accelerometer_random_walk:"))
    assert "accel_x (bounded (bias <= 4 m/s^2: no turns" in acc_k and "accel_z (no in-motion estimate)" in acc_k
    assert "IN-USE values" in text and "--noise static" in text and "2 drive(s), 0.5 h moving" in text


def test_a_wander_without_a_k_factor_is_said_not_called_no_estimate(static_model):
    """A wander estimated on an axis whose static filter model has no random walk has no K factor (nothing to
    scale): the key keeps the static K and says the wander is there, with its numbers."""
    m = copy.deepcopy(static_model)
    m.in_motion = {"axes": {"accel_x": {"factor_N": {"value": 2.0, "ci95": [1.8, 2.2]},
                                        "factor_K": {"value": None, "ci95": None},
                                        "bias": {"model": "gm", "sigma": 0.055, "tau_s": 513.0}}}}
    text = export_text(m, "kalibr")
    line = next(ln for ln in text.splitlines() if ln.startswith("accelerometer_random_walk:"))
    assert float(line.split(": ")[1].split(" ")[0]) == sensor_noise(static_model, "accel").random_walk
    assert "accel_x (bias wander while moving GM sigma 0.055 m/s^2, tau 513 s has no K factor" in line
    assert "accel_y (no in-motion estimate)" in line


@pytest.mark.parametrize("fmt", ["vins", "lio-sam", "fast-lio"])
def test_vins_lio_sam_fast_lio_say_the_static_value_in_their_own_convention(model, static_model, fmt):
    text = export_text(model, fmt)
    static = tool_values(sensor_noise(static_model, "gyro"), fmt)
    line = next(ln for ln in text.splitlines() if ln.strip().startswith(KEYS[fmt][2] + ":"))
    assert float(line.split("; static ")[1].split(" ")[0]) == static[0] and "in-use N = " in line


def test_noise_static_writes_the_static_pair_and_no_part_is_unchanged(tmp_path, model, static_model, capsys):
    for fmt in ("kalibr", "openvins", "orbslam3", "vins", "lio-sam", "fast-lio"):
        a = export_text(model, fmt, noise="static").splitlines()
        b = export_text(static_model, fmt).splitlines()
        assert [ln for ln in a if "written by imunoise" not in ln] == [ln for ln in b if "written by" not in ln]
        assert "in-use" not in "\n".join(a)
    # without the part the static objects themselves are written: the export path is the one of before
    stat = model_sensors(static_model, None, "max", None, noise="static")
    assert apply_noise(static_model, stat, "in-use") is stat
    assert "in_motion" not in static_model.to_dict()
    mp = model.save(tmp_path / "imu_model.json")
    back = model_sensors(load_model(mp), None, "max", None)  # the part survives the file
    assert [(x.noise_density, x.random_walk) for x in back.values()] == [
        (x.noise_density, x.random_walk) for x in model_sensors(model, None, "max", None).values()]
    assert main(["export", str(mp), "--to", "kalibr", "--noise", "static", "--out", str(tmp_path / "s.yaml")]) == 0
    assert main(["export", str(mp), "--to", "kalibr", "--out", str(tmp_path / "u.yaml")]) == 0
    err = capsys.readouterr().err
    assert "gyro: in-use pair written: N = " in err and "in-use N = " in err
    s, u = read_export(tmp_path / "s.yaml"), read_export(tmp_path / "u.yaml")
    assert s["gyroscope_noise_density"] == sensor_noise(static_model, "gyro").noise_density
    assert u["gyroscope_noise_density"] == pytest.approx(expected(static_model, "gyro")[0], rel=1e-12)


@pytest.mark.parametrize("fmt,fixture", [("kalibr", "kalibr_imu.yaml"), ("orbslam3", "orbslam3_euroc_v1.yaml"),
                                         ("vins", "vins_fusion_euroc_stereo_imu_config.yaml"),
                                         ("fast-lio", "fast_lio_avia.yaml")])
def test_into_writes_the_in_use_values_with_their_comment(tmp_path, model, static_model, fmt, fixture):
    path = tmp_path / fixture
    shutil.copyfile(FIX / fixture, path)
    update_into(model, fmt, path)
    got = carried_nk(fmt, tool_reads(fmt, path), F)
    assert got["gyro"][0] == pytest.approx(expected(static_model, "gyro")[0], rel=1e-12)
    text = path.read_text()
    assert "in-use N = " in text and "; static " in text


def test_a_factor_outside_its_interval_is_refused_in_one_line(static_model):
    m = copy.deepcopy(static_model)
    m.in_motion = {"axes": {"gyro_x": {"factor_N": {"value": 3.0, "ci95": [1.0, 2.0]}}}}
    with pytest.raises(ModelError, match=r"in_motion.axes.gyro_x.factor_N: in-use factor 3.0"):
        export_text(m, "kalibr")
    # the model file's normal form (a factor not identified is null, its bound says why): static kept, said so
    m.in_motion = {"axes": {"gyro_x": {"white_factor": {"value": 1.0, "ci95": None},
                                       "factor_N": {"value": None, "ci95": None},
                                       "factor_K": {"value": 2.0, "ci95": [1.5, 2.5]}}},
                   "bounds": {"gyro_x": {"what": "white", "upper": None, "reason": "too short"}}}
    text = export_text(m, "kalibr")
    line = next(ln for ln in text.splitlines() if ln.startswith("gyroscope_noise_density:"))
    assert "in-use N = static" in line and "gyro_x (bounded (white not even bounded: too short))" in line
    assert float(line.split(": ")[1].split(" ")[0]) == sensor_noise(static_model, "gyro").noise_density
    with pytest.raises(ModelError, match="--noise must be one of"):
        model_sensors(m, None, "max", None, noise="moving")
