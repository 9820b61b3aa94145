"""Why some gyro white factors of the ADIS16405 replay exceed 1 (docs/evidence/in_use_carry_over.md, 'Why some
ADIS16405 gyro white factors exceed 1'): per vehicle of a finished ``scripts/in_use_replay.py`` run, the gyro
white level of the real noise where the drives used it against the static part the in-use model carried.

For each unit (a recording) and vehicle v (seed s = seed0 + unit_step·(unit − 1) + v), with n = 60 001 samples per
600 s drive, the learning drive replays samples [2v·n, (2v+1)·n) and the scored drive [(2v+1)·n, (2v+2)·n)
(:func:`imunoise.sim.replay.stretch_index`); sample k is at k/f seconds of the drive. The stops are the drive
plan's static intervals (:func:`imunoise.sim.drive_plan.plan_drive` on the trajectory stream of the drive's seed,
the learning drive's seed being s + 7 000 000), without the final stop (the engine never completes it).

* white level N [rad/√s] of the data = σ_A(τ)·√τ at τ = 1 s (non-overlapping Allan deviation, blocks inside one
  stop or one moving stretch): of the whole 2.8 h log, at the learning drive's stops, while it moves, while the
  scored drive moves; and σ/√f (the per-sample spread: what a pure white-noise fit of the finest scale gives);
* the static part: the online engine's schedule on the learning drive's stops (identify on the first ≥
  ``min_static_s`` of stops with ``criterion="gof"``, as the ``gmwm`` row; refit after every later stop), mapped
  to the filter (:func:`imunoise.online.to_filter.filter_axis_models`), its N from
  :func:`imunoise.noise.equivalent_noise.equivalent_noise` (horizon 300 s, as the in-motion estimate's static N);
* the long-scale power: Allan deviation at τ = 10, 30, 100 s of the learning drive's whole stretch (stops and
  moving: the recording does not know the car moves) against that of the static filter model (σ_A² = 2 ν², ν²
  the model's Haar wavelet variance at the scale 2τ).

Usage: python scripts/in_use_white_diagnosis.py REPORT_DIR REC1.npz ... [--seed0 7300000] [--unit-step 10]
       [--seeds 8] [--out OUT.json]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

F = 100.0  # Hz, the recordings' and the simulator's rate
N_DRIVE = 60_001  # samples of a 600 s drive
LEARN_OFFSET = 7_000_000  # the learning drive of vehicle s is the simulated drive of s + this
TAUS_LONG = (10.0, 30.0, 100.0)  # s


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[a, b) of each run of True in ``mask``."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1), strict=True))


def allan_dev(x: np.ndarray, mask: np.ndarray, m: int) -> tuple[float, int]:
    """Non-overlapping Allan deviation at τ = m/F of ``x`` on the runs of ``mask`` (no block spans two runs) and the
    number of differences it averages (nan, 0 when none)."""
    diffs = []
    for a, b in runs(mask):
        k = (b - a) // m
        if k >= 2:
            diffs.append(np.diff(x[a:a + k * m].reshape(k, m).mean(axis=1)))
    if not diffs:
        return math.nan, 0
    d = np.concatenate(diffs)
    return math.sqrt(0.5 * float(np.mean(d * d))), int(d.size)


def white_level(x: np.ndarray, mask: np.ndarray) -> float:
    """N = σ_A(1 s)·√(1 s) [unit/√Hz]."""
    return allan_dev(x, mask, int(F))[0]


def plan_stops(seed: int) -> list[tuple[float, float]]:
    """The static intervals [s] of the 600 s, 4-stop drive of ``seed`` (static start first, final stop last)."""
    from imunoise.sim.drive_config import DriveConfig
    from imunoise.sim.drive_plan import plan_drive

    cfg = DriveConfig(duration_s=600.0, n_stops=4, seed=seed, motion_noise="none")
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(4)[0])  # simulate_drive's trajectory stream
    return [(float(a), float(b)) for a, b in plan_drive(cfg, rng).static_intervals]


def stop_mask(intervals: list[tuple[float, float]]) -> np.ndarray:
    m = np.zeros(N_DRIVE, dtype=bool)
    for a, b in intervals:
        m[int(math.ceil(a * F)):int(math.floor(b * F)) + 1] = True
    return m


def static_part(gyro: np.ndarray, intervals: list[tuple[float, float]], first_axis: int = 0) -> list:
    """The filter models of the online engine's schedule on the stops ``intervals`` (module docstring) of three
    axes' errors ``gyro`` (``first_axis`` 3: the accelerometers, with their unit and floor)."""
    from imunoise.noise.selection import refit, select_model
    from imunoise.noise.wv.accumulator import WVAccumulator
    from imunoise.online import OnlineConfig
    from imunoise.online.to_filter import filter_axis_models

    cfg = OnlineConfig(latency=0.5).with_(criterion="gof")  # the gmwm row's selection
    unit = "rad/s" if first_axis == 0 else "m/s²"
    acc = [WVAccumulator(freq=F) for _ in range(3)]
    fits: list = [None] * 3
    static_s = 0.0
    for a, b in intervals:
        i0, i1 = int(math.ceil(a * F)), int(math.floor(b * F)) + 1
        x = gyro[i0:i1] - gyro[i0:i1].mean(axis=0)
        for j in range(3):
            acc[j].add(x[:, j])
        static_s += (i1 - i0) / F
        if static_s < cfg.min_static_s:
            continue
        for j in range(3):
            wv = acc[j].result()
            fits[j] = (select_model(wv, freq=F, complete=cfg.complete, criterion=cfg.criterion, top=cfg.top,
                                    weights=cfg.weights, unit=unit).best if fits[j] is None else
                       refit(fits[j], wv, start=fits[j], freq=F, weights=cfg.weights, unit=unit))
    six = [*fits, None, None, None] if first_axis == 0 else [None, None, None, *fits]
    return filter_axis_models(six, F, cfg)[first_axis:first_axis + 3]


def model_adev(model, tau_s: float) -> float:
    """Allan deviation of a model at averaging time τ [s]: √(2 ν²(2τ)), ν² the model's Haar WV at the scale 2τ
    (:meth:`imunoise.noise.model.Model.wv`: white noise σ² gives ν²(τ) = σ²/τ, τ in samples; its Allan variance
    at m samples is σ²/m)."""
    return math.sqrt(2.0 * float(model.wv(np.array([2.0 * tau_s * F]))[0]))


def factors(report: Path) -> dict:
    """(unit, seed) → (kind, value, ci95) of the gyro white factor in ``report/in_use_replay.json``."""
    rows = json.loads((report / "in_use_replay.json").read_text())["coverage"]["white_factor"]["estimates"]
    return {(r["unit"], int(r["estimate"].split("/")[0])): (r["kind"], r["value"], r["ci95"]) for r in rows
            if r["axis"] == "gyro_x"}


def unit_rows(rec_path: str, label: str, seeds: list[int], seed0: int, fac: dict) -> list[dict]:
    from imunoise.noise.equivalent_noise import equivalent_noise
    from imunoise.sim.replay import load_recording

    rec = load_recording(str(Path(rec_path).resolve()))
    gyro_all = np.asarray(rec.errors[:, :3])
    everywhere = np.ones(rec.n, dtype=bool)
    n_log = [white_level(gyro_all[:, j], everywhere) for j in range(3)]
    log_long = [[allan_dev(gyro_all[:, j], everywhere, int(t * F))[0] for t in TAUS_LONG] for j in range(3)]
    out = []
    for s in seeds:
        v = s - seed0
        learn = gyro_all[2 * v * N_DRIVE:(2 * v + 1) * N_DRIVE]
        scored = gyro_all[(2 * v + 1) * N_DRIVE:(2 * v + 2) * N_DRIVE]
        stops_l = plan_stops(s + LEARN_OFFSET)[:-1]
        st_l, st_s = stop_mask(stops_l), stop_mask(plan_stops(s)[:-1])
        models = static_part(learn, stops_l)
        whole = np.ones(N_DRIVE, dtype=bool)
        axes = []
        for j in range(3):
            n_static = equivalent_noise(models[j], F, horizon_s=300.0).N
            axes.append({
                "N_log": n_log[j], "N_static": n_static, "N_stops": white_level(learn[:, j], st_l),
                "N_moving_learn": white_level(learn[:, j], ~st_l), "N_moving_scored": white_level(scored[:, j], ~st_s),
                "sd_stops_per_sqrt_f": float(learn[st_l, j].std() / math.sqrt(F)),
                "adev_long_learn": [allan_dev(learn[:, j], whole, int(t * F))[0] for t in TAUS_LONG],
                "adev_long_log": log_long[j],
                "adev_long_static_model": [model_adev(models[j], t) for t in TAUS_LONG],
                "static_model": str(models[j])})
        kind, val, ci = fac.get((label, s), (None, None, None))
        out.append({"unit": label, "seed": s, "stops_s": float(st_l.sum() / F), "factor_kind": kind,
                    "factor": val, "factor_ci95": ci, "axes": axes})
    return out


def _gm_ci(vals: list[float], units: list[str]) -> tuple[float, float, float]:
    """Geometric mean of ``vals`` and its 95 % t-interval over the unit means of log(vals) (clusters: units)."""
    from scipy import stats

    lv = np.log(np.asarray(vals, dtype=float))
    per = [float(np.mean(lv[[u == k for u in units]])) for k in sorted(set(units))]
    m, k = float(np.mean(per)), len(per)
    h = float(stats.t.ppf(0.975, k - 1) * np.std(per, ddof=1) / math.sqrt(k)) if k > 1 else math.nan
    return math.exp(m), math.exp(m - h), math.exp(m + h)


def summary(rows: list[dict]) -> dict:
    """Pooled ratios (geometric means over vehicles and gyro axes, 95 % CI over units) and the correlation of the
    estimated factor with each per-vehicle ratio (group mean over the three axes of the log ratio)."""
    from scipy import stats

    def per_axis(f):
        vals, units = [], []
        for r in rows:
            for a in r["axes"]:
                vals.append(f(a))
                units.append(r["unit"])
        return _gm_ci(vals, units)

    ratios = {
        "N_static / N_log": lambda a: a["N_static"] / a["N_log"],
        "N_static / N_stops": lambda a: a["N_static"] / a["N_stops"],
        "N_moving_learn / N_stops": lambda a: a["N_moving_learn"] / a["N_stops"],
        "N_moving_scored / N_static": lambda a: a["N_moving_scored"] / a["N_static"],
        "N_moving_learn / N_static": lambda a: a["N_moving_learn"] / a["N_static"],
        "(sigma/sqrt f at stops) / N_log": lambda a: a["sd_stops_per_sqrt_f"] / a["N_log"],
    }
    for i, t in enumerate(TAUS_LONG):
        ratios[f"adev({t:g} s) learning stretch / static model"] = (
            lambda a, i=i: a["adev_long_learn"][i] / a["adev_long_static_model"][i])
        ratios[f"adev({t:g} s) whole log / static model"] = (
            lambda a, i=i: a["adev_long_log"][i] / a["adev_long_static_model"][i])
    out: dict = {"pooled": {k: per_axis(f) for k, f in ratios.items()}, "correlation_with_log_factor": {}}
    given = [r for r in rows if r["factor"] is not None]
    lf = np.log([r["factor"] for r in given])
    for k, f in ratios.items():
        x = np.array([np.mean([math.log(f(a)) for a in r["axes"]]) for r in given])
        rho, p = stats.spearmanr(x, lf)
        out["correlation_with_log_factor"][k] = {"spearman": float(rho), "p": float(p), "vehicles": len(given)}
    out["factor"] = _gm_ci([r["factor"] for r in given], [r["unit"] for r in given])
    return out


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("report", help="folder of a finished scripts/in_use_replay.py run (its in_use_replay.json)")
    p.add_argument("recordings", nargs="+", help="the run's recordings, in its order")
    p.add_argument("--seed0", type=int, default=7300000)
    p.add_argument("--unit-step", type=int, default=10)
    p.add_argument("--seeds", type=int, default=8)
    p.add_argument("--out", default=None, help="JSON of every number (default: print only)")
    a = p.parse_args(argv)
    fac = factors(Path(a.report))
    rows: list[dict] = []
    for k, rec in enumerate(a.recordings):
        label = Path(rec).stem.split("_")[-1]
        s0 = a.seed0 + a.unit_step * k
        rows += unit_rows(rec, label, list(range(s0, s0 + a.seeds)), s0, fac)
    print("unit seed factor [95 % CI] | per gyro axis x,y,z: N_static/N_log, N_stops/N_log, N_moving_learn/N_log, "
          "N_moving_scored/N_log, adev(30 s) stretch/model")
    for r in rows:
        f = "not identified" if r["factor"] is None else (
            f"{r['factor']:.3f} [{r['factor_ci95'][0]:.3f}, {r['factor_ci95'][1]:.3f}]")
        ax = " | ".join(f"{x['N_static'] / x['N_log']:.3f} {x['N_stops'] / x['N_log']:.3f} "
                        f"{x['N_moving_learn'] / x['N_log']:.3f} {x['N_moving_scored'] / x['N_log']:.3f} "
                        f"{x['adev_long_learn'][1] / x['adev_long_static_model'][1]:.2f}" for x in r["axes"])
        print(f"{r['unit']} {r['seed']} {f} | {ax}")
    if a.out:  # the rows first: the summary is recomputed from them
        Path(a.out).write_text(json.dumps({"rows": rows}, indent=1))
    s = summary(rows)
    print(json.dumps(s, indent=1))
    if a.out:
        Path(a.out).write_text(json.dumps({"rows": rows, "summary": s}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
