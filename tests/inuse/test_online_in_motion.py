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
    pairs = filter_models([sc.extra["static_models"].get(ax, none) for ax in AXES], sc.rate, cfg)
    sched = sc.extra["law_schedule"]
    part = InMotionPart({a: AxisInMotion(Interval(1.5), BiasWander("gm", sigma=float(sched.gm_sigma[i]), tau_s=60.0)
                                         if i < 3 else BiasWander("none")) for i, a in enumerate(AXES)})
    moving = sched.moving
    nav = OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate, initial_models=initial_models(part, pairs, sc.rate))
    attach_in_motion(nav, part, pairs, moving)
    online = nav.run(sc.imu, sc.gnss)
    batch = run_ekf(sc.imu, sc.gnss, sc.init, sc.ekf_config(), in_motion=in_motion_filter(
        pairs, part.white_factors(), *part.moving_gm()), moving=moving)
    static_online = OnlineNavigator(cfg, sc.init, imu_rate_hz=sc.rate, initial_models=pairs).run(sc.imu, sc.gnss)
    static_batch = run_ekf(sc.imu, sc.gnss, sc.init, sc.ekf_config(), pairs)
    # the two engines differ by their flush points alone (3e-7 m without any in-motion part): the same here
    assert _max_diff(static_online, static_batch) < 1e-5
    assert _max_diff(online, batch) < 1e-5
    assert _max_diff(online, static_online) > 0.1  # and the part changes the solution
