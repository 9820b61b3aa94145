"""Public API (issue "Trustworthy outputs" §2): exported names stay what they are, every estimator takes
a model the same way and in the same order, and bad rates, units and GNSS positions are refused."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import warnings

import numpy as np
import pytest

from imunoise import AR1, QN, WN, DataError, Model, ModelError, UnitError, as_model
from imunoise.noise.em import em_fit
from imunoise.noise.estimator import gmwm
from imunoise.noise.selection import refit, select_model

# One fresh interpreter: import every submodule first (importing the estimator's submodule, then called
# imunoise/gmwm.py, used to replace the exported function gmwm by the module), then use every exported
# name twice. Each name has its own check; a name added to __all__ without one fails the test.
FRESH = textwrap.dedent(
    """
    import dataclasses, importlib, pkgutil, types
    import numpy as np
    import imunoise

    subs = {m.name for m in pkgutil.iter_modules(imunoise.__path__)}
    clash = sorted(set(imunoise.__all__) & subs)
    assert not clash, f"exported names equal to submodule names: {clash}"
    for info in pkgutil.walk_packages(imunoise.__path__, "imunoise."):
        if not info.name.endswith("__main__"):  # __main__ runs the CLI
            importlib.import_module(info.name)

    # the README's first snippet, after every submodule is imported
    from imunoise import AR1, WN, RW, gmwm

    truth = AR1(phi=0.99, sigma2=1e-4) + WN(sigma2=1e-2)
    x = truth.simulate(2**13, seed=3)
    I = imunoise

    def check_fit(fit, structure):
        assert isinstance(fit, I.GMWMFit) and str(fit.model) == structure, fit.model
        phi = fit.params.get("AR1_1.phi")
        assert phi is None or abs(phi - 0.99) < 0.01, phi
        assert abs(fit.params["WN.sigma2"] / 1e-2 - 1) < 0.2, fit.params

    def error_class(cls):
        assert issubclass(cls, I.ImunoiseError) and isinstance(cls("why"), Exception)

    def process(cls, **params):
        def check():
            assert cls().kind == cls.__name__ and not cls().known
            assert cls(**params).known and str(I.as_model(cls)) == cls.__name__
        return check

    def state_space():
        ss = (WN(sigma2=1.0) + RW(gamma2=1e-6)).state_space(0.01, freq=100.0)
        assert isinstance(ss, I.StateSpace)
        again = I.StateSpace(*[getattr(ss, f.name) for f in dataclasses.fields(ss)])
        assert again.labels == ("bias",) and again.white_psd == ss.white_psd == 0.01

    def wv_accumulator():
        acc = I.WVAccumulator(freq=100.0)
        acc.add(x[:4000])
        acc.add(x[4000:])
        ref = I.wavelet_variance([x[:4000], x[4000:]], freq=100.0)
        assert np.allclose(acc.result().variance, ref.variance, rtol=1e-10, atol=0)

    def wv_stream():
        stream = I.WVStream(freq=100.0)
        for chunk in np.array_split(x, 7):
            stream.add(chunk)
        ref = I.wavelet_variance(x, freq=100.0)
        assert np.allclose(stream.result().variance, ref.variance, rtol=1e-10, atol=0)

    def select():
        ranking = I.select_model(x, freq=100.0, complete=AR1() + WN(), criterion="wvic")
        check_fit(ranking.best, "AR1 + WN")

    def fit_roundtrip():
        fit = gmwm(AR1() + WN(), x, freq=100.0)
        back = I.GMWMFit.from_dict(fit.to_dict())
        assert back.params == fit.params and back.freq == 100.0

    checks = {
        "AR1": process(I.AR1, phi=0.5, sigma2=1.0),
        "DR": process(I.DR, omega=1e-3),
        "QN": process(I.QN, q2=1e-4),
        "RW": process(I.RW, gamma2=1e-6),
        "WN": process(I.WN, sigma2=1.0),
        "Model": lambda: I.Model([WN()]) == I.Model.parse("WN") or 1 / 0,
        "StateSpace": state_space,
        "as_model": lambda: I.as_model("AR1+WN") == AR1() + WN() == I.as_model(AR1() + WN()) or 1 / 0,
        "wavelet_variance": lambda: isinstance(I.wavelet_variance(x, freq=100.0), I.WaveletVariance) or 1 / 0,
        "WVAccumulator": wv_accumulator,
        "WVStream": wv_stream,
        "WaveletVariance": lambda: I.WaveletVariance.from_dict(I.wavelet_variance(x, freq=2.0).to_dict()).freq == 2.0
        or 1 / 0,
        "gmwm": lambda: check_fit(I.gmwm(AR1() + WN(), x, freq=100.0), "AR1 + WN"),
        "GMWMFit": fit_roundtrip,
        "select_model": select,
        "refit": lambda: check_fit(I.refit("AR1+WN", x, freq=100.0), "AR1 + WN"),
        "em_fit": lambda: check_fit(I.em_fit(AR1() + WN(), x, freq=100.0, max_iter=300), "AR1 + WN"),
        "warm_up": lambda: I.warm_up()["kernels"] >= 4 or 1 / 0,
        "ImunoiseError": lambda: error_class(I.ImunoiseError),
        "DataError": lambda: error_class(I.DataError),
        "ModelError": lambda: error_class(I.ModelError),
        "UnitError": lambda: error_class(I.UnitError),
        "FitError": lambda: error_class(I.FitError),
        "__version__": lambda: isinstance(I.__version__, str) or 1 / 0,
    }
    assert sorted(checks) == sorted(I.__all__), sorted(set(checks) ^ set(I.__all__))
    for round_ in range(2):
        for name in I.__all__:
            obj = getattr(I, name)
            assert not isinstance(obj, types.ModuleType), f"imunoise.{name} is a module in round {round_}"
            assert getattr(I, name) is obj
            checks[name]()
    fit = gmwm(AR1() + WN(), x, freq=100.0)  # the snippet's import still names the function
    check_fit(fit, "AR1 + WN")
    print("ok", len(I.__all__))
    """
)


def test_fresh_interpreter_uses_every_export_twice():
    env = dict(os.environ)
    src = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "src")
    env["PYTHONPATH"] = src + os.pathsep + env.get("PYTHONPATH", "")
    env["MPLBACKEND"] = "Agg"
    out = subprocess.run([sys.executable, "-c", FRESH], capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    assert out.stdout.split() == ["ok", str(len(__import__("imunoise").__all__))]


# -- one model argument for every estimator ----------------------------------------------------------
TRUTH_WN = Model([WN(sigma2=4e-2)])
X_WN = TRUTH_WN.simulate(2**13, seed=11)
TRUTH_AR = AR1(phi=0.98, sigma2=1e-3) + WN(sigma2=1e-2)
X_AR = TRUTH_AR.simulate(2**13, seed=12)


@pytest.mark.parametrize("model", [WN(), WN, Model([WN()]), "WN"], ids=["process", "class", "Model", "string"])
def test_gmwm_refit_em_take_a_single_process_a_model_or_a_string(model):
    for fit in (
        gmwm(model, X_WN, freq=100.0),
        refit(model, X_WN, freq=100.0),
        em_fit(model, X_WN, freq=100.0, init=WN(sigma2=1e-2), max_iter=50),
    ):
        assert str(fit.model) == "WN"
        assert fit.params["WN.sigma2"] == pytest.approx(4e-2, rel=0.05)
        assert fit.freq == 100.0


@pytest.mark.parametrize("complete", [AR1(), AR1() + WN(), "AR1+WN"], ids=["process", "Model", "string"])
def test_select_model_takes_a_process_a_model_or_a_string(complete):
    ranking = select_model(X_AR, freq=100.0, complete=complete, criterion="wvic")
    n_candidates = 1 if complete is not None and str(as_model(complete)) == "AR1" else 3
    assert len(ranking.fits) == n_candidates
    best = ranking.best
    if n_candidates == 3:  # the true structure wins and its parameters are recovered
        assert str(best.model) == "AR1 + WN"
        assert best.params["AR1_1.phi"] == pytest.approx(0.98, abs=0.01)
        assert best.params["WN.sigma2"] == pytest.approx(1e-2, rel=0.15)
    else:
        assert str(best.model) == "AR1"


def test_as_model_rejects_non_models_and_spots_swapped_arguments():
    assert as_model(2 * AR1() + WN()) == as_model("2*AR1 + WN") == as_model(Model.parse("2AR1+WN"))
    assert as_model(QN) == Model([QN()])
    with pytest.raises(ModelError, match="estimators take \\(model, data\\)"):
        gmwm(X_WN, WN(), freq=100.0)
    with pytest.raises(ModelError, match="expected a model"):
        as_model(3)


def test_em_fit_old_argument_order_warns_and_gives_the_same_fit():
    new = em_fit("WN", X_WN, freq=100.0, init=WN(sigma2=1e-2), max_iter=50)
    with pytest.warns(DeprecationWarning, match="em_fit\\(model, data"):
        old = em_fit(X_WN, freq=100.0, model="WN", init=WN(sigma2=1e-2), max_iter=50)
    assert old.params == new.params
    with pytest.warns(DeprecationWarning):
        no_model = em_fit(X_WN, freq=100.0, init=WN(sigma2=1e-2), max_iter=50)
    assert no_model.params == new.params
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # keywords in the new order are not deprecated
        kw = em_fit(model="WN", data=X_WN, freq=100.0, init=WN(sigma2=1e-2), max_iter=50)
    assert kw.params == new.params
    with pytest.raises(DataError, match="em_fit needs data"):
        em_fit("WN", freq=100.0)
    with pytest.raises(TypeError, match="unexpected keyword argument 'iters'"):
        em_fit("WN", X_WN, iters=3, freq=1.0)


# -- rates and units as the CLI checks them --------------------------------------------------------------
BAD_FREQ = [None, "100", float("nan"), 0.0, -5.0, True]


@pytest.mark.parametrize("freq", BAD_FREQ, ids=repr)
def test_bad_freq_is_a_data_error_everywhere(freq):
    with pytest.raises(DataError, match="freq"):
        gmwm(WN(), X_WN, freq=freq)
    with pytest.raises(DataError, match="freq"):
        select_model(X_WN, freq=freq, complete="WN+RW")
    with pytest.raises(DataError, match="freq"):
        em_fit(WN(), X_WN, freq=freq, init=WN(sigma2=1.0))
    if freq is not None:  # refit: None means "the previous fit's rate"
        with pytest.raises(DataError, match="freq"):
            refit(WN(), X_WN, freq=freq)


def test_numpy_and_integer_rates_are_accepted():
    assert gmwm(WN(), X_WN, freq=np.float32(100.0)).freq == 100.0
    assert gmwm(WN(), X_WN, freq=100).freq == 100.0


def test_unknown_unit_is_a_unit_error_known_units_pass():
    with pytest.raises(UnitError, match="furlongs"):
        gmwm(WN(), X_WN, freq=100.0, unit="furlongs")
    with pytest.raises(UnitError):
        refit(WN(), X_WN, freq=100.0, unit="furlongs")
    with pytest.raises(UnitError):
        select_model(X_WN, freq=100.0, complete="WN", unit="furlongs")
    with pytest.raises(UnitError):
        em_fit(WN(), X_WN, freq=100.0, unit="furlongs", init=WN(sigma2=1.0))
    fit = gmwm(WN(), X_WN, freq=100.0, unit="rad/s")
    assert fit.unit == "rad/s" and fit.param_units()["WN.sigma2"] == "(rad/s)²"
    assert gmwm(WN(), X_WN, freq=100.0).unit == "u"  # unspecified stays allowed


# -- OnlineNavigator input checks ------------------------------------------------------------------------
@pytest.fixture(scope="module")
def navigator_factory():
    from imunoise.nav.ekf import InitialState
    from imunoise.online import OnlineConfig, OnlineNavigator

    llh0 = np.array([np.radians(30.5), np.radians(114.4), 20.0])
    init = InitialState(t=0.0, llh=llh0, vel_ned=np.zeros(3), euler=np.zeros(3))

    def make():
        # λ0 learned from the first 0.5 s (the default 10 s would hold the samples of these short tests)
        config = OnlineConfig(modelling=False, learn_lambda0_s=0.5)
        return OnlineNavigator(config, init, imu_rate_hz=100.0), llh0

    return make


def _static_sample(k: int) -> tuple[float, np.ndarray, np.ndarray]:
    # at rest, level, FRD: specific force −g along down, plus a little sensor noise (the static detector
    # learns its threshold from it); the Earth rate is left out (a few 1e-5 rad/s)
    rng = np.random.default_rng(k)
    dth = rng.normal(0.0, 1e-5, 3)
    dv = np.array([0.0, 0.0, -9.7936 * 0.01]) + rng.normal(0.0, 1e-4, 3)
    return 0.01 * k, dth, dv


def test_push_gnss_refuses_degrees_and_non_finite_positions(navigator_factory):
    nav, llh0 = navigator_factory()
    deg = np.array([30.5, 114.4, 20.0])
    with pytest.raises(DataError, match="np.radians"):
        nav.push_gnss(1.0, deg, np.ones(3))
    with pytest.raises(DataError, match="np.radians"):
        nav.push_gnss(1.0, [0.5, 4.0, 20.0], np.ones(3))  # latitude fine, longitude beyond π
    with pytest.raises(DataError, match="non-finite"):
        nav.push_gnss(1.0, [np.nan, llh0[1], 20.0], np.ones(3))
    with pytest.raises(DataError, match="non-finite"):
        nav.push_gnss(float("inf"), llh0, np.ones(3))
    with pytest.raises(DataError, match="3 values"):
        nav.push_gnss(1.0, llh0[:2], np.ones(3))
    with pytest.raises(DataError, match="≥ 0"):
        nav.push_gnss(1.0, llh0, [-1.0, 1.0, 1.0])
    assert nav.state.gnss == []  # nothing refused reached the filter queue


def test_push_gnss_in_radians_is_used(navigator_factory):
    """A fix 2 m north of the start, in radians, pulls the static solution north; without it the solution
    stays put (the 5 cm initial σ and the χ² gate refuse fixes much further off)."""
    from imunoise.nav.earth import radii

    def north_after(fix):
        nav, llh0 = navigator_factory()
        rm, _ = radii(llh0[0])
        for k in range(1, 301):
            if k == 150 and fix is not None:
                nav.push_gnss(1.495, llh0 + np.array([fix / (rm + llh0[2]), 0.0, 0.0]), np.full(3, 0.5))
            nav.push_imu(*_static_sample(k))
        state = nav.solution()
        assert np.all(np.isfinite(state["llh"])) and nav.ekf.n_rejected == 0
        return (state["llh"][0] - llh0[0]) * (rm + llh0[2])

    assert abs(north_after(None)) < 0.05
    assert 0.2 < north_after(2.0) < 2.0


@pytest.mark.parametrize(
    "dtheta, dv",
    [(np.zeros(2), np.zeros(3)), (np.zeros(3), np.zeros((2, 3))), (np.zeros((1, 3)), np.zeros(3)), (0.0, 0.0)],
    ids=["dtheta-2", "dv-2x3", "dtheta-1x3", "scalars"],
)
def test_push_imu_wrong_shape_is_a_data_error(navigator_factory, dtheta, dv):
    nav, _ = navigator_factory()
    with pytest.raises(DataError, match="3 increments"):
        nav.push_imu(0.01, dtheta, dv)
    nav.push_imu(*_static_sample(1))  # the refused sample did not advance the stream
