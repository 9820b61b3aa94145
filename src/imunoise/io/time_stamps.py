"""Time stamps of a log: sort, drop and count duplicates, report gaps and the sampling jitter, infer or check
the sample rate (docs/guide/theory.rst, 'Interfaces'). The same report is used by the table and ROS bag readers."""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from imunoise.errors import DataError, TimingWarning

__all__ = ["GAP_FACTOR", "RATE_TOLERANCE", "TimeReport", "TimingWarning", "clean_time"]

GAP_FACTOR = 5.0
"""A step longer than this many median steps is a gap (same rule as the KF-GINS reader)."""

RATE_TOLERANCE = 0.01
"""Relative difference allowed between a given --freq and the rate of the time stamps."""


@dataclass(frozen=True)
class TimeReport:
    """What :func:`clean_time` found and did. Times in s; ``jitter_s`` is the robust standard deviation
    (1.4826·MAD) of the steps outside gaps; ``rate_hz`` = 1 / mean step outside gaps."""

    source: str
    n_in: int
    n_kept: int
    n_unsorted: int
    n_duplicates: int
    n_gaps: int
    largest_gap_s: float
    median_dt_s: float
    jitter_s: float
    rate_hz: float

    @property
    def jitter_rel(self) -> float:
        return self.jitter_s / self.median_dt_s if self.median_dt_s > 0 else float("nan")

    def summary(self) -> str:
        parts = [
            f"{self.n_kept} samples from {self.source}",
            f"rate {self.rate_hz:.6g} Hz (median step {1e3 * self.median_dt_s:.6g} ms, "
            f"jitter {1e6 * self.jitter_s:.3g} µs = {100 * self.jitter_rel:.3g} % of a step)",
        ]
        if self.n_unsorted:
            parts.append(f"{self.n_unsorted} out-of-order stamps sorted")
        if self.n_duplicates:
            parts.append(f"{self.n_duplicates} duplicated stamps dropped")
        if self.n_gaps:
            parts.append(f"{self.n_gaps} gaps > {GAP_FACTOR:g} steps (largest {self.largest_gap_s:.6g} s)")
        return "; ".join(parts)

    def to_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def clean_time(
    t: np.ndarray,
    *,
    source: str = "time stamps",
    freq: float | None = None,
    gap_factor: float = GAP_FACTOR,
    tolerance: float = RATE_TOLERANCE,
) -> tuple[np.ndarray, TimeReport]:
    """Indices that put ``t`` in time order without duplicates, and a :class:`TimeReport`.

    Out-of-order stamps are sorted (stable), duplicates dropped (the first kept), both counted and warned
    about with :class:`TimingWarning`; gaps longer than ``gap_factor`` median steps are counted and warned.
    The rate is 1/(mean step outside gaps). With ``freq`` given, a rate that differs by more than ``tolerance``
    (relative) raises :class:`DataError`: the noise densities scale with √f, so a wrong rate is a wrong
    model.
    """
    t = np.asarray(t, dtype=float)
    if t.ndim != 1:
        raise DataError(f"{source}: time must be 1-D, got shape {t.shape}")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise DataError(f"{source}: {bad.size} non-finite time stamp(s), first at sample {bad[0]}; remove them")
    if t.size < 2:
        raise DataError(f"{source}: need at least 2 time stamps, got {t.size}")
    n_unsorted = int(np.count_nonzero(np.diff(t) < 0))
    order = np.argsort(t, kind="stable") if n_unsorted else np.arange(t.size)
    ts = t[order]
    d = np.diff(ts)
    dup = np.flatnonzero(d == 0) + 1
    keep = np.ones(t.size, dtype=bool)
    keep[dup] = False
    idx = order[keep]
    ts = ts[keep]
    if ts.size < 2:
        raise DataError(f"{source}: all {t.size} time stamps are equal")
    d = np.diff(ts)
    med = float(np.median(d))
    gaps = d[d > gap_factor * med]
    regular = d[d <= gap_factor * med]
    jitter = float(1.4826 * np.median(np.abs(regular - np.median(regular)))) if regular.size else 0.0
    # the mean of the regular steps (not the median): stamps quantised by float64 or a clock tick still
    # average to the true step. 9 significant digits: integer-ns stamps converted to float carry ~1e-13
    # relative noise that would otherwise show up as "200.0000000001819 Hz" in every file downstream
    rate = float(f"{1.0 / float(np.mean(regular)) if regular.size else 1.0 / med:.9g}")
    report = TimeReport(
        source=source,
        n_in=int(t.size),
        n_kept=int(ts.size),
        n_unsorted=n_unsorted,
        n_duplicates=int(dup.size),
        n_gaps=int(gaps.size),
        largest_gap_s=float(gaps.max()) if gaps.size else 0.0,
        median_dt_s=med,
        jitter_s=jitter,
        rate_hz=rate,
    )
    if n_unsorted:
        warnings.warn(f"{source}: {n_unsorted} out-of-order time stamps; sorted", TimingWarning, stacklevel=2)
    if dup.size:
        warnings.warn(
            f"{source}: dropped {dup.size} samples with a duplicated time stamp (the first of each kept)",
            TimingWarning,
            stacklevel=2,
        )
    if gaps.size:
        warnings.warn(
            f"{source}: {gaps.size} gaps longer than {gap_factor:g} sample steps (largest {gaps.max():.6g} s); "
            "the wavelet variance treats the samples as contiguous, so model static segments separately "
            "if the gaps are long",
            TimingWarning,
            stacklevel=2,
        )
    if freq is not None:
        if not freq > 0:
            raise DataError(f"--freq must be a positive rate in Hz, got {freq}")
        if abs(rate - freq) > tolerance * freq:
            raise DataError(
                f"{source}: the time stamps give {rate:.6g} Hz (median step {med:.6g} s) but --freq is {freq:g} Hz; "
                "fix --freq (or --time-unit) — the noise densities scale with the rate"
            )
    return idx, report
