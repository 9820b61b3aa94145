"""One vocabulary (architecture issue): one AXES, one ImuData, one model-file reader/writer, one fit → filter
mapping, one version, one JSON default helper. AST checks over src/imunoise plus behaviour checks of the
shared pieces (old names and old truth files still read)."""

from __future__ import annotations

import ast
import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

import imunoise
from imunoise.imu import AXES, LEGACY_AXES, ImuData, canonical_axis

SRC = Path(__file__).resolve().parents[1] / "src" / "imunoise"
ROOT = SRC.parents[1]
AXIS_SETS = ({*AXES}, {*LEGACY_AXES})


def _modules() -> dict[str, ast.Module]:
    return {str(p.relative_to(SRC)): ast.parse(p.read_text(encoding="utf-8")) for p in sorted(SRC.rglob("*.py"))}


MODULES = _modules()


def _where(pred) -> list[str]:
    """``module:line`` of every node for which ``pred(node)`` holds."""
    return [f"{m}:{n.lineno}" for m, tree in MODULES.items() for n in ast.walk(tree) if pred(n)]


def _assigns(name: str):
    def pred(n) -> bool:
        if isinstance(n, ast.Assign):
            return any(isinstance(t, ast.Name) and t.id == name for t in n.targets)
        return isinstance(n, ast.AnnAssign) and isinstance(n.target, ast.Name) and n.target.id == name

    return pred


def _str_const(n, value: str) -> bool:
    return isinstance(n, ast.Constant) and n.value == value


def test_axes_assigned_once_and_no_other_axis_name_tuples():
    assert [w.split(":")[0] for w in _where(_assigns("AXES"))] == ["imu.py"]

    def axis_literal(n) -> bool:
        if not isinstance(n, (ast.Tuple, ast.List, ast.Set)) or len(n.elts) != 6:
            return False
        if not all(isinstance(e, ast.Constant) and isinstance(e.value, str) for e in n.elts):
            return False
        return {e.value for e in n.elts} in AXIS_SETS

    assert [w.split(":")[0] for w in _where(axis_literal)] == ["imu.py", "imu.py"]
    # every module that still exposes AXES exposes the same object
    from imunoise.experiments import common, plots
    from imunoise.io import imu_input
    from imunoise.nav import ekf, error_states
    from imunoise.sim import imu_errors

    for mod in (common, plots, imu_input, ekf, error_states, imu_errors):
        assert mod.AXES is AXES, mod.__name__


def test_canonical_axis_maps_both_spellings():
    assert [canonical_axis(a) for a in ("gx", "GY", "gz", "ax", "ay", "az")] == list(AXES)
    assert [canonical_axis(a.upper()) for a in AXES] == list(AXES)
    assert canonical_axis("rate") is None and canonical_axis("gyro") is None


def test_imudata_defined_once_old_import_path_is_an_alias():
    defs = _where(lambda n: isinstance(n, ast.ClassDef) and n.name == "ImuData")
    assert [d.split(":")[0] for d in defs] == ["imu.py"]
    from imunoise.io import kfgins
    from imunoise.io.kfgins import ImuData as OldImuData

    assert OldImuData is ImuData and "ImuData" in kfgins.__all__
    t = np.arange(1, 5) * 0.01
    d = ImuData(t, np.ones((4, 3)), 2 * np.ones((4, 3)), kind="rates").as_increments()
    np.testing.assert_allclose(d.dtheta, 0.01 * np.ones((4, 3)))


def test_simulator_produces_the_one_imudata_and_axes():
    from imunoise.sim import simulate_static

    rec = simulate_static({"gyro": "WN"}, 2.0, 50.0, seed=1)
    assert type(rec.imu) is ImuData
    assert tuple(rec.models) == AXES[:3] and tuple(rec.truth["models"]) == AXES[:3]
    assert rec.truth["turn_on_bias"]["axes"] == list(AXES)


def test_model_file_is_read_and_written_only_by_imu_model():
    kind = _where(lambda n: _str_const(n, "imunoise.noise.imu_model"))
    assert {k.split(":")[0] for k in kind} == {"noise/imu_model.py"}
    by_hand = ("nav/defaults.py", "cli/em.py", "cli/online.py", "cli/demo.py")

    def json_read(n) -> bool:
        f = n.func if isinstance(n, ast.Call) else None
        return isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) and f.value.id == "json" and (
            f.attr in ("load", "loads")
        )

    for m in by_hand:
        tree = MODULES[m]
        assert not [n.lineno for n in ast.walk(tree) if json_read(n)], m
        assert not [n.lineno for n in ast.walk(tree) if _str_const(n, "imunoise.fit")], m
    assert not [n.lineno for n in ast.walk(MODULES["nav/defaults.py"]) if _str_const(n, "axes")]


def test_load_axis_models_reads_old_and_new_truth_and_imu_model_files(tmp_path):
    """The simulator's truth.json with short (old) or AXES (new) keys, and the imu_model file written by
    ImuModel.save, give the same filter models through the one parser."""
    from imunoise.nav.defaults import default_axis_models, load_axis_models
    from imunoise.noise.imu_model import ImuModel, axis_fit_dicts
    from imunoise.noise.model import Model
    from imunoise.sim import simulate_static

    rec = simulate_static({"gyro": "WN + RW", "az": "AR1 + WN"}, 2.0, 100.0, seed=3)
    new = rec.truth
    old = {**new, "models": {s: new["models"][a] for s, a in LEGACY_AXES.items() if a in new["models"]}}
    assert set(old["models"]) == {"gx", "gy", "gz", "az"}
    (tmp_path / "old.json").write_text(json.dumps(old))
    a = load_axis_models(str(tmp_path / "old.json"), 100.0)
    b = load_axis_models(new, 100.0)
    default = default_axis_models(100.0)
    for j in range(6):
        assert a[j] == b[j] and a[j].freq == b[j].freq
    assert a[0] == rec.models["gyro_x"] and a[5] == rec.models["accel_z"]
    assert a[3] == default[3]
    assert list(axis_fit_dicts(old)) == ["gyro_x", "gyro_y", "gyro_z", "accel_z"]
    # the multi-axis file round-trips through its one writer and reader
    fit = {"kind": "imunoise.fit", "model": "WN", "params": {"WN.sigma2": 1e-6}, "freq_hz": 100.0, "unit": "rad/s"}
    p = ImuModel(100.0, {"gyro_y": fit}).save(tmp_path / "imu_model.json")
    assert ImuModel.load(p).axes == {"gyro_y": fit}
    assert json.loads(p.read_text())["imunoise_version"] == imunoise.__version__
    assert load_axis_models(p, 100.0)[1] == Model.from_dict(fit)


def _calls_in_functions(module: str, callee: str) -> list[str]:
    """Names of the functions of ``module`` whose body calls ``callee`` by name."""
    out = []
    for fn in ast.walk(MODULES[module]):
        if isinstance(fn, ast.FunctionDef) and any(
            isinstance(c, ast.Call) and getattr(c.func, "id", None) == callee for c in ast.walk(fn)
        ):
            out.append(fn.name)
    return out


def test_one_filter_mapping_used_by_engine_and_experiments():
    """The six-axis fit → filter loop exists once (online.filter_axis_models); the navigator and the
    experiments' fixed-model baselines both call it."""
    from imunoise.experiments.common import filter_models
    from imunoise.nav.defaults import default_axis_models
    from imunoise.noise.estimator import gmwm
    from imunoise.noise.processes import AR1, RW, WN
    from imunoise.online import OnlineConfig, data_horizon, ekf_axis_model, filter_axis_models

    # the one door: nav/filter_model.filter_model, called per axis by its filter_axis_models only (the engine's
    # ekf_axis_model is the same function under the name the engine has used)
    calls = _where(lambda n: isinstance(n, ast.Call) and getattr(n.func, "id", None) in ("ekf_axis_model",
                                                                                          "filter_model"))
    assert [c.split(":")[0] for c in calls] == ["nav/filter_model.py"]
    assert _calls_in_functions("nav/filter_model.py", "filter_model") == ["filter_axis_models"]
    assert "filter_models" in _calls_in_functions("online/navigator.py", "filter_axis_models")  # OnlineNavigator's
    assert _calls_in_functions("experiments/common.py", "filter_axis_models") == ["filter_models"]

    f = 100.0
    cfg = OnlineConfig()
    floor = default_axis_models(f, cfg.ekf.fallback)
    m = AR1(phi=0.999, sigma2=1e-10) + WN(sigma2=1e-6) + RW(gamma2=1e-14)
    rng = np.random.default_rng(5)
    fit = gmwm("WN + RW", rng.normal(0.0, 1e-3, 20000), freq=f, unit="rad/s")
    got = filter_models([m, None, fit, m, m, fit], f, cfg)
    assert got[0] == ekf_axis_model(m, f, floor[0]) and got[3] == ekf_axis_model(m, f, floor[3])
    assert got[1] == floor[1] and got[1].freq == f  # no fit: the plain default itself
    assert got[2] == ekf_axis_model(fit.model, fit.freq, floor[2], horizon=data_horizon(fit)) and got[2].freq == f
    assert data_horizon(fit) is not None
    bare = filter_axis_models([m] * 6, f, cfg.with_(floor="none"))
    assert all(b == ekf_axis_model(m, f, None) and b.freq == f for b in bare)


def test_version_has_one_home():
    assigns = _where(_assigns("__version__"))
    assert [a.split(":")[0] for a in assigns] == ["_version.py"]
    wrong = _where(lambda n: isinstance(n, ast.ImportFrom) and n.module == "imunoise"
                   and any(a.name == "__version__" for a in n.names))
    assert wrong == []
    from imunoise._version import __version__

    assert imunoise.__version__ is __version__
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "version" in pyproject["project"]["dynamic"]
    assert pyproject["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "imunoise._version.__version__"}


def test_one_json_default_helper():
    from imunoise.io.jsonutil import json_default

    helpers = _where(lambda n: isinstance(n, ast.FunctionDef) and ("json_default" in n.name or n.name == "_default"))
    assert [h.split(":")[0] for h in helpers] == ["io/jsonutil.py"]

    bad = []
    for m, tree in MODULES.items():
        # names bound to the helper in this module (``from imunoise.io.jsonutil import json_default [as x]``)
        ok = {"str"} | {a.asname or a.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)
                        and n.module == "imunoise.io.jsonutil" for a in n.names}
        for n in ast.walk(tree):
            if isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute) and n.func.attr in ("dump", "dumps"):
                bad += [f"{m}:{n.lineno}" for kw in n.keywords if kw.arg == "default"
                        and not (isinstance(kw.value, ast.Name) and kw.value.id in ok)]
    assert bad == []
    out = json.dumps({"a": np.arange(3), "b": np.float32(0.5), "c": np.bool_(True), "p": Path("x")},
                     default=json_default)
    assert json.loads(out) == {"a": [0, 1, 2], "b": 0.5, "c": True, "p": "x"}


def test_one_number_test_and_no_private_text_opener():
    from imunoise.io.files import is_number

    defs = _where(lambda n: isinstance(n, ast.FunctionDef) and n.name in ("_is_number", "is_number", "_open_text"))
    assert [d.split(":")[0] for d in defs] == ["io/files.py"]
    assert is_number("1e-3") and is_number(" -2 ") and not is_number("gx") and not is_number("")


@pytest.mark.parametrize("old", ["gw", "gyro_w"])
def test_sim_refuses_unknown_axis_names(old):
    from imunoise.errors import ModelError
    from imunoise.sim import resolve_imu_models

    with pytest.raises(ModelError, match="gyro_x"):
        resolve_imu_models({old: "WN"}, 100.0)
