"""``online`` with a model file's in-motion part runs the filter ``nav`` runs: the same in-motion noise while
moving, the static part at stops, switched by the same moving flag (events of the online engine)."""

from __future__ import annotations

import numpy as np

from imunoise.imu import AXES
from imunoise.inuse import AxisInMotion, BiasWander, InMotionPart, Interval
from imunoise.nav.ekf import run_ekf
from imunoise.nav.filter_model import in_motion_filter


def _max_diff(x, y) -> float:
    """Largest position difference [m] at the epochs both solutions have."""
    i = np.clip(np.searchsorted(y.t, x.t), 0, y.t.size - 1)
    ok = np.abs(y.t[i] - x.t) < 1e-9
    d = np.abs(x.llh[ok] - y.llh[i[ok]]) * [6.4e6, 6.4e6, 1.0]
    return float(d.max())


def test_online_in_motion_matches_nav_and_changes_the_solution():
    from imunoise.experiments.common import filter_models, simulate_scenario
    from imunoise.noise.model import Model
    from imunoise.noise.processes import WN
    from imunoise.online import OnlineConfig, OnlineNavigator
    from imunoise.online.in_motion import attach_in_motion, initial_models

    sc = simulate_scenario(4702, duration_s=330.0, n_stops=2, motion_noise="gyro_moving_gm", n_outages=0)
    cfg = OnlineConfig().with_(ekf=sc.ekf_config(), floor="none", modelling=False, gate=False)
    none = Model([WN(sigma2=1e-30)])
    models = filter_models([sc.extra["static_models"].get(ax, none) for ax in AXES], sc.rate, cfg)
    sched = sc.extra["law_schedule"]
    part = InMotionPart({a: AxisInMotion(Interval(1.5), BiasWander("gm", sigma=float(sched.gm_sigma[i]), tau_s=60.0)
                                         if i < 3 else BiasWander("none")) for i, a in enumerate(AXES)})
    moving = sched.moving
    nav = OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate, initial_models=initial_models(part, models, sc.rate))
    attach_in_motion(nav, part, models, moving)
    online = nav.run(sc.imu, sc.gnss)
    batch = run_ekf(sc.imu, sc.gnss, sc.init, sc.ekf_config(), in_motion=in_motion_filter(
        models, part.white_factors(), *part.moving_gm()), moving=moving)
    static_online = OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate, initial_models=models).run(sc.imu, sc.gnss)
    static_batch = run_ekf(sc.imu, sc.gnss, sc.init, sc.ekf_config(), models)
    # the two engines differ by their flush points alone (3e-7 m without any in-motion part): the same here
    assert _max_diff(static_online, static_batch) < 1e-5
    assert _max_diff(online, batch) < 1e-5
    assert _max_diff(online, static_online) > 0.1  # and the part changes the solution


def test_a_refit_at_a_stop_keeps_the_in_motion_part():
    """With modelling on, each refit of the static part at a stop is composed with the same in-motion part: after
    the last swap the filter's noise while moving is exactly that of a filter built afresh on the last static fits
    plus the moving states, with the in-motion white factors applied."""
    from imunoise.experiments.common import filter_models, simulate_scenario
    from imunoise.nav.moving_run import moving_control
    from imunoise.nav.step_filter import LooselyCoupledEKF
    from imunoise.online import OnlineConfig, OnlineNavigator
    from imunoise.online.in_motion import attach_in_motion, initial_models

    sc = simulate_scenario(4703, duration_s=330.0, n_stops=2, motion_noise="gyro_moving_gm", n_outages=0)
    cfg = OnlineConfig().with_(ekf=sc.ekf_config())
    start = filter_models([None] * 6, sc.rate, cfg)  # the engine's default models until the first fit
    part = InMotionPart({a: AxisInMotion(Interval(1.7), BiasWander("gm", sigma=2e-5, tau_s=80.0))
                         for a in AXES[:3]})
    moving = sc.extra["law_schedule"].moving
    n = int(np.flatnonzero(moving)[-1]) + 1  # up to the last moving sample: the filter's noise is the in-motion one
    nav = OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate, initial_models=initial_models(part, start, sc.rate))
    attach_in_motion(nav, part, start, moving)
    t = np.asarray(sc.imu.t, dtype=float)
    dth, dv = sc.imu.increments()
    k = int(np.searchsorted(sc.gnss.t, t[n - 1], side="right"))
    nav.push_chunk(t[:n], dth[:n], dv[:n], sc.gnss.t[:k], sc.gnss.llh[:k], sc.gnss.sigma_ned[:k])
    res = nav.finish()
    swaps = [e for e in res.events if e["event"] == "swap"]
    assert [e["job"] for e in swaps].count("refit") >= 1  # the static part was refit at a stop
    imf = in_motion_filter(nav.static_models, part.white_factors(), *part.moving_gm())
    fresh = LooselyCoupledEKF(sc.ekf_config(), imf.models, sc.init, imu_rate_hz=sc.rate)
    control = moving_control(fresh, imf)
    control.set_noise_scale(imf.white, np.ones(6))
    control.set_moving(True)
    want = control.arrays()
    got, _ = nav.ekf.kernel_parts()
    assert nav.ekf.layout.labels == fresh.layout.labels  # the moving states are in the layout after the refit
    for name in want._fields:
        np.testing.assert_array_equal(getattr(got, name), getattr(want, name), err_msg=name)
    static = LooselyCoupledEKF(sc.ekf_config(), nav.static_models, sc.init, imu_rate_hz=sc.rate).kernel_parts()[0]
    assert not np.array_equal(got.wpsd, static.wpsd)  # and the white factors are on
