"""Model selection (issue 3): speed of all 79 candidates, refit, nesting, and structure recovery.

Acceptance 1 (recovery, 20 seeds per case and size), 2 (timing) and 4 (nesting on the simts series) of
issue 3. ``scripts/modelling_checks.py`` reuses these functions and adds the real-data, AV and EM parts.
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path

import numpy as np

from imunoise.noise.estimator import fit_problem, prepare
from imunoise.noise.model import Model
from imunoise.noise.selection import candidates, refit, select_model

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"
FREQ = 125.0  # the paper's rate; 40 000 samples = 318 s

CASES = {
    "a": Model.parse("AR1+WN").with_params({"AR1_1.phi": 0.999, "AR1_1.sigma2": 1e-8, "WN.sigma2": 1e-4}),
    "b": Model.parse("2*AR1+WN+RW").with_params(
        {
            "AR1_1.phi": 0.9999,
            "AR1_1.sigma2": 1e-10,
            "AR1_2.phi": 0.99,
            "AR1_2.sigma2": 1e-7,
            "WN.sigma2": 1e-5,
            "RW.gamma2": 1e-11,
        }
    ),
    "c": Model.parse("WN+QN+RW").with_params({"WN.sigma2": 1e-6, "QN.q2": 1e-7, "RW.gamma2": 1e-12}),
}


def _median_time(f, repeat: int = 5) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def timing_rows() -> list[str]:
    """Acceptance 2: all 79 candidates and refit, medians of 5, N = 40 000 and 10^6; cold baseline."""
    rows = [
        "| N | all 79 candidates (WV + Ω + fits), wall, median of 5 | per candidate (wall, median) | "
        "`refit` (warm start, WV included), wall, median of 5 | 79 independent cold fits (same WV/Ω, "
        "`fit_problem` defaults), wall | speed-up (wall) |",
        "|---|---|---|---|---|---|",
    ]
    truth = CASES["b"]
    for n in (40_000, 1_000_000):
        x = truth.simulate(n, seed=1)
        ranking = select_model(x, freq=FREQ)  # warm-up (JIT cache, buffers)
        t_sel = _median_time(lambda x=x: select_model(x, freq=FREQ))
        per = statistics.median(f.elapsed_s for f in ranking.fits)
        prev = ranking.by_structure("2*AR1+WN+RW")
        t_ref = _median_time(lambda x=x, prev=prev: refit(prev, x))
        problem = prepare(x, freq=FREQ)
        t0 = time.perf_counter()
        for cand in candidates():
            fit_problem(problem, cand.model, with_cov=False)
        t_cold = time.perf_counter() - t0
        rows.append(
            f"| {n:,} | **{1e3 * t_sel:.0f} ms** | {1e3 * per:.1f} ms | **{1e3 * t_ref:.1f} ms** | "
            f"{1e3 * t_cold:.0f} ms (fits only) | {t_cold / t_sel:.1f}× |"
        )
    rows += [
        "",
        "Targets: ≤ 1 s for the 79 candidates at N = 40 000, ≤ 50 ms for `refit`. One core: candidates are "
        "visited small to large and warm-started from their immediate sub-models, so they form a chain of "
        "dependencies; a process pool would pay ≈ 1 s of start-up and numba cache loading per worker for "
        "less than that of work. Reference points (not re-measured): the paper's structure "
        "identification took 84 s; R `gmwm::auto_imu` took 83 s on the simts series.",
    ]
    return rows


def nesting_rows() -> list[str]:
    """Acceptance 4: GOF(bigger) ≤ GOF(smaller) for every nested pair on the simts reference series."""
    path = SHARED / "simts_reference" / "sim_2ar1_wn_rw_N100000.npy"
    if not path.exists():
        return ["_simts reference series not available (../shared/data/simts_reference missing)._"]
    x = np.load(path)
    r = select_model(x, freq=1.0, criterion="gof")
    pairs = viol = 0
    worst = 0.0
    for big in r.fits:
        for small in r.fits:
            if big is not small and big.model.nests(small.model):
                pairs += 1
                if big.objective > small.objective:
                    viol += 1
                    worst = max(worst, big.objective - small.objective)
    true_rank = 1 + [str(f.model) for f in r.fits].index("2*AR1 + WN + RW")
    w = select_model(x, freq=1.0, criterion="wvic")
    w_rank = 1 + [str(f.model) for f in w.fits].index("2*AR1 + WN + RW")
    return [
        "| simts series (2*AR1+WN+RW, N = 100 000) | imunoise, this run "
        "| R `auto_imu` (issue text, not measured here) |",
        "|---|---|---|",
        f"| nested pairs checked | {pairs} | – |",
        f"| pairs with GOF(bigger) > GOF(smaller) | **{viol}** (worst excess {worst:.3g}) | "
        "violated: 2*AR1+WN+RW 0.498 vs +DR 0.137 … |",
        f"| GOF of 2*AR1+WN+RW / 2*AR1+WN+RW+DR | {r.by_structure('2*AR1+WN+RW').objective:.4g} / "
        f"{r.by_structure('2*AR1+WN+RW+DR').objective:.4g} | 0.498 / 0.137 (its own Ω) |",
        f"| rank of the true structure by GOF / by WVIC | {true_rank} / **{w_rank}** | 10th |",
        f"| best by WVIC | {w.best.model} | AR1 AR1 |",
        f"| wall time for all candidates | {1e3 * r.elapsed_s:.0f} ms | 83 s |",
    ]


def recovery(case: str, n: int, seeds: int = 20) -> dict[str, float]:
    """Acceptance 1: how often GOF and WVIC pick the true structure (and median time)."""
    truth = CASES[case]
    gof = wvic = 0
    times, picks = [], {}
    for seed in range(seeds):
        x = truth.simulate(n, seed=1000 + seed)
        r = select_model(x, freq=FREQ, criterion="wvic")
        times.append(r.elapsed_s)
        best_w = r.best
        best_g = min(r.fits, key=lambda f: (f.objective, f.n_params))
        gof += best_g.model.unknown() == truth.unknown()
        wvic += best_w.model.unknown() == truth.unknown()
        picks[str(best_w.model)] = picks.get(str(best_w.model), 0) + 1
    common = ", ".join(f"{k} ×{v}" for k, v in sorted(picks.items(), key=lambda kv: -kv[1])[:3])
    return {"gof": gof / seeds, "wvic": wvic / seeds, "time": statistics.median(times), "picks": common}


def recovery_rows(seeds: int = 20) -> list[str]:
    rows = [
        "| case | truth | N | GOF picks truth | WVIC picks truth | WVIC's picks (top 3) | median wall time |",
        "|---|---|---|---|---|---|---|",
    ]
    for case, truth in CASES.items():
        for n in (40_000, 2**20):
            res = recovery(case, n, seeds)
            rows.append(
                f"| ({case}) | {truth!r} | {n:,} | {100 * res['gof']:.0f} % | **{100 * res['wvic']:.0f} %** | "
                f"{res['picks']} | {1e3 * res['time']:.0f} ms |"
            )
    rows += [
        "",
        f"{seeds} seeds per row at {FREQ:g} Hz. GOF (Eq. 8) always prefers a bigger model when it nests the "
        "truth (its ties go to the smaller model), so it almost never picks the truth; the paper's ranking "
        'therefore needs the penalised WVIC (`criterion="wvic"`: −2 log-likelihood of the WV + p·ln n, see '
        "`imunoise.noise.selection`). Target: WVIC ≥ 80 % for (a) and (c) at both sizes; (b) reported as measured "
        "(its slow AR1 has T_c = 80 s and its RW crosses the AR1s only near the longest scales).",
    ]
    return rows


def main() -> str:
    lines = ["## Model selection (`bench_selection.py`, issue 3)", "", "### Timing (acceptance 2)", ""]
    lines += timing_rows()
    lines += ["", "### Nesting on the simts series (acceptance 4)", ""]
    lines += nesting_rows()
    lines += ["", "### Structure recovery (acceptance 1)", ""]
    lines += recovery_rows()
    return "\n".join(lines)


if __name__ == "__main__":
    print(main())
