"""Dense-window evidence on the simulator (issue 25 acceptance 3, scaled down): the same drives inline and in
two worker processes, CPU and wall time, and the per-window values of both compared to the bit.

The acceptance figure itself is the 30-drive run of ``imunoise experiment online --sim --seeds 30 --seed0 0
--outages dense:60:20 --gnss-regime noise:1.5,3,1 --noise-seeds 1 --latency 1 --methods plain,gmwm``; this
benchmark runs the same protocol on fewer, shorter drives so that ``make bench`` stays short.
"""

from __future__ import annotations

import resource
import time

from imunoise.experiments import dense
from imunoise.experiments.gnss_regimes import parse_gnss
from imunoise.online import OnlineConfig
from imunoise.sim.motion import DEFAULT_MOTION, motion_arg

SEEDS = [0, 1]
DURATION_S = 300.0
METHODS = ("plain", "gmwm")


def _cpu() -> float:
    """CPU time [s] of this process and its reaped children (the pool's workers)."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def _run(workers: int) -> tuple[dict, float, float]:
    kw = dict(spec=dense.DenseSpec(60.0, 20.0), regimes=[parse_gnss("noise:1.5,3,1")], noise_seeds=[1],
              methods=METHODS, base=OnlineConfig(latency=1.0), duration_s=DURATION_S, n_stops=3,
              motion_noise=motion_arg(DEFAULT_MOTION))
    c0, w0 = _cpu(), time.perf_counter()
    res = dense.run_sim(SEEDS, workers=workers, **kw)
    return res, _cpu() - c0, time.perf_counter() - w0


def main() -> str:
    _run(1)  # compile / warm caches (numba kernels, the fit cache of this process)
    inline, cpu1, wall1 = _run(1)
    par, cpu2, wall2 = _run(2)
    same = inline["per_window"] == par["per_window"]
    sim_s = len(SEEDS) * DURATION_S * len(METHODS)
    lines = [
        "## Dense-window evidence (`imunoise experiment online --sim --outages dense:60:20`)",
        "",
        f"{len(SEEDS)} simulated drives of {DURATION_S:.0f} s, methods {', '.join(METHODS)}, GNSS noise:1.5,3,1 "
        f"(one noise seed), latency 1 s, {inline['n_windows']} windows; CPU = this process and its workers.",
        "",
        "| run | wall [s] | CPU [s] | drive-seconds per wall second (methods × drives) |",
        "|---|---|---|---|",
        f"| inline (`--workers 1`) | {wall1:.1f} | {cpu1:.1f} | {sim_s / wall1:.0f} |",
        f"| two processes (`--workers 2`) | {wall2:.1f} | {cpu2:.1f} | {sim_s / wall2:.0f} |",
        "",
        f"Per-window values identical to the bit between the two runs: **{'yes' if same else 'NO'}**. "
        f"Wall ratio inline / two processes: {wall1 / wall2:.2f}× (the machine's other load counts).",
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    print(main())
