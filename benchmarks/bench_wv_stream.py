"""Long logs in bounded memory: ``WVStream`` fed 1e6-sample chunks vs the batch ``wavelet_variance``.

Each estimator runs in its own child process (so its peak RSS, ``VmHWM``, is its own): the series
(0.5 + white noise + a small random walk, 1e8 samples by default, about 28 h at 1 kHz) is generated
chunk by chunk from per-chunk seeds, so the streaming child never holds more than one chunk of it while
the batch child assembles the whole array first. Times cover only the estimator (``add`` calls plus
``result`` for the stream, ``wavelet_variance`` for the batch), after a small warm-up call that loads the
numba cache. Usage: ``python benchmarks/bench_wv_stream.py [--n 1e8] [--chunk 1e6]``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
N = 100_000_000
CHUNK = 1_000_000
CAPPED_LEVELS = 20  # tau_J = 2**20 samples, about 17 min at 1 kHz
SEED = 20240601


def _chunks(n: int, chunk: int):
    """The benchmark series, one chunk at a time (same numbers whatever consumes them)."""
    level = 0.0
    for k, start in enumerate(range(0, n, chunk)):
        rng = np.random.default_rng([SEED, k])
        size = min(chunk, n - start)
        walk = level + 1e-3 * np.cumsum(rng.standard_normal(size))
        level = float(walk[-1])
        yield 0.5 + rng.standard_normal(size) + walk


def _rss_mb() -> float:
    """Peak RSS of this process [MiB]: VmHWM, which starts afresh at exec (``ru_maxrss`` would carry the
    peak of the parent that forked this child on Linux)."""
    with open("/proc/self/status") as f:
        return int(next(line.split()[1] for line in f if line.startswith("VmHWM:"))) / 1024.0


def _child(mode: str, n: int, chunk: int) -> dict:
    from imunoise.noise.wv import wavelet_variance
    from imunoise.noise.wv_stream import WVStream

    warm = np.random.default_rng(0).standard_normal(1 << 16)
    wavelet_variance(warm, freq=1.0)
    WVStream(freq=1.0).add(warm)
    rss0 = _rss_mb()
    if mode == "batch":
        x = np.empty(n)
        for k, c in enumerate(_chunks(n, chunk)):
            x[k * chunk : k * chunk + c.shape[0]] = c
        t0 = time.perf_counter()
        wv = wavelet_variance(x, freq=1.0)
        seconds = time.perf_counter() - t0
    else:
        stream = WVStream(levels=CAPPED_LEVELS if mode == "capped" else None, freq=1.0)
        seconds = 0.0
        for c in _chunks(n, chunk):
            t0 = time.perf_counter()
            stream.add(c)
            seconds += time.perf_counter() - t0
        t0 = time.perf_counter()
        wv = stream.result()
        seconds += time.perf_counter() - t0
    return {
        "seconds": seconds,
        "rss0_mb": rss0,
        "peak_mb": _rss_mb(),
        "levels": wv.levels.tolist(),
        "variance": wv.variance.tolist(),
        "ci_high": wv.ci_high.tolist(),
        "cov": np.diag(wv.cov).tolist(),
    }


def _run_child(mode: str, n: int, chunk: int) -> dict:
    env = dict(os.environ, PYTHONPATH=str(REPO / "src") + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = subprocess.run(
        [sys.executable, __file__, "--child", mode, "--n", str(n), "--chunk", str(chunk)],
        env=env, capture_output=True, text=True, check=True, timeout=3600,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def _max_rel(a: dict, b: dict, top: int) -> float:
    keys = ("variance", "ci_high", "cov")
    return max(float(np.max(np.abs(np.asarray(a[k][:top]) / np.asarray(b[k][:top]) - 1.0))) for k in keys)


def main(n: int = N, chunk: int = CHUNK) -> str:
    batch = _run_child("batch", n, chunk)
    stream = _run_child("stream", n, chunk)
    capped = _run_child("capped", n, chunk)
    assert stream["levels"] == batch["levels"], (stream["levels"], batch["levels"])
    rel = _max_rel(stream, batch, len(batch["levels"]))
    rel_capped = _max_rel(capped, batch, CAPPED_LEVELS)
    data_mb = n * 8 / 2**20
    top = batch["levels"][-1]

    def row(name: str, r: dict) -> str:
        return (
            f"| {name} | {r['seconds']:.2f} | {batch['seconds'] / r['seconds']:.2f} | {r['peak_mb']:,.0f} | "
            f"{r['peak_mb'] - r['rss0_mb']:,.0f} |"
        )

    return "\n".join(
        [
            "## Long logs in bounded memory (`imunoise.noise.wv_stream`)",
            "",
            f"{n:.3g} samples (0.5 + white noise + random walk) streamed in chunks of {chunk:.3g} into "
            f"`WVStream`, vs the batch `wavelet_variance` of the whole array ({data_mb:,.0f} MiB). One child "
            "process per row, so the peak RSS is that estimator's own; the increase is over the RSS after "
            "imports and a warm-up call (for the batch it includes the series itself, which the stream "
            "never holds).",
            "",
            "| estimator | wall time (s) | speed vs batch (wall) | peak RSS (MiB) | increase (MiB) |",
            "|---|---|---|---|---|",
            row(f"batch `wavelet_variance`, {len(batch['levels'])} levels (tau up to 2^{top})", batch),
            row(f"`WVStream(freq=…)`, all {len(stream['levels'])} levels", stream),
            row(f"`WVStream(levels={CAPPED_LEVELS}, freq=…)`", capped),
            "",
            f"Max relative difference to the batch (variance, CI, covariance diagonal): {rel:.1e} (all "
            f"levels), {rel_capped:.1e} (levels 1-{CAPPED_LEVELS}). Rings of the capped stream: "
            f"2^{CAPPED_LEVELS} - 1 window sums ({(2**CAPPED_LEVELS - 1) * 8 / 2**20:.0f} MiB) whatever N is.",
        ]
    )


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=float, default=N, help="samples in the series (default 1e8)")
    parser.add_argument("--chunk", type=float, default=CHUNK, help="samples per chunk (default 1e6)")
    parser.add_argument("--child", choices=["batch", "stream", "capped"], help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print(json.dumps(_child(args.child, int(args.n), int(args.chunk))))
    else:
        print(main(int(args.n), int(args.chunk)))
