"""Wavelet variance speed: imunoise.noise.wv vs allantools' overlapping ADEV on an octave tau grid
(docs/guide/theory.rst, 'Quality bars').

Both compute the same numbers (overlapping AVAR at m = 2**(j-1) equals 2*nu^2_j), on the same 1e6
samples, CPU time (``time.process_time``: one thread each), median of 5 after a warm-up call. The floor of
the WV is a few passes over the data, so it is also stated as a multiple of one ``np.cumsum`` pass over the
same array into a reused buffer, timed the same way. Also the streaming accumulator's cost per added segment.
"""

from __future__ import annotations

import time

import allantools
import numpy as np

from imunoise.noise.wv import WVAccumulator, wavelet_variance

N = 1_000_000
REPEATS = 5


def _median_time(fn, repeats: int = REPEATS) -> float:
    """Median CPU seconds of ``fn()`` after one warm-up call (numba cache load, allocations)."""
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        times.append(time.process_time() - t0)
    return float(np.median(times))


def main() -> str:
    rng = np.random.default_rng(20240601)
    x = rng.standard_normal(N) + 1e-3 * np.cumsum(rng.standard_normal(N))
    wv = wavelet_variance(x, freq=1.0)
    taus = (wv.scales / 2.0).astype(float)  # m = 2**(j-1), same levels as the WV
    # interleaved rounds, so that a burst of load on this shared machine hits every case alike
    buf = np.empty_like(x)  # the WV reuses its work buffers too: no page faults of a fresh 8 MB array
    t_wv, t_av, t_cs = [], [], []
    for _ in range(3):
        t_wv.append(_median_time(lambda: wavelet_variance(x, freq=1.0)))
        t_av.append(_median_time(lambda: allantools.oadev(x, rate=1.0, data_type="freq", taus=taus)))
        t_cs.append(_median_time(lambda: np.cumsum(x, out=buf)))
    t_wv, t_av, t_cs = (float(np.median(t)) for t in (t_wv, t_av, t_cs))
    _, adev, _, _ = allantools.oadev(x, rate=1.0, data_type="freq", taus=taus)
    agree = float(np.max(np.abs(2.0 * wv.variance / adev**2 - 1.0)))
    ratio = t_av / t_wv

    rows = []
    for seg_len in (1_000, 10_000, 100_000):
        segs = [rng.standard_normal(seg_len) for _ in range(20)]
        acc = WVAccumulator()
        acc.add(segs[0])  # warm-up
        t0 = time.process_time()
        for s in segs:
            acc.add(s)
        per_add = (time.process_time() - t0) / len(segs)
        t_res = _median_time(acc.result)
        rows.append(
            f"| {seg_len:,} | {int(np.log2(seg_len))} | {per_add * 1e3:.3f} | "
            f"{per_add / seg_len * 1e9:.1f} | {t_res * 1e3:.3f} |"
        )

    return "\n".join(
        [
            "## Wavelet variance (`imunoise.noise.wv`)",
            "",
            f"{N:,} samples (WN + small RW), {len(wv)} levels (tau = 2..2^{wv.levels[-1]}), classical "
            "estimate including eta3 CIs and the batch-means covariance; allantools `oadev` "
            f"(data_type='freq') at the same {len(taus)} octave averaging times. CPU time, median of 3 × "
            f"{REPEATS} interleaved, one thread.",
            "",
            "| method | CPU (ms) | multiple of one `np.cumsum` pass |",
            "|---|---:|---:|",
            f"| `np.cumsum(x, out=buf)` (one pass into a reused buffer) | {t_cs * 1e3:.2f} | 1.0 |",
            f"| imunoise `wavelet_variance` | {t_wv * 1e3:.2f} | **{t_wv / t_cs:.1f}** |",
            f"| allantools `oadev`, octave taus | {t_av * 1e3:.2f} | {t_av / t_cs:.1f} |",
            "",
            f"allantools ÷ imunoise (CPU): **{ratio:.1f}×**. "
            f"Max relative difference of 2*nu^2 vs oadev^2: {agree:.1e}.",
            "",
            "Streaming `WVAccumulator`: CPU cost of `add()` per segment (mean of 20 segments) and of "
            "`result()` (median of 5):",
            "",
            "| segment length (samples) | levels | add, CPU (ms) | add per sample, CPU (ns) | result, CPU (ms) |",
            "|---|---|---|---|---|",
            *rows,
        ]
    )


if __name__ == "__main__":
    print(main())
