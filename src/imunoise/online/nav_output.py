"""What the online navigator hands out: stored epochs, the result, a branch (fork) of a running navigator."""

from __future__ import annotations

import copy
from collections.abc import Sequence
from typing import Any

import numpy as np

from imunoise.errors import ModelError
from imunoise.online.result import EpochStore, OnlineResult

__all__ = ["store_epoch", "build_result", "fork_navigator"]


def store_epoch(store: EpochStore, ekf: Any, t: float) -> None:
    """One row of :class:`EpochStore` (time, position/velocity, quaternion, sensor errors, 1σ) at ``t``."""
    e = ekf.sensor_errors()
    row = np.empty(EpochStore.COLS)
    row[0] = t
    sv = ekf.view
    row[1:7] = sv.pos_vel
    row[7:11] = sv.quat
    row[11:17] = e
    row[17:26] = sv.std_nav
    store.add(row)


def fork_navigator(nav: Any, others: Sequence[Any], share: tuple) -> tuple:
    """:meth:`OnlineNavigator.fork`: ``(navigator, *others)`` copied together, ``share`` and the modelling-job
    cache shared."""
    if nav.config.worker != "inline":
        raise ModelError("fork() needs OnlineConfig(worker='inline'): a worker thread cannot be copied")
    memo = {id(o): o for o in share}
    if nav.modeller.job_cache is not None:
        memo[id(nav.modeller.job_cache)] = nav.modeller.job_cache
    # the per-sample logs get their own lists (both runs append and trim them) holding the same elements:
    # floats, bools and raw-sample rows that nothing writes into once appended (they are only read,
    # sliced and copied), so a shallow copy is the deep one without copying a row per sample
    st = nav.state
    for seq in (st.gate_log, st.sample_t, st.static_raw, st.rows):
        memo[id(seq)] = list(seq)
    nav, *rest = copy.deepcopy((nav, *others), memo)
    if nav.state.store is not None:
        nav.state.store = EpochStore()
    return (nav, *rest)


def build_result(nav: Any) -> OnlineResult:
    """The :class:`OnlineResult` of navigator ``nav`` (:meth:`OnlineNavigator.finish`)."""
    st = nav.state
    if st.store is not None and st.store.n:
        t, pos, vel, eul, eg, ea, std = st.store.arrays()
    else:
        z = np.zeros((0, 3))
        t, pos, vel, eul, eg, ea, std = np.zeros(0), z, z, z, z, z, np.zeros((0, 9))
    return OnlineResult(
        t=t, llh=pos, vel_ned=vel, euler=eul, gyro_error=eg, accel_error=ea, std=std,
        events=nav.events, updates=nav.updates, segments=list(nav.segments),
        gate_open=np.array(st.gate_log, dtype=bool), static_raw=np.array(st.static_raw, dtype=bool),
        lambda0=float(nav.lambda0) if nav.lambda0 is not None else float("nan"),
        elapsed_s=st.elapsed, final_models=list(nav.current_models), fits=list(nav.fits),
        sample_t=np.array(st.sample_t), rejected_segments=list(nav.rejected_segments),
        detected_segments=list(nav.detected_segments), static_pieces=nav.modeller.static_pieces(copy=False),
    )
