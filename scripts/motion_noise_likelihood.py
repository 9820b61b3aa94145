"""Can a likelihood identify the in-motion noise within one drive? (issue 24; a development diagnostic for the
design of the in-motion noise learner's decision statistic, not a method: nothing here changes the learner.)

Per simulated drive (the simulator's default 10-min drive, ``--law``, meter-level GNSS ``--gnss``) the GNSS-aided
filter (no outages) runs with the TRUE static per-axis models (the ``oracle`` mapping, no floor) and a one-parameter
family of in-motion inflations, k on a grid: while the online engine's static detector says "moving" (its raw
per-sample test with λ_0 learned from the first ``learn_lambda0_s``, as :class:`~imunoise.online.OnlineNavigator`
does; the first N samples, before its window is full, count as not moving; ``--switch truth``: the simulator's
true motion), the white PSD of axis a is multiplied by W_a^k and the driving noise of its bias states by B_a^k
(:class:`~imunoise.nav.noise_schedule.NoiseControl`), where W_a = mean m_w², B_a = mean m_b² of the family law
(``--family-law``, default ``drive0708``) over the drive's moving samples: k = 0 is the static model, k = 1 the
oracle's moving model (:func:`imunoise.sim.motion.oracle_models`, applied while moving only), i.e. k is the way
from the static to the oracle's moving models in log-variance. Under ``--law none`` k = 0 is the truth (the harm
side). For every k:

(a) the one-step GNSS position innovation NLL, Σ over fixes of −log N(ν; 0, S), S = HPHᵀ + R before the update
    (the kernel's own :func:`~imunoise.nav.filter_loop.gnss_position_update`, called fix by fix from here);
(b) the multi-step predictive NLL: every ``--every`` s while the filter moves (≥ the learner's 2 m/s), a copy of
    the aided filter runs ``--window`` s without fixes and every fix of that span is scored with its predicted
    position covariance + R (a composite likelihood: Σ of the per-fix marginals; ``b_h`` the horizontal part);
(c) the learner's current statistic on the same spans: log RMS horizontal distance to the fixes
    (:mod:`imunoise.online.learner.rehearsal`), summed over the spans.

Per drive and horizon (first 2, 5, 10 min): each criterion's argmin k, Δ = crit(k=1) − crit(k=0), and a
within-drive z (the paired differences per 20-s block, mean / SE: the test one drive could run online). Over the
drives: paired 95 % t-interval of Δ, the share of drives with Δ < 0 and with z < −1.645, and the share whose
likelihood-ratio test of k = 0 against the best k of the grid, LR = 2(crit(0) − min_k crit(k)) > 2.71, rejects
k = 0 (a 5 % test on the boundary, ½χ²₀ + ½χ²₁; meaningful for (a), the exact likelihood of all fixes by the
prediction-error decomposition, not for the composite (b)).

    python scripts/motion_noise_likelihood.py --seeds 3200-3219 --law drive0708 --out out/lik_drive0708
    python scripts/motion_noise_likelihood.py --seeds 3200-3219 --law none --out out/lik_none
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import multiprocessing as mp
import sys
from typing import Any

import numpy as np

GRID = (0.0, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0)
CRITERIA = ("a", "b", "b_h", "c")
LABELS = {"a": "(a) one-step innovation NLL", "b": "(b) 20-s predictive NLL", "b_h": "(b) horizontal only",
          "c": "(c) log RMS drift (learner)"}
LOG2PI = math.log(2.0 * math.pi)
LR_CRIT = 2.706  # 5 % test of k = 0 on the boundary (½χ²₀ + ½χ²₁): the χ²₁ 90 % quantile


def gaussian_nll(nu: np.ndarray, S: np.ndarray) -> np.ndarray:
    """−log N(ν; 0, S) = ½(νᵀS⁻¹ν + log det S + d log 2π) for rows ν (n, d) and covariances S (n, d, d)."""
    nu = np.atleast_2d(np.asarray(nu, dtype=float))
    S = np.asarray(S, dtype=float).reshape(nu.shape[0], nu.shape[1], nu.shape[1])
    L = np.linalg.cholesky(S)
    z = np.linalg.solve(L, nu[:, :, None])[:, :, 0]
    logdet = 2.0 * np.log(np.diagonal(L, axis1=1, axis2=2)).sum(axis=1)
    return 0.5 * (np.sum(z * z, axis=1) + logdet + nu.shape[1] * LOG2PI)


def scalar_kf_nll(y: np.ndarray, q: float, r: float, p0: float) -> np.ndarray:
    """Per-step innovation NLL of a random walk x_k = x_{k−1} + w (var q), y_k = x_k + v (var r), x_0 ~ N(0, p0):
    the prediction-error decomposition (sums to −log p(y_1..y_n))."""
    x, p, out = 0.0, p0, []
    for yk in np.asarray(y, dtype=float):
        p += q
        s = p + r
        nu = yk - x
        out.append(gaussian_nll(np.array([[nu]]), np.array([[[s]]]))[0])
        g = p / s
        x += g * nu
        p *= 1.0 - g
    return np.array(out)


# ------------------------------------------------------------------------------------------------------------
# one drive
# ------------------------------------------------------------------------------------------------------------
def moving_flags(sc, t_filter: np.ndarray, i0: int) -> np.ndarray:
    """The online engine's raw per-sample "not static" on the filter's samples (λ_0 learned as it learns it)."""
    from dataclasses import replace

    from imunoise.detect import DetectorConfig, detect_static, learn_lambda0
    from imunoise.errors import ImunoiseError
    from imunoise.online import OnlineConfig

    gyro, accel = sc.imu.rates()
    t = np.asarray(sc.imu.t, dtype=float)
    base = DetectorConfig()
    held = t < t[0] + OnlineConfig().learn_lambda0_s
    try:
        lam = learn_lambda0(np.asarray(accel)[held], window=base.window)
    except ImunoiseError:
        lam = base.lambda0
    det = detect_static(t, np.asarray(accel), np.asarray(gyro), replace(base, lambda0=lam), rate_hz=sc.rate)
    # the window-filling first N samples (statistic NaN) are "not static" for the detector but not motion
    moving = ~det.static_raw & np.all(np.isfinite(det.statistic), axis=1)
    return np.asarray(moving[i0 : i0 + t_filter.size], dtype=bool)


def family_scales(sc, family_law: str, law: str) -> tuple[np.ndarray, np.ndarray, str]:
    """(W, B): per axis mean m_w², m_b² of ``family_law`` over the drive's moving samples (the oracle's moving
    models are the static ones scaled by √W, √B: :func:`imunoise.sim.motion.oracle_models`)."""
    from imunoise.sim.motion import resolve_motion

    sched = sc.extra.get("law_schedule")
    if law == family_law and sched is not None:
        mv = np.asarray(sched.moving, dtype=bool)
        return sched.white_var_scale[mv].mean(axis=0), sched.bias_var_scale[mv].mean(axis=0), "law schedule"
    t = np.asarray(sc.imu.t, dtype=float)
    rt = np.asarray(sc.ref.t, dtype=float)
    vel = np.column_stack([np.interp(t, rt, np.asarray(sc.ref.vel_ned)[:, j]) for j in range(3)])
    eul = np.unwrap(np.asarray(sc.ref.euler, dtype=float), axis=0)
    rates = np.gradient(eul, rt, axis=0)
    turn = np.interp(t, rt, np.linalg.norm(rates, axis=1))
    acc = np.interp(t, rt, np.linalg.norm(np.gradient(np.asarray(sc.ref.vel_ned), rt, axis=0), axis=1))
    static = np.asarray(sc.static_truth, dtype=bool)
    mw, mb = resolve_motion(family_law).multipliers(np.linalg.norm(vel, axis=1)[~static], turn[~static],
                                                    accel=acc[~static])
    return (mw * mw).mean(axis=0), (mb * mb).mean(axis=0), "reference kinematics"


def _folded_psd(sc, models: list) -> np.ndarray:
    """Per axis the part of the filter's white PSD that is folded short AR1 noise (scales as bias noise)."""
    from imunoise.imu import AXES
    from imunoise.noise.model import Model
    from imunoise.noise.processes import WN

    none = Model([WN(sigma2=1e-30)])
    st = sc.extra["static_models"]
    return np.array([max(m.white_variance() / f - st.get(AXES[a], none).white_variance() / f, 0.0)
                     for a, (m, f) in enumerate((m, m.freq) for m in models)])


def prepare(seed: int, law: str, gnss_spec: str, family_law: str, duration: float, stops: int = 4,
            switch: str = "detector", sigma_scale: float = 1.0) -> dict[str, Any]:
    from imunoise.experiments.common import filter_models, simulate_scenario
    from imunoise.experiments.gnss_regimes import parse_gnss
    from imunoise.experiments.oracle_law import law_filter
    from imunoise.imu import AXES
    from imunoise.noise.model import Model
    from imunoise.noise.processes import WN
    from imunoise.online import OnlineConfig

    sc = simulate_scenario(seed, n_outages=0, motion_noise=law, duration_s=duration, n_stops=stops)
    gnss = parse_gnss(gnss_spec).apply(sc.gnss, 1_000_003 * seed + 1)
    none = Model([WN(sigma2=1e-30)])
    cfg = OnlineConfig().with_(ekf=sc.ekf_config(), floor="none")
    models = filter_models([sc.extra["static_models"].get(ax, none) for ax in AXES], sc.rate, cfg)
    lf = law_filter(sc, (), models=models)  # the oracle's batch path: samples from init.t, the 30 °/s gate
    i0 = int(np.searchsorted(np.asarray(sc.imu.t), sc.init.t, side="right")) - 1
    W, B, src = family_scales(sc, family_law, law)
    gt = np.asarray(gnss.t, dtype=float)
    keep = (gt > sc.init.t) & (gt <= lf.imu.t[-1])
    moving = (moving_flags(sc, lf.imu.t, i0) if switch == "detector"
              else ~np.asarray(sc.static_truth, dtype=bool)[i0 : i0 + lf.imu.t.size])
    return {"sc": sc, "models": models, "imu": lf.imu, "moving": moving,
            "W": W, "B": B, "scale_source": src, "folded": _folded_psd(sc, models),
            "gt": gt[keep], "gllh": np.asarray(gnss.llh)[keep], "gsig": sigma_scale * np.asarray(gnss.sigma_ned)[keep]}


def run_member(p: dict, k: float, window_s: float, every_s: float, min_speed: float,
               starts: list[int] | None = None) -> dict[str, Any]:
    """The aided filter of family member k over the drive: per fix (a), per window (b), (c). ``starts``: the
    indices of the fixes that open a window (default: chosen here, every ``every_s`` at ≥ ``min_speed``; give
    the first member's ``starts`` to the others so that every member is scored on the same spans, as the
    learner tests the speed once per round for all its shadows)."""
    from imunoise.nav.filter_loop import FilterArrays, gnss_position_update
    from imunoise.nav.noise_schedule import NoiseControl, run_pieces
    from imunoise.nav.state import StateView
    from imunoise.nav.step_filter import LooselyCoupledEKF, new_outputs

    sc, imu = p["sc"], p["imu"]
    ekf = LooselyCoupledEKF(sc.ekf_config(), p["models"], sc.init, imu_rate_hz=sc.rate)
    ekf.prime(imu.dth[0], imu.dv[0])
    base, settings = ekf.kernel_parts()
    nc = NoiseControl(ekf.layout, base, ekf.dt_nom, bias_psd=p["folded"])
    m_static = nc.arrays()
    nc.set_noise_scale(p["W"] ** k, p["B"] ** k)
    m_moving = nc.arrays()
    moving = p["moving"]
    n = imu.t.size
    flips = np.flatnonzero(moving[1:] != moving[:-1])  # a piece ends at sample c when moving[c + 1] differs
    out = new_outputs(n, store_cov=False, has_sf=False)
    lever = ekf.lever
    no_fix = ekf.streams()
    floor = sc.ekf_config().gnss_sigma_floor

    def advance(f, a: int, b: int) -> None:
        cuts = flips[(flips > a) & (flips < b)]
        run_pieces(ekf, imu, f, no_fix, out, [a, *cuts, b], lambda x: m_moving if moving[x + 1] else m_static)

    def copy_of(f):
        return FilterArrays(*(v.copy() for v in f))

    gt, gllh, gsig = p["gt"], p["gllh"], np.maximum(p["gsig"], floor)
    at = np.minimum(np.searchsorted(imu.t, gt, side="left"), n - 1)  # the first sample with t ≥ the fix
    f = ekf.arrays()
    cur, reject = 0, 0
    nll3, nllh, used = np.empty(gt.size), np.empty(gt.size), np.zeros(gt.size, dtype=bool)
    windows: list[dict] = []
    next_w = -math.inf
    opened: list[int] = []
    start_set = None if starts is None else set(starts)
    for j in range(gt.size):
        i = int(at[j])
        if i > cur:
            advance(f, cur, i)
            cur = i
        m = m_moving if moving[min(cur + 1, n - 1)] else m_static
        nis, ok, dz, S, _ = gnss_position_update(f, m, settings, gllh[j], gsig[j], lever, imu.t[cur] - gt[j],
                                                 reject >= settings.max_reject)
        nll3[j] = gaussian_nll(dz[None], S[None])[0]
        nllh[j] = gaussian_nll(dz[None, :2], S[None, :2, :2])[0]
        used[j] = bool(ok)
        reject = 0 if ok else reject + 1
        due = (j in start_set) if start_set is not None else (
            gt[j] >= next_w and StateView(f.nav, f.P, f.xm).speed_h >= min_speed)
        if due:
            next_w = gt[j] + every_s
            opened.append(j)
            sel = np.flatnonzero((gt > gt[j]) & (gt <= gt[j] + window_s))
            if sel.size == 0:
                continue
            fb, bcur = copy_of(f), cur
            w3, wh, e2 = [], [], []
            for q in sel:
                iq = int(at[q])
                if iq > bcur:
                    advance(fb, bcur, iq)
                    bcur = iq
                mq = m_moving if moving[min(bcur + 1, n - 1)] else m_static
                _, _, dzq, Sq, _ = gnss_position_update(copy_of(fb), mq, settings, gllh[q], gsig[q], lever,
                                                        imu.t[bcur] - gt[q], True)
                w3.append(gaussian_nll(dzq[None], Sq[None])[0])
                wh.append(gaussian_nll(dzq[None, :2], Sq[None, :2, :2])[0])
                e2.append(float(dzq[0] ** 2 + dzq[1] ** 2))
            windows.append({"t0": float(gt[j]), "t1": float(gt[sel[-1]]), "n": int(sel.size),
                            "b": float(np.sum(w3)), "b_h": float(np.sum(wh)), "b_end": float(w3[-1]),
                            "c": math.log(max(math.sqrt(float(np.mean(e2))), 1e-3))})
    return {"k": k, "t": gt.tolist(), "a": nll3.tolist(), "a_h": nllh.tolist(), "used": used.tolist(),
            "windows": windows, "starts": opened}


def drive_job(args: tuple) -> dict[str, Any]:
    seed, law, gnss, family_law, duration, stops, switch, sigma_scale, grid, window_s, every_s, min_speed = args
    logging.getLogger("imunoise").setLevel(logging.WARNING)
    p = prepare(seed, law, gnss, family_law, duration, stops, switch, sigma_scale)
    first = run_member(p, 0.0, window_s, every_s, min_speed)  # the static model's filter picks the spans
    runs = [first if k == 0.0 else run_member(p, k, window_s, every_s, min_speed, first["starts"]) for k in grid]
    return {"seed": seed, "t0": float(p["sc"].imu.t[0]), "W": p["W"].tolist(), "B": p["B"].tolist(),
            "scale_source": p["scale_source"], "moving_share": float(np.mean(p["moving"])), "runs": runs}


# ------------------------------------------------------------------------------------------------------------
# criteria and the tables
# ------------------------------------------------------------------------------------------------------------
def criteria(drive: dict, horizon_s: float, block_s: float) -> dict[str, dict[str, Any]]:
    """Per criterion: the value at each k (first ``horizon_s`` of the drive), the 20-s block sums (for the
    within-drive z) and the argmin."""
    t_end = drive["t0"] + horizon_s
    out: dict[str, dict[str, Any]] = {}
    for c in CRITERIA:
        vals, blocks = [], []
        for r in drive["runs"]:
            if c == "a":
                t = np.asarray(r["t"])
                v = np.asarray(r["a"])[t <= t_end]
                b_id = np.floor((t[t <= t_end] - drive["t0"]) / block_s).astype(int)
                blk = np.bincount(b_id, weights=v) if v.size else np.zeros(0)
            else:
                blk = np.array([w[c] for w in r["windows"] if w["t1"] <= t_end])
            vals.append(float(blk.sum()))
            blocks.append(blk)
        out[c] = {"values": vals, "blocks": blocks, "argmin": int(np.argmin(vals))}
    return out


def paired_z(d: np.ndarray) -> float:
    """Mean / SE of a drive's per-block differences (one drive's own test); NaN with < 3 blocks."""
    if d.size < 3 or not np.std(d, ddof=1) > 0:
        return math.nan
    return float(d.mean() / (np.std(d, ddof=1) / math.sqrt(d.size)))


def summarize(drives: list[dict], grid: tuple, horizons: list[float], block_s: float) -> dict[str, Any]:
    from scipy.stats import t as student

    i0, i1 = grid.index(0.0), grid.index(1.0)
    res: dict[str, Any] = {}
    for h in horizons:
        per = [criteria(d, h, block_s) for d in drives]
        res[f"{h:g}"] = {}
        for c in CRITERIA:
            delta = np.array([p[c]["values"][i1] - p[c]["values"][i0] for p in per])
            z = np.array([paired_z(p[c]["blocks"][i1] - p[c]["blocks"][i0]) for p in per])
            argk = [grid[p[c]["argmin"]] for p in per]
            best_gain = np.array([min(p[c]["values"]) - p[c]["values"][i0] for p in per])
            lr = -2.0 * best_gain  # likelihood ratio of the best k against k = 0 (for the likelihoods (a), (b))
            nd = delta.size
            m, s = float(delta.mean()), float(delta.std(ddof=1)) if nd > 1 else math.nan
            half = float(student.ppf(0.975, nd - 1) * s / math.sqrt(nd)) if nd > 1 else math.nan
            res[f"{h:g}"][c] = {
                "delta": delta.tolist(), "delta_mean": m, "delta_sd": s, "delta_ci": [m - half, m + half],
                "share_prefers_k1": float(np.mean(delta < 0)), "z": z.tolist(),
                "share_z_decides_k1": float(np.mean(z < -1.645)),
                "median_z": float(np.nanmedian(z)) if np.any(np.isfinite(z)) else math.nan,
                "argmin_k": argk, "share_argmin_pos": float(np.mean(np.array(argk) > 0)),
                "median_argmin_k": float(np.median(argk)), "best_minus_k0": best_gain.tolist(),
                "lr": lr.tolist(), "share_lr_rejects_k0": float(np.mean(lr > LR_CRIT)),
                "values": [p[c]["values"] for p in per]}
    return res


def markdown(meta: dict, res: dict) -> str:
    lines = [f"In-motion noise family k (0 = static, 1 = the oracle's moving model of `{meta['family_law']}`, "
             f"log-variance, applied while moving) on {len(meta['seeds'])} drives of law `{meta['law']}` "
             f"(seeds {meta['seeds_text']}, GNSS {meta['gnss']}, filter told {meta['gnss_sigma_scale']:g}× its σ, "
             f"{meta['duration']:g} s, switch: {meta['switch']}), "
             f"grid {list(meta['grid'])}. "
             "Δ = crit(k=1) − crit(k=0) summed over the horizon (negative: prefers the oracle's model), paired "
             "95 % t-CI over drives; z: one drive's paired test over 20-s blocks; 'z decides' = z < −1.645; "
             "LR = 2(crit(0) − min_k crit(k)) > 2.71: the likelihood-ratio test of k = 0 at 5 % (boundary: "
             "½χ²₀ + ½χ²₁; calibrated for (a), not for the composite (b)).", "",
             "| horizon | criterion | Δ mean [95 % CI] | sd over drives | Δ<0 | z decides k=1 | median z | "
             "argmin k: median, share > 0 | LR > 2.71 |", "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for h, per in res.items():
        for c in CRITERIA:
            r = per[c]
            lines.append(f"| {float(h) / 60:g} min | {LABELS[c]} | {r['delta_mean']:.2f} [{r['delta_ci'][0]:.2f}, "
                         f"{r['delta_ci'][1]:.2f}] | {r['delta_sd']:.2f} | {r['share_prefers_k1']:.0%} | "
                         f"{r['share_z_decides_k1']:.0%} | {r['median_z']:.2f} | {r['median_argmin_k']:g}, "
                         f"{r['share_argmin_pos']:.0%} | "
                         + (f"{r['share_lr_rejects_k0']:.0%} |" if c != "c" else "n/a |"))
    last = list(res)[-1]
    lines += ["", f"Mean over drives of crit(k) − crit(k=0) over the first {float(last) / 60:g} min (curve shape; "
              "sd over drives in brackets):", "",
              "| criterion | " + " | ".join(f"k={k:g}" for k in meta["grid"]) + " |",
              "|---|" + "---:|" * len(meta["grid"])]
    for c in CRITERIA:
        v = np.asarray(res[last][c]["values"], dtype=float)
        d = v - v[:, [list(meta["grid"]).index(0.0)]]
        sd = d.std(axis=0, ddof=1) if d.shape[0] > 1 else np.full(d.shape[1], math.nan)
        lines.append(f"| {LABELS[c]} | " + " | ".join(f"{x:.2f} ({y:.2f})" for x, y in zip(d.mean(axis=0), sd)) + " |")
    return "\n".join(lines) + "\n"


def _seeds(text: str) -> list[int]:
    if "-" in text:
        a, b = text.split("-")
        return list(range(int(a), int(b) + 1))
    return [int(x) for x in text.split(",")]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", default="3200-3209", help="development simulator seeds, a-b or a,b,c (< 1 000 000)")
    ap.add_argument("--law", default="drive0708", help="the drives' motion law (default drive0708)")
    ap.add_argument("--family-law", default="drive0708", help="the law whose moving models are k = 1")
    ap.add_argument("--gnss", default="noise:1.5,3,1")
    ap.add_argument("--duration", type=float, default=600.0, help="drive length [s] (default 600, the simulator's)")
    ap.add_argument("--stops", type=int, default=4, help="stops in a drive (default 4, the simulator's)")
    ap.add_argument("--switch", choices=("detector", "truth"), default="detector",
                    help="moving/stopped switch of the family: the online engine's static detector (default) or the "
                         "simulator's true motion")
    ap.add_argument("--gnss-sigma-scale", type=float, default=1.0,
                    help="the filter is told this times the fixes' true 1σ (a misstated receiver σ; default 1)")
    ap.add_argument("--grid", default=",".join(f"{k:g}" for k in GRID), help="k values (must hold 0 and 1)")
    ap.add_argument("--horizons", default="120,300,600", help="first seconds of the drive scored")
    ap.add_argument("--window", type=float, default=20.0, help="free propagation of (b), (c) [s]")
    ap.add_argument("--every", type=float, default=20.0, help="a window every this many s while moving")
    ap.add_argument("--min-speed", type=float, default=2.0, help="a window starts only at ≥ this speed [m/s]")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--out", required=True, help="output folder (likelihood.json, likelihood.md)")
    a = ap.parse_args(argv)
    from pathlib import Path

    from imunoise.errors import ImunoiseError
    from imunoise.io.atomic import atomic_write_text

    seeds = _seeds(a.seeds)
    grid = tuple(float(x) for x in a.grid.split(","))
    if any(s >= 1_000_000 for s in seeds) or 0.0 not in grid or 1.0 not in grid:
        raise ImunoiseError("--seeds must be development seeds (< 1 000 000) and --grid must hold 0 and 1")
    horizons = [min(float(x), a.duration) for x in a.horizons.split(",")]
    jobs = [(s, a.law, a.gnss, a.family_law, a.duration, a.stops, a.switch, a.gnss_sigma_scale, grid, a.window,
             a.every, a.min_speed) for s in seeds]
    if a.workers > 1:
        with mp.get_context("fork").Pool(a.workers) as pool:
            drives = pool.map(drive_job, jobs)
    else:
        drives = [drive_job(j) for j in jobs]
    meta = {"seeds": seeds, "seeds_text": a.seeds, "law": a.law, "family_law": a.family_law, "gnss": a.gnss,
            "duration": a.duration, "stops": a.stops, "switch": a.switch, "gnss_sigma_scale": a.gnss_sigma_scale,
            "grid": grid, "window_s": a.window,
            "every_s": a.every, "min_speed": a.min_speed}
    res = summarize(drives, grid, horizons, a.every)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    per_drive = [{k: d[k] for k in ("seed", "W", "B", "scale_source", "moving_share")}
                 | {"n_fixes": len(d["runs"][0]["t"]), "n_windows": [len(r["windows"]) for r in d["runs"]],
                    "rejected": [int(np.sum(~np.asarray(r["used"]))) for r in d["runs"]]} for d in drives]
    atomic_write_text(out / "likelihood.json", json.dumps({"meta": meta, "drives": per_drive, "results": {
        h: {c: {k: v for k, v in r.items()} for c, r in per.items()} for h, per in res.items()}}, indent=1))
    text = markdown(meta, res)
    atomic_write_text(out / "likelihood.md", text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
