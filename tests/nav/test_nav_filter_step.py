"""One filter step (issue 23): the batch kernel and the step filter give the same trajectory to the bit; the
filter's arrays are read through named views; no literal state slices outside imunoise.nav."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from imunoise.experiments.common import simulate_scenario
from imunoise.nav.defaults import EkfConfig
from imunoise.nav.ekf import LooselyCoupledEKF, run_ekf
from imunoise.nav.measurements.nhc import NhcConfig
from imunoise.nav.mechanization import nav_euler

SRC = Path(__file__).resolve().parents[2] / "src" / "imunoise"


@pytest.fixture(scope="module")
def short_drive():
    """A 200 s simulated drive (20 s static start, no stop), GNSS at 1 Hz."""
    return simulate_scenario(1, duration_s=200, n_stops=0, n_outages=1, outage_s=30, outage_lead_s=30, static_s=20)


def _step_run(sc, init, config, t_end, zupt):
    """The step filter fed sample by sample as run_ekf feeds its kernel (start on an IMU epoch)."""
    t_all = sc.imu.t
    dth, dv = sc.imu.increments()
    i0 = int(np.searchsorted(t_all, init.t))
    i1 = int(np.searchsorted(t_all, t_end, side="right"))
    ekf = LooselyCoupledEKF(config, None, init, imu_rate_hz=sc.rate)
    ekf.prime(dth[i0], dv[i0])
    gnss = sc.gnss.without(sc.windows)
    gi = int(np.searchsorted(gnss.t, t_all[i0], side="right"))
    rows = []
    for k in range(i0 + 1, i1):
        ekf.propagate(dth[k], dv[k], t_all[k])
        while gi < gnss.t.size and gnss.t[gi] <= t_all[k]:
            ekf.update_gnss(gnss.t[gi], gnss.llh[gi], gnss.sigma_ned[gi])
            gi += 1
        if zupt[k] and (k - i0) % config.zupt_every == 0:
            ekf.zupt_update(config.zupt_sigma)
        sv = ekf.view
        rows.append(np.concatenate([sv.llh, sv.vel, nav_euler(ekf.nav), sv.std_nav]))
    return np.array(rows)


@pytest.mark.parametrize("aiding", [(), (NhcConfig(),)], ids=["plain", "nhc"])
def test_batch_and_step_paths_are_identical(short_drive, aiding):
    sc = short_drive
    i0 = int(np.searchsorted(sc.imu.t, sc.init.t))
    init = replace(sc.init, t=float(sc.imu.t[i0]))  # on an IMU epoch: no split first increment
    config = sc.ekf_config().with_(aiding=aiding)
    t_end = init.t + 120.0
    zupt = np.asarray(sc.static_truth, dtype=bool)
    batch = run_ekf(sc.imu, sc.gnss.without(sc.windows), init, config, t_end=t_end, zupt=zupt)
    step = _step_run(sc, init, config, t_end, zupt)
    got = np.hstack([batch.llh, batch.vel_ned, batch.euler, batch.std])[1:]
    assert got.shape == step.shape
    assert np.array_equal(got, step)  # to the bit: the same numba functions in the same order
    assert np.sum(batch.gnss_status == 1) > 50  # the fixes were used, the outage window skipped


def test_state_view_is_a_view():
    from imunoise.nav.ekf import InitialState

    init = InitialState(0.0, np.array([0.7, -1.8, 100.0]), np.array([1.0, 2.0, 3.0]), np.zeros(3))
    ekf = LooselyCoupledEKF(EkfConfig(), None, init)
    sv = ekf.view
    assert np.array_equal(sv.vel, [1.0, 2.0, 3.0]) and np.array_equal(sv.llh, init.llh)
    assert sv.speed_h == pytest.approx(np.hypot(1.0, 2.0))
    assert np.array_equal(sv.P_vel, np.diag(np.square(EkfConfig().sigma_vel0)))
    sv.vel[0] = 5.0  # a view, not a copy
    assert ekf.nav[3] == 5.0
    assert np.array_equal(sv.std_nav, np.sqrt(np.diag(ekf.P)[:9]))


# a filter array (nav, P, xm, acc, or an attribute of that name) indexed by a number or a numeric slice
_LITERAL = re.compile(r"(?:\.|\b)(?:nav|P|xm|acc)\s*\[\s*-?\d*\s*(?::\s*-?\d*\s*)?[],]")


@pytest.mark.parametrize("folder", ["online", "experiments", "cli"])
def test_no_literal_state_slices_outside_nav(folder):
    hits = []
    for path in sorted((SRC / folder).rglob("*.py")):
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if _LITERAL.search(line):
                hits.append(f"{path.relative_to(SRC)}:{n}: {line.strip()}")
    assert hits == [], "use imunoise.nav.state names / ekf.view instead:\n" + "\n".join(hits)


def test_the_slice_scan_finds_literal_slices():
    for bad in ("v = self.ekf.nav[3:6]", "S = ekf.P[3:6, 3:6]", "x = nav[3]", "a = self.acc[15]"):
        assert _LITERAL.search(bad), bad
    for ok in ("v = self.ekf.view.vel", "row[1:7] = sv.pos_vel", "P_vel[0, 0]"):
        assert not _LITERAL.search(ok), ok
