"""One aided run with a GNSS-free branch per window (the dense-window protocol of
:mod:`imunoise.experiments.dense`): the aided run in kernel spans from one window start to the next and each
branch in one chunk (:meth:`OnlineNavigator.push_chunk`), or sample by sample when a method's updater acts
between samples; the per-window metrics (:mod:`imunoise.experiments.window_errors`)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from imunoise.errors import ModelError
from imunoise.experiments.common import Scenario
from imunoise.experiments.dense_methods import LEARNED_ROWS, STATIC_WARM_METHODS, Updater, base_method, method_setup
from imunoise.experiments.dense_spec import BRANCH_MARGIN_S
from imunoise.experiments.nees import drive_nees, epoch_error, nees6, scored_epochs
from imunoise.experiments.window_errors import (
    branch_errors,
    navigator_window_metrics,
    stored_errors,
    window_last_sample,
    window_metrics,
)
from imunoise.nav.metrics import nav_errors
from imunoise.online import MotionNoisePrior, OnlineConfig, OnlineNavigator

__all__ = ["run_windows", "evaluate_method"]


def _fork(nav: OnlineNavigator, upd: Updater | None, shared: Sequence[Any]):
    # the branch keeps only its own epochs: the result converts every stored epoch to Euler angles; the aided
    # run's store is shared rather than copied, since the fork replaces it with an empty one. The finished
    # modelling jobs (ModelUpdate, never changed once made; their fits and rankings are most of what a fork
    # would copy) are shared too: the branch gets its own list of them.
    store = nav.store
    done = tuple(nav.updates)
    nav2, upd2 = nav.fork(upd, share=(*shared, *((store,) if store is not None else ()), *done))
    return nav2, upd2


def _push_scored(nav: OnlineNavigator, data, i0: int, i: int, k: int, ks: int, scored, read) -> None:
    """push_chunk of samples [i0, i) and fixes [k, ks), split after every scored sample inside (``scored``:
    sorted sample indices, None: no split), where ``read(q)`` takes the state; a split changes nothing, since
    push_chunk equals push_imu/push_gnss in time order to the bit. The chunk's last sample is read after it."""
    t, dth, dv, gt, gllh, gsig = data
    a = i0
    for q in ([] if scored is None else scored[(scored >= i0) & (scored < i)]):
        if q < i - 1:
            kq = min(max(int(np.searchsorted(gt, t[q], side="right")), k), ks)  # the fixes at or before t[q]
            nav.push_chunk(t[a:q + 1], dth[a:q + 1], dv[a:q + 1], gt[k:kq], gllh[k:kq], gsig[k:kq])
            a, k = q + 1, kq
        else:
            nav.push_chunk(t[a:i], dth[a:i], dv[a:i], gt[k:ks], gllh[k:ks], gsig[k:ks])
            a, k = i, ks
        read(int(q))
    if a < i or k < ks:
        nav.push_chunk(t[a:i], dth[a:i], dv[a:i], gt[k:ks], gllh[k:ks], gsig[k:ks])


def _aided_chunks(nav: OnlineNavigator, sc: Scenario, windows, order_w, data, shared, out: list,
                  scored=None, read=None) -> None:
    """The aided run and its branches in kernel spans (:meth:`OnlineNavigator.push_chunk`): the aided run is
    pushed from one window start to the next and each branch in one chunk, with the fixes :func:`_aided_samples`
    pushes in the same places (push_chunk equals push_imu/push_gnss in time order to the bit); ``scored`` /
    ``read``: the NEES epochs of the aided run (:func:`_push_scored`)."""
    t, dth, dv, gt, gllh, gsig = data
    n = t.size
    ref_t = np.asarray(sc.ref.t, dtype=float)
    if nav.detector is None and n:
        # λ_0 from the first learn_lambda0_s of the record at once, as OnlineNavigator.run does (push_imu holds
        # those samples, learns from the same accelerations at the first later sample, then replays them one by
        # one): the detector exists before the first chunk, so no sample takes the per-sample path for it
        dt = np.diff(t, prepend=t[0] - nav.dt_nom)
        nav.learn_lambda0((dv / dt[:, None])[t < t[0] + nav.config.learn_lambda0_s], t[0])
    i0 = k = 0
    for j in order_w:
        s, length = windows[j]
        i = int(np.searchsorted(t, s, side="left"))  # the first sample with t ≥ s: the branch starts there
        if i >= n:
            break
        ks = max(int(np.searchsorted(gt, s, side="left")), k)  # the fixes before the window start
        _push_scored(nav, data, i0, i, k, ks, scored, read)
        i0, k = i, ks
        br, _ = _fork(nav, None, shared)
        ie = int(np.searchsorted(t, s + length + BRANCH_MARGIN_S, side="left"))
        ie = max(window_last_sample(t, ref_t, s, length, ie), i)  # no sample after the window's last epoch
        # inside the window no fix; after its end those up to the branch's last sample
        kb = int(np.searchsorted(gt, s + length, side="left"))
        ke = max(int(np.searchsorted(gt, t[ie - 1], side="right")), kb) if ie > i else kb
        br.push_chunk(t[i:ie], dth[i:ie], dv[i:ie], gt[kb:ke], gllh[kb:ke], gsig[kb:ke])
        out[j] = navigator_window_metrics(br, sc, s, length)
    ke = max(int(np.searchsorted(gt, t[-1], side="right")), k)  # fixes after the last sample are never pushed
    _push_scored(nav, data, i0, n, k, ke, scored, read)


def _aided_samples(nav: OnlineNavigator, updater: Updater, sc: Scenario, windows, order_w, data,
                   shared, out: list, scored=None, read=None) -> None:
    """The aided run and its branches sample by sample, the ``updater`` after every sample (its policy acts
    between samples); ``read(i)`` after each sample of ``scored``."""
    score = set() if scored is None else {int(q) for q in scored}
    t, dth, dv, gt, gllh, gsig = data
    n, ng = t.size, gt.size
    k = 0
    wi = 0
    for i in range(n):
        ti = t[i]
        while wi < len(order_w) and windows[order_w[wi]][0] <= ti:
            j = order_w[wi]
            s, length = windows[j]
            while k < ng and gt[k] < s:
                nav.push_gnss(gt[k], gllh[k], gsig[k])
                k += 1
            br, bu = _fork(nav, updater, shared)
            kb = int(np.searchsorted(gt, s + length, side="left"))
            ib = i
            while ib < n and t[ib] < s + length + BRANCH_MARGIN_S:
                while kb < ng and gt[kb] <= t[ib]:
                    br.push_gnss(gt[kb], gllh[kb], gsig[kb])
                    kb += 1
                br.push_imu(t[ib], dth[ib], dv[ib])
                bu.step(br)
                ib += 1
            out[j] = window_metrics(branch_errors(br.finish(), sc, s), s, length)
            wi += 1
        while k < ng and gt[k] <= ti:
            nav.push_gnss(gt[k], gllh[k], gsig[k])
            k += 1
        nav.push_imu(ti, dth[i], dv[i])
        updater.step(nav)
        if i in score:
            read(i)


def _unguarded(config: OnlineConfig, updater: Updater | None) -> OnlineConfig:
    """``config`` without the stop guard where it has no effect on the navigation: the guard only chooses which
    detected stops are modelled (:mod:`imunoise.online.stops`), so a run that models nothing (no modelling, no
    ZUPT, no in-motion learner, no updater reading the kept stops) navigates the same to the bit without it,
    and skips the guard's per-sample rows over every static sample of the aided run and of each branch."""
    if (config.modelling or config.zupt or config.motion_noise is not None or updater is not None
            or config.stop_guard == "none"):
        return config
    return config.with_(stop_guard="none")


def run_windows(sc: Scenario, config: OnlineConfig, gnss, windows: Sequence[tuple[float, float]], *,
                initial_models=None, updater: Updater | None = None, keep: bool = False,
                earlier_static: Sequence[np.ndarray] | None = None, nees: bool = False,
                prepare: Callable[[OnlineNavigator], Any] | None = None) -> dict:
    """One aided run (``gnss`` everywhere) with a GNSS-free branch per window (module docstring);
    ``earlier_static``: the navigator's (static pieces of earlier drives of the same IMU); ``prepare(nav)``: called on
    the new navigator before its first sample (the ``in_use_stops`` row attaches its in-motion schedule there).

    Returns ``windows`` (per window ``drift``, ``rms``, ``drift_v``, ``aided_rms``) and the aided run's
    ``horizontal_rms_m``/``vertical_rms_m``; ``_full`` (the aided OnlineResult) when ``keep``; with ``nees`` the
    aided run's NEES of position + velocity (``nees``: :func:`imunoise.experiments.nees.drive_nees`)."""
    if not keep:  # a kept result reports its stops as guarded
        config = _unguarded(config, updater)
    t = np.asarray(sc.imu.t, dtype=float)
    dth, dv = sc.imu.increments()
    gt = np.asarray(gnss.t, dtype=float)
    order = np.argsort(gt, kind="stable")
    gt, gllh, gsig = gt[order], np.asarray(gnss.llh)[order], np.asarray(gnss.sigma_ned)[order]
    cache = sc.extra.setdefault("job_cache", {})
    nav = OnlineNavigator(config, sc.init, imu_rate_hz=sc.rate, initial_models=initial_models, job_cache=cache,
                          earlier_static=earlier_static)
    if sc.extra.get("streams"):  # GNSS velocity, odometer, ...: every branch keeps them through its window
        nav.add_streams(*sc.extra["streams"])
    if prepare is not None:  # e.g. a model file's in-motion schedule (imunoise.online.in_motion), before any sample
        prepare(nav)
    shared = [cache, sc, t, dth, dv, gt, gllh, gsig, sc.imu, sc.ref, config]
    if updater is not None:
        shared += list(updater.shared())
    order_w = sorted(range(len(windows)), key=lambda j: windows[j][0])
    out: list[dict | None] = [None] * len(windows)
    data = (t, dth, dv, gt, gllh, gsig)
    scored, read, values = _nees_reader(nav, sc, t) if nees else (None, None, [])
    if updater is None:
        _aided_chunks(nav, sc, windows, order_w, data, shared, out, scored, read)
    else:
        _aided_samples(nav, updater, sc, windows, order_w, data, shared, out, scored, read)
    full = err = None
    if not keep:  # the errors from the stored epochs they read, the result over the whole drive not built
        err = stored_errors(nav, sc)
    if err is None:
        full = nav.finish()
        err = nav_errors(full.t, full.antenna_llh(sc.lever), full.vel_ned, full.euler, sc.ref)
    for j, (s, length) in enumerate(windows):
        m = (err.t >= s) & (err.t < s + length)
        h = err.horizontal[m]
        if out[j] is None:
            out[j] = {"drift": None, "rms": None, "drift_v": None}
        out[j]["aided_rms"] = float(np.sqrt(np.mean(h * h))) if h.size else None
    res: dict[str, Any] = {"windows": out,
                           "horizontal_rms_m": float(np.sqrt(np.mean(err.horizontal ** 2))),
                           "vertical_rms_m": float(np.sqrt(np.mean(err.vertical ** 2)))}
    if nees:
        res["nees"] = drive_nees(values)
    if keep:
        res["_full"] = full
    return res


def _nees_reader(nav: OnlineNavigator, sc: Scenario, t: np.ndarray):
    """(scored sample indices, the reader that appends the NEES of ``nav``'s state at a sample, the values)."""
    idx, ref = scored_epochs(sc, t)
    of = dict(zip(idx.tolist(), ref.tolist(), strict=True))
    values: list[float] = []

    def read(i: int) -> None:
        st = nav.ekf.state()
        e = epoch_error(sc, of[int(i)], st["llh"], st["euler"], st["vel_ned"])
        values.append(nees6(e, nav.ekf.P))

    return idx, read, values


def evaluate_method(sc: Scenario, name: str, gnss, windows, *, base: OnlineConfig | None = None,
                    cache: dict | None = None, prior: MotionNoisePrior | None = None,
                    earlier_static: Sequence[np.ndarray] | None = None, nees: bool = False,
                    in_use: Any = None) -> dict:
    """:func:`run_windows` for one method (:func:`method_setup`); ``earlier_static`` the earlier drives' stops
    a ``gmwm_warm`` method pools (:func:`~imunoise.experiments.dense_warm.earlier_stops`); ``in_use`` the model
    the ``in_use`` method learned on the vehicle's earlier drives (:mod:`imunoise.experiments.in_use_method`)."""
    if base_method(name) in (*LEARNED_ROWS, "oracle_const") and name != base_method(name):
        raise ModelError(f"{name}: {base_method(name)} has no scale-factor or NHC variant (the in-motion filter "
                         f"has no such states); use {base_method(name)}")
    if (name in LEARNED_ROWS) != (in_use is not None):
        raise ModelError(f"{', '.join(LEARNED_ROWS)} navigate with the model learned on the vehicle's earlier drives, "
                         "and only they take one: run them on the simulator with --vehicle-drives 2 or more")
    if name == "in_use":
        from imunoise.experiments.in_use_method import run_windows_in_use

        return {**run_windows_in_use(sc, gnss, windows, in_use, base=base, nees=nees), "in_use": in_use.summary()}
    if name == "in_use_stops":
        from imunoise.experiments.in_use_method import in_use_stops_run

        cfg, kw = in_use_stops_run(sc, in_use, base=base, cache=cache)
        return {**run_windows(sc, cfg, gnss, windows, nees=nees, **kw), "in_use": in_use.summary()}
    if (base_method(name) in STATIC_WARM_METHODS) != (earlier_static is not None):
        raise ModelError(f"{name}: earlier drives' stops are for {', '.join(STATIC_WARM_METHODS)} only, and those "
                         "need them (the simulator makes them: run_sim)")
    if name == "oracle_law":  # the batch filter told the law's schedule (imunoise.experiments.oracle_law)
        from imunoise.experiments.oracle_law import run_windows_law

        return run_windows_law(sc, gnss, windows, base=base, nees=nees)
    if name == "oracle_const":  # the in_use filter with the truth's constant model (imunoise.experiments.oracle_const)
        from imunoise.experiments.oracle_const import run_windows_const

        return run_windows_const(sc, gnss, windows, base=base, nees=nees)
    if name == "oracle_const_gmwm":  # the same on in_use's static part
        from imunoise.experiments.oracle_const import run_windows_const

        return run_windows_const(sc, gnss, windows, base=base, nees=nees, models=in_use.models)
    cfg, models, upd = method_setup(name, sc, base, cache, prior=prior)
    return run_windows(sc, cfg, gnss, windows, initial_models=models, updater=upd, earlier_static=earlier_static,
                       nees=nees)
