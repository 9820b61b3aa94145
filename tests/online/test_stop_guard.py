"""Which stops the online engine models (``OnlineConfig.stop_guard``): a detected stop is modelled only where the
navigation solution agrees. Truth: the simulator's stationary mask, and hand-made speed profiles for the pure
verdict."""

from __future__ import annotations

import logging
import re

import numpy as np
import pytest

from imunoise.detect import static_metrics
from imunoise.errors import ModelError
from imunoise.online import OnlineConfig, OnlineNavigator, stop_verdict

RATE = 100.0
KW = dict(rate_hz=RATE, max_speed=1.0, sigma_k=3.0, chi2=0.0, edge_s=1.0, min_duration_s=2.0)


def _verdict(speed, *, aided=True, sigma=0.1, nis=np.nan, **kw):
    n = len(speed)
    args = {**KW, **kw}
    return stop_verdict(np.asarray(speed, float), np.full(n, sigma), np.full(n, aided), np.full(n, nis), **args)


def test_verdict_keeps_a_still_segment_whole_and_cuts_the_cruise_after_a_stop():
    still = _verdict(np.full(1000, 0.2))
    assert still.whole and still.keep == [(0, 1000)] and still.reason == ""
    # 10 s stop, then 5 s of cruising at 9 m/s in the same detected run: the stop minus the 1 s edge is kept
    v = np.r_[np.full(1000, 0.1), np.full(500, 9.0)]
    r = _verdict(v)
    assert r.keep == [(0, 900)] and r.drop == [(900, 1500)]
    assert r.max_speed_mps == 9.0 and r.n_bad == 500 and "9.00 m/s" in r.reason
    # cruising in the middle of two stops: two pieces; a piece shorter than 2 s after the cut is dropped
    r = _verdict(np.r_[np.full(600, 0.1), np.full(300, 9.0), np.full(250, 0.1)])
    assert r.keep == [(0, 500)] and r.drop == [(500, 1150)]
    assert _verdict(np.full(700, 8.0)).keep == []


def test_verdict_bound_grows_with_the_filter_sigma_and_unaided_samples_need_the_chi2_option():
    v = np.full(500, 2.0)
    assert not _verdict(v, sigma=0.1).whole  # 2 m/s > max(1, 0.3)
    assert _verdict(v, sigma=1.0).whole  # 2 m/s < 3σ = 3 m/s: the filter does not know it moves
    assert _verdict(v, aided=False, nis=400.0).whole  # unaided, no χ² test: not tested
    r = _verdict(v, aided=False, nis=400.0, chi2=11.34)
    assert r.keep == [] and "NIS" in r.reason
    # unaided, the NIS alone is not enough: the speed must exceed stop_max_speed as well
    assert _verdict(np.full(500, 0.5), aided=False, nis=400.0, chi2=11.34).whole
    # samples before the filter started (NaN speed) are not tested
    assert _verdict(np.full(500, np.nan)).whole


@pytest.mark.parametrize("kw, field", [
    ({"stop_guard": "imu"}, "stop_guard"), ({"stop_max_speed": 0.0}, "stop_max_speed"),
    ({"stop_aided_s": -1.0}, "stop_aided_s"), ({"stop_edge_s": np.nan}, "stop_edge_s"),
    ({"stop_sigma_k": "3"}, "stop_sigma_k"), ({"stop_chi2": -2.0}, "stop_chi2"), ({"stop_chi2": True}, "stop_chi2"),
])
def test_config_errors_name_the_field(kw, field):
    with pytest.raises(ModelError, match=re.escape(field)):
        OnlineConfig(**kw)


@pytest.fixture(scope="module")
def noisy_drive():
    """300 s on the noisy IMU (seed 0): its learned λ0 lets smooth cruising pass the IMU-only test."""
    from imunoise.experiments.common import simulate_scenario

    logger = logging.getLogger("imunoise")
    level = logger.level
    logger.setLevel(logging.ERROR)  # quiet for this module's tests only: later tests read the warnings
    # moving = static errors (motion_noise "none"): with the in-motion vibration of the default law the detector
    # alone already separates cruising from stops on this drive (precision 0.98)
    yield simulate_scenario(0, imu_models="noisy", duration_s=300.0, n_stops=2, n_outages=0, static_s=30.0,
                            motion_noise="none")
    logger.setLevel(level)


def _mask(n, segments):
    m = np.zeros(n, dtype=bool)
    for s in segments:
        m[s.i0:s.i1] = True
    return m


def _run(sc, guard, **kw):
    cfg = OnlineConfig(ekf=sc.ekf_config(), stop_guard=guard, warm_up=False, **kw)
    return OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate).run(sc.imu, sc.gnss)


def test_guard_gives_static_precision_on_a_noisy_imu_and_rejected_data_never_reaches_the_fit(noisy_drive):
    sc = noisy_drive
    n = sc.static_truth.size
    none = _run(sc, "none", modelling=False)
    nav = _run(sc, "nav", latency=0.0, complete="AR1 + WN + RW")
    p_none = static_metrics(_mask(n, none.segments), sc.static_truth)
    p_nav = static_metrics(_mask(n, nav.segments), sc.static_truth)
    assert p_none["precision"] < 0.8  # the detector alone models cruising
    assert p_nav["precision"] >= 0.99 and p_nav["recall"] >= 0.9 * p_none["recall"]
    # the detector found the same segments; the guard split them into modelled and dropped pieces
    assert nav.detected_segments == none.segments and nav.rejected_segments
    kept, dropped = _mask(n, nav.segments), _mask(n, nav.rejected_segments)
    assert not np.any(kept & dropped)
    np.testing.assert_array_equal(kept | dropped, _mask(n, nav.detected_segments))
    assert static_metrics(dropped, ~sc.static_truth)["precision"] > 0.9  # what it drops is mostly motion
    # the modelled static total (what the WV pools) is the kept pieces only, also at every fit
    total = sum(s.duration for s in nav.segments)
    end = next(e for e in nav.events if e["event"] == "end")
    assert end["static_s"] == pytest.approx(total)
    fits = [e for e in nav.events if e["event"] in ("identified", "refit")]
    assert fits and fits[-1]["static_total_s"] == pytest.approx(total)
    assert nav.updates[-1].static_s < sum(s.duration for s in nav.detected_segments) - 10.0
    rej = [e for e in nav.events if e["event"] == "stop_rejected"]
    assert rej and all(e["max_speed_mps"] > 1.0 and "m/s" in e["reason"] for e in rej)


def _strip_times(events: list[dict]) -> str:
    # as tests/test_detect_paths.py: compute times and the warm-up's process state differ between two runs
    text = re.sub(r"np\.float64\(([^)]*)\)", r"\1", repr(events))
    return re.sub(r"'(time_s|elapsed_s|compiled|loaded|already)': [^,}]+", r"'\1': X", text)


def test_run_equals_push_with_the_guard(noisy_drive):
    sc = noisy_drive
    cfg = OnlineConfig(ekf=sc.ekf_config(), modelling=False, warm_up=False)
    gnss = sc.gnss.without(sc.windows[:1]) if sc.windows else sc.gnss
    batch = OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate).run(sc.imu, gnss)
    nav = OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate)
    t = sc.imu.t
    gi = 0
    for k in range(t.size):
        while gi < gnss.t.size and gnss.t[gi] <= t[k]:
            nav.push_gnss(gnss.t[gi], gnss.llh[gi], gnss.sigma_ned[gi])
            gi += 1
        nav.push_imu(t[k], sc.imu.dtheta[k], sc.imu.dv[k])
    stream = nav.finish()
    assert batch.rejected_segments and stream.rejected_segments == batch.rejected_segments
    assert stream.segments == batch.segments
    assert _strip_times(stream.events) == _strip_times(batch.events)
    np.testing.assert_array_equal(stream.llh, batch.llh)
