"""Why the in-motion estimate's accelerometer white factor sometimes comes out near 25 on simulated drives whose
true factor is 1 (docs/evidence/in_use_estimate.md, 'Why the accelerometer white factor sometimes comes out near
25 (development)').

    python scripts/in_use_accel_white_diagnosis.py --drives 4703:gyro_moving_gm --estimate --out out/accwhite/d4703.json
    python scripts/in_use_accel_white_diagnosis.py --drives 7520100:none 7520104:none --estimate \
        --out out/accwhite/dnone.json
    python scripts/in_use_accel_white_diagnosis.py --drives 7520104:none --profile-only --gnss-sigma 0.3 0.3 0.6 \
        --out out/accwhite/sig03.json
    python scripts/in_use_accel_white_diagnosis.py --drives 7520104:none --profile-only --gnss-sigma 3 3 6 \
        --out out/accwhite/sig3.json

(the drives where it shows found with ``scripts/in_use_estimate.py sim --laws none --seeds 7520100 7520130``;
development seeds only.)

Per drive (seed:law; 600 s, 4 stops, no outages, the static part the simulator's true static model, as
``scripts/in_use_estimate.py sim`` builds them: :func:`imunoise.experiments.oracle_const.true_static_models`):

* ``estimate`` (with ``--estimate``): :func:`imunoise.inuse.estimate_in_motion` as the recovery runs it, its
  group values and the white factor's likelihood-ratio test;
* ``profile``: the pooled NLL (:class:`imunoise.inuse.likelihood.DriveLikelihood`) over the accelerometer white
  factor on a log grid 0.3 … 100, no wander, the gyro group at factor 1 and (with ``--estimate``) at the
  estimate's gyro values;
  with the grid's minimum, its likelihood interval (ΔNLL ≤ 1.92) and the Wald interval of the curvature there;
  ``--gnss-sigma`` changes the GNSS σ (where the profile's wall lies), ``--profile-only`` stops here;
* ``epochs``: per GNSS fix the NLL at factor 1 minus that at ``--factor`` (the gain), with the filter's χ² gate as
  the estimate runs it and without it (gate off, ``gate_abs_m`` 0: then the NIS is the innovation's quadratic form
  q and the term ½(q + log det S) splits into its two parts); the gain's share carried by the top 1/3/10 fixes,
  on moving and static fixes, within 5 s of a change of the moving flag, and by tercile of the drive's horizontal
  acceleration and turn rate (reference trajectory at the fix);
* ``parts``: the gain at ``--factor`` when the drive's IMU carries only some of its errors (the simulator's true
  increments plus its model error paths and/or its turn-on bias, realigned as the scenario aligns): which error
  makes a larger accelerometer white factor fit better;
* ``models``: per axis the Allan deviation of the filter's static model against the simulator's true one at
  τ = 0.01 … 100 s (σ_A² = 2ν², ν² the Haar wavelet variance at scale 2τ).

Deterministic: every random draw is the simulator's, seeded by the drive's seed.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from imunoise.experiments.oracle_const import true_static_models

GRID = [0.3, 0.5, 1.0, 2.0, 3.0, 5.0, 8.0, 12.0, 16.0, 20.0, 25.0, 30.0, 40.0, 50.0, 70.0, 100.0]
TAUS_S = [0.01, 0.1, 1.0, 10.0, 100.0]


def _drive(seed: int, law: str, duration: float, stops: int, gnss_sigma: list | None):
    """The scenario (as the recovery builds it) and the simulated drive behind it (true increments, error paths);
    ``gnss_sigma`` (N, E, D [m]) replaces the simulator's GNSS σ (simulated and reported) when given."""
    from imunoise.experiments.common import SIM_IMU, simulate_scenario
    from imunoise.sim import DriveConfig, simulate_drive

    kw = {} if gnss_sigma is None else {"gnss_sigma_m": tuple(gnss_sigma)}
    sc = simulate_scenario(seed, duration_s=duration, motion_noise=law, n_outages=0, n_stops=stops, **kw)
    dr = simulate_drive(DriveConfig(duration_s=duration, n_stops=stops, seed=seed, motion_noise=law, **kw), SIM_IMU,
                        seed=seed)
    if not np.array_equal(np.asarray(dr.imu.dv), np.asarray(sc.imu.dv)):
        raise SystemExit(f"seed {seed}: the re-simulated drive differs from the scenario's")
    return sc, dr


def _run(sc, models, moving, gyro: tuple, accel: float, cfg=None):
    from imunoise.nav.ekf import run_ekf
    from imunoise.nav.filter_model import in_motion_filter

    gw, gs, gt = gyro
    imf = in_motion_filter(models, (gw,) * 3 + (accel,) * 3, (gs,) * 3 + (0.0,) * 3, (gt,) * 3 + (60.0,) * 3)
    return run_ekf(sc.imu, sc.gnss, sc.init, cfg or sc.ekf_config(), in_motion=imf, moving=moving, with_nll=True)


def _estimate(sc, models) -> dict:
    from imunoise.inuse import estimate_in_motion

    est = estimate_in_motion([sc], models, freq=sc.rate, names=[sc.name])
    th = est.theta
    ax = est.part.axes
    return {"gyro": [th.white[0], th.sigma[0], th.tau_s[0]], "accel": [th.white[3], th.sigma[3], th.tau_s[3]],
            "accel_white": ax["accel_x"].white_factor.to_dict(), "gyro_white": ax["gyro_x"].white_factor.to_dict(),
            "lr_white_one": est.part.evidence.get("lr_white_one", {}), "lr_wander": est.lr_wander,
            "nll": est.nll, "runs": est.runs}


def _profile(sc, models, moving, gyro: tuple) -> list:
    return [[f, float(np.nansum(_run(sc, models, moving, gyro, f).gnss_nll))] for f in GRID]


def _profile_summary(prof: list) -> dict:
    """The grid's minimum, the likelihood interval on the grid (NLL ≤ min + 1.92, ½χ²₁(0.95)) and the Wald
    interval from the curvature at the grid's minimum in log f (neighbouring grid points), as the estimate's
    Hessian takes it there."""
    f = np.array([x for x, _ in prof])
    v = np.array([y for _, y in prof])
    i = int(np.argmin(v))
    inside = f[v <= v[i] + 1.92]
    out = {"f_min": float(f[i]), "dnll_min_vs_1": float(v[i] - v[f == 1.0][0]),
           "lik_interval_grid": [float(inside.min()), float(inside.max())], "wald": None}
    if 0 < i < f.size - 1:
        u = np.log(f[i - 1:i + 2])
        c = np.polyfit(u, v[i - 1:i + 2], 2)[0] * 2.0  # second derivative in log f
        if c > 0:
            sd = 1.0 / math.sqrt(c)
            out["wald"] = [float(f[i] * math.exp(-1.96 * sd)), float(f[i] * math.exp(1.96 * sd))]
    return out


def _shares(gain: np.ndarray, masks: dict) -> dict:
    tot = float(np.nansum(gain))
    o = np.argsort(-np.nan_to_num(gain))
    out = {"total": tot, **{f"top{n}": float(np.sum(gain[o[:n]])) for n in (1, 3, 10)}}
    out.update({k: float(np.nansum(gain[m])) for k, m in masks.items()})
    return out


def _epochs(sc, models, moving, factor: float) -> dict:
    """The per-fix gain of ``factor`` over 1 (gyro at 1, no wander), with and without the gate."""
    t_imu = np.asarray(sc.imu.t)
    ref_t = np.asarray(sc.ref.t)
    vel = np.asarray(sc.ref.vel_ned)[:, :2]
    acc = np.linalg.norm(np.gradient(vel, ref_t, axis=0), axis=1)
    turn = np.degrees(np.abs(np.gradient(np.unwrap(np.asarray(sc.ref.euler)[:, 2]), ref_t)))
    out = {}
    for lab, cfg in (("gate", sc.ekf_config()), ("no_gate", sc.ekf_config().with_(chi2_gate=0.0, gate_abs_m=0.0))):
        r1 = _run(sc, models, moving, (1.0, 0.0, 60.0), 1.0, cfg)
        ra = _run(sc, models, moving, (1.0, 0.0, 60.0), factor, cfg)
        t = np.asarray(r1.gnss_t)
        k = np.searchsorted(t_imu, t).clip(0, t_imu.size - 1)
        kr = np.searchsorted(ref_t, t).clip(0, ref_t.size - 1)
        mv = moving[k]
        flips = t_imu[np.flatnonzero(np.diff(moving.astype(int)) != 0) + 1]
        near = np.min(np.abs(t[:, None] - flips[None, :]), axis=1) <= 5.0 if flips.size else np.zeros(t.size, bool)
        gain = np.asarray(r1.gnss_nll) - np.asarray(ra.gnss_nll)
        a_t, w_t = np.nanpercentile(acc[kr], [33.3, 66.7]), np.nanpercentile(turn[kr], [33.3, 66.7])
        masks = {"moving": mv, "static": ~mv, "within_5s_of_flag_change": near, "moving_away_from_change": mv & ~near,
                 "acc_low": acc[kr] <= a_t[0], "acc_mid": (acc[kr] > a_t[0]) & (acc[kr] <= a_t[1]),
                 "acc_high": acc[kr] > a_t[1], "turn_low": turn[kr] <= w_t[0],
                 "turn_mid": (turn[kr] > w_t[0]) & (turn[kr] <= w_t[1]), "turn_high": turn[kr] > w_t[1]}
        row = {"nll_1": float(np.nansum(r1.gnss_nll)), "nll_f": float(np.nansum(ra.gnss_nll)),
               "rejected_1": int(np.sum(np.asarray(r1.gnss_status) == 0)),
               "rejected_f": int(np.sum(np.asarray(ra.gnss_status) == 0)),
               "n_fixes": int(np.sum(np.isfinite(gain))), "n_moving": int(mv.sum()), "gain": _shares(gain, masks),
               "terciles_acc_m_s2": a_t.tolist(), "terciles_turn_deg_s": w_t.tolist()}
        if lab == "no_gate":  # NIS = q exactly: split ½(q + log det S)
            q1, qa = np.asarray(r1.gnss_nis), np.asarray(ra.gnss_nis)
            c = 3.0 * math.log(2.0 * math.pi)
            ld1, lda = 2 * np.asarray(r1.gnss_nll) - q1 - c, 2 * np.asarray(ra.gnss_nll) - qa - c
            row["gain_innovation_term"] = float(0.5 * np.nansum(q1 - qa))
            row["gain_logdet_term"] = float(0.5 * np.nansum(ld1 - lda))
            row["mean_q_1"] = {"moving": float(np.nanmean(q1[mv])), "static": float(np.nanmean(q1[~mv]))}
            o = np.argsort(-np.nan_to_num(gain))[:5]
            row["top5"] = [{"t_s": float(t[i] - t_imu[0]), "gain": float(gain[i]), "q_1": float(q1[i]),
                            "q_f": float(qa[i]), "moving": bool(mv[i]), "speed_m_s": float(np.hypot(*vel[kr[i]])),
                            "acc_m_s2": float(acc[kr[i]]), "turn_deg_s": float(turn[kr[i]])} for i in o]
        out[lab] = row
    return out


def _parts(sc, dr, models, moving, factor: float) -> dict:
    """The NLL at factor 1 and ``factor`` (gyro at 1, no wander) with only some of the drive's IMU errors."""
    from imunoise.imu import ImuData
    from imunoise.nav.align import coarse_align

    t = np.asarray(dr.imu.t)
    dt = np.diff(t, prepend=t[0] - 1.0 / sc.rate)[:, None]
    rt = np.column_stack([dr.imu_true.dtheta, dr.imu_true.dv]) / dt
    rm = np.column_stack([dr.imu.dtheta, dr.imu.dv]) / dt
    err = np.asarray(dr.model_errors)
    bias = np.median(rm - rt - err, axis=0)  # the turn-on bias (no scale factor, no vibration under a law)
    resid = float(np.max(np.abs(rm - rt - err - bias)))
    a, b = dr.truth["static_intervals"][0]
    g, z = np.s_[:, :3], np.zeros_like(err[:, :3])

    def with_rate(rate):
        imu = ImuData(t=t, dtheta=rate[g] * dt, dv=rate[:, 3:] * dt)
        init = coarse_align(imu, dr.gnss, float(t[0]) + 1.0, static_window=(a, b),
                            lever_arm=dr.config.lever_arm_m)
        return replace(sc, imu=imu, init=init)

    variants = {"actual": sc, "error_free": with_rate(rt), "turn_on_bias_only": with_rate(rt + bias),
                "model_errors_only": with_rate(rt + err),
                "gyro_model_errors_only": with_rate(rt + np.column_stack([err[g], z])),
                "accel_model_errors_only": with_rate(rt + np.column_stack([z, err[:, 3:]])),
                "all_but_gyro_model_errors": with_rate(rt + bias + np.column_stack([z, err[:, 3:]]))}
    out = {"turn_on_bias": bias.tolist(), "decomposition_residual": resid}
    for k, s2 in variants.items():
        n1 = float(np.nansum(_run(s2, models, moving, (1.0, 0.0, 60.0), 1.0).gnss_nll))
        nf = float(np.nansum(_run(s2, models, moving, (1.0, 0.0, 60.0), factor).gnss_nll))
        out[k] = {"nll_1": n1, "nll_f": nf, "gain": n1 - nf}
    return out


def _models(sc, models) -> dict:
    from imunoise.imu import AXES

    out = {}
    for j, ax in enumerate(AXES):
        true, filt, f = sc.extra["static_models"][ax], models[j], sc.rate
        adev = [[math.sqrt(2.0 * float(m.wv(np.array([2.0 * tau * f]))[0])) for tau in TAUS_S] for m in (true, filt)]
        out[ax] = {"true_model": str(true), "filter_model": str(filt), "adev_true": adev[0], "adev_filter": adev[1],
                   "ratio": [b / a for a, b in zip(*adev, strict=True)]}
    return out


def diagnose(seed: int, law: str, args) -> dict:
    from imunoise.inuse.likelihood import drive_moving

    sc, dr = _drive(seed, law, args.duration, args.stops, args.gnss_sigma)
    models = true_static_models(sc)
    moving = drive_moving(sc)
    row = {"seed": seed, "law": law, "factor": args.factor, "gnss_sigma_m": args.gnss_sigma}
    if args.estimate:
        row["estimate"] = _estimate(sc, models)
    row["profile_gyro_1"] = _profile(sc, models, moving, (1.0, 0.0, 60.0))
    if args.estimate:
        row["profile_gyro_est"] = _profile(sc, models, moving, tuple(row["estimate"]["gyro"]))
    for k in ("profile_gyro_1", "profile_gyro_est"):
        if k in row:
            row[k + "_summary"] = _profile_summary(row[k])
    if args.profile_only:
        return row
    row["epochs"] = _epochs(sc, models, moving, args.factor)
    row["parts"] = _parts(sc, dr, models, moving, args.factor)
    row["models"] = _models(sc, models)
    return row


def _print(row: dict) -> None:
    print(f"== seed {row['seed']} law {row['law']}")
    if "estimate" in row:
        e = row["estimate"]
        print("  estimate: accel white", e["accel_white"], "gyro white", e["gyro_white"], "gyro (f, σ, τ)",
              e["gyro"], "LR white=1", e["lr_white_one"])
    for k in ("profile_gyro_1", "profile_gyro_est"):
        if k in row:
            n0 = dict((f, v) for f, v in row[k])[1.0]
            print(f"  {k}: NLL − NLL(f=1):", " ".join(f"{f:g}:{v - n0:+.2f}" for f, v in row[k]))
            print("   ", row[k + "_summary"])
    if "epochs" not in row:
        return
    for lab, ep in row["epochs"].items():
        g = ep["gain"]
        print(f"  epochs {lab}: gain {g['total']:.2f} (top1 {g['top1']:.2f}, top3 {g['top3']:.2f}, top10 "
              f"{g['top10']:.2f}; moving {g['moving']:.2f}, static {g['static']:.2f}, ≤5 s of a flag change "
              f"{g['within_5s_of_flag_change']:.2f}; acc terciles {g['acc_low']:.2f}/{g['acc_mid']:.2f}/"
              f"{g['acc_high']:.2f}; turn terciles {g['turn_low']:.2f}/{g['turn_mid']:.2f}/{g['turn_high']:.2f}) "
              f"rejected {ep['rejected_1']}→{ep['rejected_f']} of {ep['n_fixes']}")
        if "gain_innovation_term" in ep:
            print(f"    innovation term {ep['gain_innovation_term']:+.2f}, log-det term {ep['gain_logdet_term']:+.2f};"
                  f" mean q at f=1: moving {ep['mean_q_1']['moving']:.2f}, static {ep['mean_q_1']['static']:.2f}")
    p = row["parts"]
    print("  parts: gain at the factor (NLL(1) − NLL(f)):",
          ", ".join(f"{k} {v['gain']:+.2f}" for k, v in p.items() if isinstance(v, dict)))
    print("  model adev ratio filter/true (τ 0.01…100 s):",
          {k: [round(x, 4) for x in v["ratio"]] for k, v in row["models"].items()})


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--drives", nargs="+", required=True, help="seed:law, e.g. 4703:gyro_moving_gm 7520101:none")
    p.add_argument("--factor", type=float, default=25.0, help="the accelerometer white factor against 1")
    p.add_argument("--duration", type=float, default=600.0, help="drive length [s]")
    p.add_argument("--stops", type=int, default=4)
    p.add_argument("--estimate", action="store_true", help="run the estimate too (gyro values for the profile)")
    p.add_argument("--gnss-sigma", nargs=3, type=float, default=None, help="GNSS σ N E D [m] (default: the "
                   "simulator's 1 1 2)")
    p.add_argument("--profile-only", action="store_true", help="the profiles alone (no epochs, parts, models)")
    p.add_argument("--out", required=True)
    args = p.parse_args(argv)
    rows = []
    for spec in args.drives:
        seed, law = spec.split(":")
        rows.append(diagnose(int(seed), law, args))
        _print(rows[-1])
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps({"argv": sys.argv, "rows": rows}, indent=1, default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
