"""The drives of the in-motion likelihood on Dask (imunoise.inuse.fleet): on two short simulated drives and a local
2-worker cluster the pooled NLL, and the whole estimate, are the serial ones to the last bit; without
--scheduler nothing changes (no mapper: the likelihood's own loop, the per-drive runs summed in drive order)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imunoise.imu import AXES
from imunoise.inuse import estimate_in_motion
from imunoise.inuse.fleet import DaskDriveMap, fleet_mapper
from imunoise.inuse.likelihood import DriveLikelihood, Theta
from imunoise.nav.ekf import run_ekf
from imunoise.nav.filter_model import in_motion_filter

THETAS = [Theta(), Theta(white=(1.5,) * 3 + (2.0,) * 3, sigma=(2e-4,) * 3 + (0.0,) * 3, tau_s=(40.0,) * 6)]


@pytest.fixture(scope="module")
def fleet():
    """Two 180 s simulated drives (seeds 5301, 5302; one stop each) and their static filter models."""
    from imunoise.experiments.common import filter_models, simulate_scenario
    from imunoise.noise.model import Model
    from imunoise.noise.processes import WN
    from imunoise.online import OnlineConfig

    drives = [simulate_scenario(s, duration_s=180.0, n_stops=1, n_outages=0, motion_noise="gyro_moving_gm")
              for s in (5301, 5302)]
    none = Model([WN(sigma2=1e-30)])
    sc = drives[0]
    cfg = OnlineConfig().with_(ekf=sc.ekf_config(), floor="none")
    models = filter_models([sc.extra["static_models"].get(ax, none) for ax in AXES], sc.rate, cfg)
    return drives, models


def test_without_a_scheduler_the_runs_are_summed_in_drive_order_here(fleet):
    drives, models = fleet
    with fleet_mapper("sequential") as mapper:
        assert mapper is None
    lik = DriveLikelihood(drives, models)
    for th in THETAS:  # the loop of before: one run per drive, the fixes' NLLs added drive after drive
        imf = in_motion_filter(models, th.white, th.sigma, th.tau_s)
        total = 0.0
        for d, mv in zip(drives, lik.moving, strict=True):
            r = run_ekf(d.imu, d.gnss, d.init, d.ekf_config(), in_motion=imf, moving=mv, with_nll=True)
            total += float(np.nansum(r.gnss_nll))
        assert lik.nll(th) == total and math.isfinite(total)
    assert lik.runs == 2 * len(THETAS)


@pytest.mark.slow  # a 2-process Dask cluster and the estimate twice: about a minute on 2 cores
def test_a_local_two_worker_cluster_gives_the_serial_nll_and_estimate_bit_for_bit(fleet):
    drives, models = fleet
    serial = DriveLikelihood(drives, models)
    kw = {"freq": drives[0].rate, "groups": ("gyro",), "maxfev": 6}
    est_serial = estimate_in_motion(drives, models, **kw)
    with fleet_mapper("local", 2) as mapper:
        assert isinstance(mapper, DaskDriveMap) and len(mapper.client.scheduler_info()["workers"]) == 2
        par = DriveLikelihood(drives, models, mapper=mapper)
        for th in THETAS:
            assert par.nll(th) == serial.nll(th)  # exact: the same runs, summed in the same order
        est_par = estimate_in_motion(drives, models, mapper=mapper, **kw)
        assert mapper.worker_cpu_s > 0.0
    assert est_par.nll == est_serial.nll and est_par.nll_static == est_serial.nll_static
    assert est_par.part.to_dict() == est_serial.part.to_dict() and est_par.runs == est_serial.runs


def test_lost_workers_are_one_line_naming_the_option():
    """A cluster whose connection is lost mid-run (CommClosedError from gather) is a DataError naming --scheduler,
    not a traceback; the per-drive tasks are submitted in drive order."""
    from distributed.comm.core import CommClosedError

    from imunoise.errors import DataError

    class LostCluster:
        submitted: list = []

        def scatter(self, items, **kw):
            return list(items)

        def submit(self, fn, *args, **kw):
            self.submitted.append(args[1])
            return args[1]

        def gather(self, futures):
            raise CommClosedError("in <TCP (closed)>: Stream is closed")

    mapper = DaskDriveMap(LostCluster())
    with pytest.raises(DataError, match=r"^--scheduler: the Dask workers were lost .* without --scheduler$"):
        mapper(lambda d, m, imf: 0.0, ["drive 1", "drive 2"], [np.ones(3, bool)] * 2, None)
    assert LostCluster.submitted == ["drive 1", "drive 2"]
