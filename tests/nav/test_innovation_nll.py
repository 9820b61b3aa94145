"""The batch loop stores each fix's one-step innovation NLL beside the NIS: its Gaussian −log density (the
learner's likelihood statistic, :mod:`imunoise.online.learner`)."""

from __future__ import annotations

import copy
import math
from dataclasses import replace

import numpy as np
from scipy.stats import multivariate_normal

from imunoise.experiments.common import simulate_scenario
from imunoise.nav.ekf import LooselyCoupledEKF


def test_stored_nll_is_the_gaussian_log_density_and_changes_nothing():
    sc = simulate_scenario(2, duration_s=90, n_stops=0, n_outages=0, static_s=10)
    i0 = int(np.searchsorted(sc.imu.t, sc.init.t))
    init = replace(sc.init, t=float(sc.imu.t[i0]))
    dth, dv = sc.imu.increments()
    ekf = LooselyCoupledEKF(sc.ekf_config(), None, init, imu_rate_hz=sc.rate)
    ekf.prime(dth[i0], dv[i0])
    i1 = i0 + int(round(20.0 * sc.rate))  # 20 s with its fixes
    t = sc.imu.t[i0:i1 + 1]
    g = sc.gnss
    m = (g.t > t[0]) & (g.t <= t[-1])
    gt, gllh, gsig = g.t[m], g.llh[m], g.sigma_ned[m]
    assert gt.size >= 15
    plain = ekf.rehearse(t, dth[i0:i1 + 1], dv[i0:i1 + 1], gt, gllh, gsig, with_nis=True, with_std=True)
    llh, eul, nis, nll, std = ekf.rehearse(t, dth[i0:i1 + 1], dv[i0:i1 + 1], gt, gllh, gsig, with_nis=True,
                                              with_nll=True, with_std=True)
    # asking for the NLL changes no output bit
    for a, b in zip(plain, (llh, eul, nis, std), strict=True):
        assert np.array_equal(a, b, equal_nan=True)
    assert np.all(np.isfinite(nll))
    # the step filter up to the 5th fix gives its innovation ν and S: the stored NLL is −log N(ν; 0, S) (not
    # ½(NIS + log det S + 3 log 2π): the gate's NIS adds gate_abs² to S)
    step = copy.deepcopy(ekf)
    j = 4
    k = i0 + 1
    fi = 0
    while fi <= j:
        step.propagate(dth[k], dv[k], sc.imu.t[k])
        while fi <= j and gt[fi] <= sc.imu.t[k]:
            step.update_gnss(gt[fi], gllh[fi], gsig[fi])
            fi += 1
        k += 1
    u = step.last_update
    assert u.kind == "gnss_position"
    assert u.nis == nis[j] and u.t == gt[j]
    direct = -multivariate_normal(mean=np.zeros(3), cov=u.S).logpdf(u.y)
    assert abs(nll[j] - direct) < 1e-9 * max(1.0, abs(direct))
    assert abs(nll[j] - 0.5 * (u.nis + np.linalg.slogdet(u.S)[1] + 3 * math.log(2 * math.pi))) > 1e-6
