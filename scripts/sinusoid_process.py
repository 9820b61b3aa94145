"""The sinusoid process SIN (docs/evidence/sinusoid_process.md): its Haar WV against the empirical WV of simulated
lines, GMWM fits of WN + SIN on simulation, and on the five shared ADIS16405 gyro_z logs the exported white-noise
density N with SIN in the model against N after line suppression, both against the data's Allan deviation at 1 s.

Usage::

    python scripts/sinusoid_process.py --seed0 4500 --count 10               # development
    python scripts/sinusoid_process.py --seed0 6530000 --count 20 --data ../shared/data/imudata_adis16405
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

F = 100.0
FREQS_HZ = (31.0, 12.87, 5.0, 0.5)
T_975 = {4: 2.776, 9: 2.262, 19: 2.093}  # Student t quantiles for the paired 95 % intervals (df = clusters − 1)


def wv_check(seed0: int, count: int) -> None:
    """Per frequency, over ``count`` seeds: a pure line (2^18 samples) against the estimator's exact bound for a
    line, ν/(M_j |sin β|); white noise + line (2^16 samples) against the estimator's 95 % χ² intervals."""
    from imunoise.noise.model import Model
    from imunoise.noise.processes import SIN, WN
    from imunoise.noise.wv import wavelet_variance

    print("== WV of SIN against simulation ==")
    for f_hz in FREQS_HZ:
        beta = 2 * math.pi * f_hz / F
        line = SIN(alpha2=2.5e-3, beta=beta)
        worst_rel, worst_ratio = 0.0, 0.0
        inside = []
        for seed in range(seed0, seed0 + count):
            wv = wavelet_variance(Model([line]).simulate(2**18, seed=seed), freq=F)
            theo = line.wv(wv.scales)
            rel = np.abs(wv.variance / theo - 1.0)
            bound = 1.0 / (wv.n_coefficients * abs(math.sin(beta)))
            worst_rel = max(worst_rel, float(np.max(rel)))
            worst_ratio = max(worst_ratio, float(np.max(rel / bound)))
            model = WN(sigma2=1e-4) + SIN(alpha2=4e-4, beta=beta)
            wv2 = wavelet_variance(model.simulate(2**16, seed=seed), freq=F)
            t2 = model.wv(wv2.scales)
            inside.append((t2 >= wv2.ci_low) & (t2 <= wv2.ci_high))
        cover = float(np.mean(inside))
        print(f"  {f_hz:6.2f} Hz (beta {beta:.4f} rad/sample): pure line worst |nu_hat/nu - 1| {worst_rel:.2e}, "
              f"worst ratio to the bound 1/(M_j|sin beta|) {worst_ratio:.3f}; WN + SIN: theory inside the 95 % "
              f"chi2 CI at {100 * cover:.1f} % of {len(inside)} x {inside[0].size} scales")


def fit_check(seed0: int, count: int) -> None:
    """GMWM fits of WN + SIN (2^17 samples): relative errors of amplitude, frequency and N over the seeds."""
    from imunoise.noise.estimator import gmwm
    from imunoise.noise.processes import SIN, WN

    print("== GMWM fit of WN + SIN on simulation (2^17 samples, N 1e-3 u/sqrt(Hz), amplitude 0.02 u) ==")
    for f_hz in FREQS_HZ:
        errs = []
        t0 = time.perf_counter()
        for seed in range(seed0, seed0 + count):
            truth = WN(sigma2=1e-4) + SIN(alpha2=4e-4, beta=2 * math.pi * f_hz / F)
            c = gmwm("WN+SIN", truth.simulate(2**17, seed=seed), freq=F).model.continuous(F)
            errs.append((c["SIN.amplitude"] / 0.02 - 1, c["SIN.frequency"] / f_hz - 1,
                         c["WN.noise_density"] / 1e-3 - 1))
        e = np.abs(np.array(errs)) * 100
        print(f"  {f_hz:6.2f} Hz: worst |error| amplitude {e[:, 0].max():.2f} %, frequency {e[:, 1].max():.3f} %, "
              f"N {e[:, 2].max():.2f} % over {count} seeds ({(time.perf_counter() - t0) / count:.2f} s per fit)")


def adev(y: np.ndarray, freq: float, tau: float) -> float:
    """Overlapping Allan deviation of the rate series ``y`` at averaging time ``tau`` [s]."""
    m = int(round(tau * freq))
    theta = np.concatenate([[0.0], np.cumsum(y)]) / freq
    d = theta[2 * m:] - 2 * theta[m:-m] + theta[:-2 * m]
    return math.sqrt(float(np.mean(d**2)) / (2 * tau**2))


def adis_gyro_z(data: Path) -> None:
    """Per unit: model selection (WVIC, the default complete model) on the line-suppressed data (``fit --auto``'s
    path) against model selection on the data as read with SIN added to the complete model; N of each against
    the raw data's AD(1 s); the paired difference of |N/AD(1 s) − 1| over the five units with its 95 % CI."""
    from imunoise.export import axis_noise
    from imunoise.lines import remove_lines
    from imunoise.noise.selection import select_model

    print("== ADIS16405 gyro_z: N with SIN in the model vs N after line suppression, against AD(1 s) ==")
    supp, sinm = [], []
    for k in range(1, 6):
        z = np.load(data / f"adis16405_unit{k}.npz")
        cols = [str(c) for c in z["columns"]]
        y = z["data"][:, cols.index("gyro_z")] * math.pi / 180
        ad1 = adev(y, F, 1.0)
        t0 = time.perf_counter()
        yc, found = remove_lines(y, F, unit="rad/s")
        fit_s = select_model(yc, freq=F, unit="rad/s").best
        t1 = time.perf_counter()
        fit_l = select_model(y, freq=F, unit="rad/s", complete="4*AR1+DR+WN+QN+RW+SIN").best
        t2 = time.perf_counter()
        n_s, n_l = axis_noise(fit_s, "gyro_z").N, axis_noise(fit_l, "gyro_z").N
        e_s, e_l = n_s / ad1 - 1, n_l / ad1 - 1
        supp.append(abs(e_s))
        sinm.append(abs(e_l))
        line = ""
        if any(c.kind == "SIN" for c in fit_l.model.components):
            c = fit_l.model.continuous(F)
            line = f" (SIN {c['SIN.frequency']:.2f} Hz, amplitude {c['SIN.amplitude']:.3g} rad/s)"
        lines = ", ".join(f"{ln.freq_hz:.3g} Hz {100 * ln.share:.2g} %" for ln in found) or "none"
        print(f"  unit {k}: AD(1 s) {ad1:.4e} rad/s | suppressed ({lines}): {fit_s.model} N {n_s:.4e} "
              f"({100 * e_s:+.1f} %, {t1 - t0:.0f} s) | with SIN: {fit_l.model}{line} N {n_l:.4e} "
              f"({100 * e_l:+.1f} %, {t2 - t1:.0f} s)")
    d = 100 * (np.array(sinm) - np.array(supp))
    half = T_975[len(d) - 1] * float(np.std(d, ddof=1)) / math.sqrt(len(d))
    print(f"  paired |N/AD(1 s) - 1| (SIN) - (suppression), 5 units: mean {d.mean():+.2f} percentage points, "
          f"95 % CI [{d.mean() - half:+.2f}, {d.mean() + half:+.2f}]; mean |error| suppression "
          f"{100 * np.mean(supp):.2f} %, SIN {100 * np.mean(sinm):.2f} %")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seed0", type=int, required=True, help="first seed of the simulated parts")
    p.add_argument("--count", type=int, default=10, help="number of seeds")
    p.add_argument("--data", type=Path, help="folder of adis16405_unitK.npz (skipped when absent)")
    args = p.parse_args()
    wv_check(args.seed0, args.count)
    fit_check(args.seed0, args.count)
    if args.data is not None and (args.data / "adis16405_unit1.npz").exists():
        adis_gyro_z(args.data)
    else:
        print("== ADIS16405 gyro_z: skipped (no --data folder with adis16405_unitK.npz) ==")


if __name__ == "__main__":
    main()
