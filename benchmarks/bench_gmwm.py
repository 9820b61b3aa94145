"""GMWM core: objective vs R simts on its own series, parameter recovery, fit speed (issue 2)."""

from __future__ import annotations

import json
import shutil
import statistics
import subprocess
import time
from pathlib import Path

import numpy as np

from imunoise import AR1, RW, WN
from imunoise.noise.estimator import gmwm

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"


_R_FIT = """
suppressMessages(library(simts))
x <- RcppCNPy::npyLoad("{npy}")
f <- function() gmwm(2*AR1() + WN() + RW(), x, model.type = "imu", compute.v = "fast", G = 1e6, seed = 1337)
invisible(f())
t <- replicate(5, {s <- system.time(f()); s[["user.self"]] + s[["sys.self"]]})
cat(median(t), "\\n")
"""


def _simts_rows(ref_dir: Path, ours_cpu: float) -> list[str]:
    """R simts' fit time in this run when R and simts are installed, else the reason it is skipped and the
    figure recorded in reference.json, labelled as such."""
    ref = json.loads((ref_dir / "reference.json").read_text())
    rscript = shutil.which("Rscript")
    reason = "R is not installed on this machine (no `Rscript` on PATH)"
    if rscript is not None:
        script = _R_FIT.replace("{npy}", str(ref_dir / "sim_2ar1_wn_rw_N100000.npy"))
        out = subprocess.run([rscript, "-e", script], capture_output=True, text=True, timeout=600)
        if out.returncode == 0 and out.stdout.strip():
            cpu = float(out.stdout.split()[-1])
            return [f"| R simts `gmwm`, this run | {1e3 * cpu:.0f} ms | – |",
                    "", f"R simts ÷ imunoise (CPU, this run): **{cpu / ours_cpu:.0f}×**."]
        reason = f"R simts could not run ({(out.stderr or 'no output').strip().splitlines()[-1][:120]})"
    return [
        "",
        f"R simts skipped: {reason}. For reference only, not measured in this run: "
        "`../shared/data/simts_reference/reference.json` records a median of 5 simts fits of "
        f"{1e3 * ref['simts_cpu_seconds_median_of_5']:.0f} ms CPU "
        f"({1e3 * ref['simts_wall_seconds_median_of_5']:.0f} ms wall) on the same machine kind.",
    ]


def _simts_section() -> list[str]:
    ref_dir = SHARED / "simts_reference"
    if not (ref_dir / "reference.json").exists():
        return ["_simts reference not available (../shared/data/simts_reference missing)._"]
    ref = json.loads((ref_dir / "reference.json").read_text())
    x = np.load(ref_dir / "sim_2ar1_wn_rw_N100000.npy")
    gmwm("2*AR1+WN+RW", x, freq=1.0)  # JIT warm-up
    times, cpus, fit = [], [], None
    for _ in range(5):
        t0, c0 = time.perf_counter(), time.process_time()
        fit = gmwm("2*AR1+WN+RW", x, freq=1.0)
        times.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
    fast = gmwm("2*AR1+WN+RW", x, weights="fast", freq=1.0)
    t_med, c_med = statistics.median(times), statistics.median(cpus)
    lines = [
        "### simts reference series (2*AR1+WN+RW, N = 100 000)",
        "",
        "| objective (same WV) | our Ω (efficient, iterated) | simts' Ω (1/CI width²) |",
        "|---|---|---|",
        f"| at our estimate | **{fit.objective:.6g}** | **{fast.objective:.10g}** |",
        f"| at simts' estimate | {fit.objective_at(ref['simts_estimate']):.6g} | "
        f"{fast.objective_at(ref['simts_estimate']):.10g} |",
        f"| at the truth | {fit.objective_at(ref['truth']):.6g} | {fast.objective_at(ref['truth']):.10g} |",
        "",
        f"simts itself reports {ref['simts_objective_own_omega']} at its estimate and "
        f"{ref['simts_objective_minimum_found_by_polishing_own_omega']} as the minimum found by polishing.",
        "",
        "| parameter | truth | imunoise (efficient) | imunoise (simts' Ω) | simts |",
        "|---|---|---|---|---|",
    ]
    for name, true in ref["truth"].items():
        lines.append(
            f"| {name} | {true:.4g} | {fit.params[name]:.4g} | {fast.params[name]:.4g} | "
            f"{ref['simts_estimate'][name]:.4g} |"
        )
    lines += [
        "",
        "| one fit, WV included (median of 5) | CPU | wall |",
        "|---|---|---|",
        f"| imunoise `gmwm` (efficient Ω, 2 reweighting steps), this run | {1e3 * c_med:.1f} ms | "
        f"{1e3 * t_med:.1f} ms |",
        *_simts_rows(ref_dir, c_med),
    ]
    return lines


def _recovery_section(seeds: int = 50) -> list[str]:
    truth = AR1(phi=0.995, sigma2=1e-6) + WN(sigma2=1e-4) + RW(gamma2=1e-9)
    rel, times = [], []
    for seed in range(seeds):
        x = truth.simulate(2**17, seed=seed)
        t0 = time.perf_counter()
        fit = gmwm(truth.unknown(), x, freq=1.0)
        times.append(time.perf_counter() - t0)
        rel.append([fit.params[k] / v - 1 for k, v in truth.params.items()])
    rel = np.array(rel)
    lines = [
        f"### Parameter recovery: AR1(0.995, 1e-6) + WN(1e-4) + RW(1e-9), N = 2^17, {seeds} seeds",
        "",
        "| parameter | truth | median relative error (signed) | median abs. relative error | IQR of rel. error |",
        "|---|---|---|---|---|",
    ]
    for i, (name, value) in enumerate(truth.params.items()):
        q1, q3 = np.percentile(rel[:, i], [25, 75])
        lines.append(
            f"| {name} | {value:g} | {100 * np.median(rel[:, i]):+.2f} % | "
            f"{100 * np.median(np.abs(rel[:, i])):.2f} % | [{100 * q1:+.1f} %, {100 * q3:+.1f} %] |"
        )
    lines += [
        "",
        f"Median fit wall time {1e3 * statistics.median(times):.1f} ms (WV included). RW dominates only the two "
        "coarsest levels at this N, whose own relative standard deviation is 80–140 %: the spread of γ̂² "
        "is an information limit, its median bias is not.",
    ]
    return lines


def main() -> str:
    lines = ["## GMWM core (`bench_gmwm.py`)", ""]
    lines += _simts_section()
    lines += [""]
    lines += _recovery_section()
    return "\n".join(lines)


if __name__ == "__main__":
    print(main())
