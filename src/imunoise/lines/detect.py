"""Detection of narrowband lines: Welch PSD peaks above a running-median broadband floor.

The floor at frequency f is the median of the Welch PSD read at log-spaced frequencies over [f/2, 2f] (a
window one octave each side, so a hump several hertz wide, like the ADIS16405 gyro_z's 17–22 Hz, holds well
under half the window and does not lift its own floor). A line is a run of bins whose PSD is above
:data:`RATIO` × floor, merged across gaps of up to :data:`GAP_BINS` bins, holding at least :data:`MIN_SHARE`
of the axis's variance in excess power.

Why these numbers: with ``nperseg`` = :data:`SEGMENT_S` × f the Welch estimate of a 10⁶-sample record averages
≈ 490 segments (relative standard deviation ≈ 4.5 % per bin), and of a 20 s stop ≈ 4 (Hann, 50 % overlap): a
ratio of 1.5 is 11 standard deviations on the long record. On the broadband family (WN, QN, RW, AR1 up to
a one-pole knee) the running median of a spectrum falling at most as f⁻² over linearly spaced bins sits at
most ≈ 1.2× below the PSD at the window's centre, so no broadband spectrum reaches 1.5; the low-frequency end
(below :data:`MIN_FREQ_BINS` bins) where the window is truncated is not searched. Measured: ADIS16405 gyro_x/y
reach at most 1.33, the lines 1.6–27.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["GAP_BINS", "MIN_FREQ_BINS", "MIN_SHARE", "RATIO", "SEGMENT_S", "STOP_SEGMENT_S", "Line", "find_lines",
           "lines_in_psd", "lines_text", "pooled_lines",
           "psd_floor", "welch_psd"]

RATIO = 1.5
"""PSD over its running-median floor above which a bin belongs to a line (module docstring)."""
MIN_SHARE = 0.002
"""Share of the axis's variance (0.2 %) that a line must carry in excess power to be reported and removed."""
GAP_BINS = 3
"""Bins below :data:`RATIO` that a line may span (one hump split by estimation noise stays one line)."""
MIN_FREQ_BINS = 10
"""Lowest bin searched: below it the floor's window is truncated by the spectrum's start."""
SEGMENT_S = 40.96
"""Welch segment length [s] (4096 samples at 100 Hz: 0.024 Hz resolution)."""


@dataclass(frozen=True)
class Line:
    """One narrowband line of an axis.

    Attributes
    ----------
    freq_hz : float
        Frequency of the line's peak [Hz].
    band_hz : tuple of float
        Band removed [Hz] (the run of bins above the floor).
    share : float
        Excess power in the band over the axis's variance (0–1).
    rms : float
        Root of the excess power [unit of the data].
    peak_ratio : float
        PSD over the floor at the peak.
    unit : str
        Unit of ``rms``.
    """

    freq_hz: float
    band_hz: tuple[float, float]
    share: float
    rms: float
    peak_ratio: float
    unit: str = ""

    def text(self) -> str:
        return (f"line at {self.freq_hz:.3g} Hz ({self.band_hz[0]:.3g}–{self.band_hz[1]:.3g} Hz): "
                f"{100 * self.share:.3g} % of the variance, RMS {self.rms:.3g} {self.unit}".rstrip()
                + f", {self.peak_ratio:.3g}× the floor")

    def to_dict(self) -> dict[str, Any]:
        return {"freq_hz": self.freq_hz, "band_hz": list(self.band_hz), "share": self.share, "rms": self.rms,
                "peak_ratio": self.peak_ratio, "unit": self.unit}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Line:
        return cls(float(d["freq_hz"]), (float(d["band_hz"][0]), float(d["band_hz"][1])), float(d["share"]),
                   float(d["rms"]), float(d["peak_ratio"]), str(d.get("unit", "")))


def welch_psd(x: np.ndarray, freq: float, segment_s: float = SEGMENT_S) -> tuple[np.ndarray, np.ndarray]:
    """One-sided Welch PSD (Hann, 50 % overlap, mean removed) of ``x`` sampled at ``freq`` [Hz]:
    (frequencies [Hz], PSD [u²/Hz]). The segment is shortened to the record when the record is shorter."""
    from scipy.signal import welch

    n = int(min(max(16, round(segment_s * freq)), x.size))
    return welch(np.asarray(x, dtype=float), fs=freq, nperseg=n, detrend="constant")


def psd_floor(f: np.ndarray, p: np.ndarray, octaves: float = 1.0, points: int = 33) -> np.ndarray:
    """Running median of ``p`` over [f·2^−octaves, f·2^octaves], read at ``points`` log-spaced frequencies
    (interpolated): the broadband floor (module docstring). Log spacing makes the median of any monotone
    spectrum its value at the window's centre, so a steep-then-flat corner (a Gauss-Markov knee, a random
    walk meeting white noise) is not taken for a line."""
    g = f[:, None] * np.exp2(np.linspace(-octaves, octaves, points))[None, :]
    g = np.clip(g, f[1] if f.size > 1 else f[0], f[-1])
    return np.median(np.interp(g, f, p), axis=1)


def _runs(mask: np.ndarray, gap: int) -> list[tuple[int, int]]:
    idx = np.flatnonzero(mask)
    if idx.size == 0:
        return []
    cuts = np.flatnonzero(np.diff(idx) > gap + 1)
    starts = np.r_[idx[0], idx[cuts + 1]]
    ends = np.r_[idx[cuts], idx[-1]]
    return [(int(a), int(b)) for a, b in zip(starts, ends, strict=True)]


MIN_AVERAGES = 8
"""Welch segments a PSD must average before its peaks are read as lines: with fewer, a periodogram bin of white
noise is an exponential variable and its largest of thousands stands tens of times above the floor (a 20 s
white-noise record, one segment, showed six "lines" at 10-58x)."""

FALSE_LINE_RATE = 0.01
"""Chance that a broadband PSD shows a bin above the detection ratio anywhere (Bonferroni over its bins)."""


def welch_averages(n_samples: int, segment: int) -> int:
    """Number of half-overlapping Welch segments of ``segment`` samples in a record of ``n_samples``."""
    if n_samples < segment or segment < 2:
        return 0
    return 1 + (n_samples - segment) // (segment // 2)


def chance_ratio(n_averages: int, n_bins: int, rate: float = FALSE_LINE_RATE) -> float:
    """The ratio PSD / running-median floor that broadband noise exceeds in any of ``n_bins`` bins with
    probability ``rate``, for a PSD that averages ``n_averages`` segments (each bin χ² with 2K degrees of
    freedom; the floor is a median, hence the median in the denominator)."""
    from scipy.stats import chi2

    dof = 2.0 * max(n_averages, 1)
    return float(chi2.ppf(1.0 - rate / max(n_bins, 1), dof) / chi2.ppf(0.5, dof))


def lines_in_psd(f: np.ndarray, p: np.ndarray, total_var: float, *, unit: str = "", ratio: float = RATIO,
                 min_share: float = MIN_SHARE, n_averages: int = MIN_AVERAGES) -> list[Line]:
    """The lines of a PSD (module docstring); ``total_var`` is the variance the shares are taken of and
    ``n_averages`` the Welch segments the PSD averages (fewer than :data:`MIN_AVERAGES`: no line is read; the
    detection ratio is at least the one broadband noise reaches by chance, :func:`chance_ratio`)."""
    if f.size < 2 * MIN_FREQ_BINS or not total_var > 0 or n_averages < MIN_AVERAGES:
        return []
    df = float(f[1] - f[0])
    fl = psd_floor(f, p)
    r = np.divide(p, fl, out=np.ones_like(p), where=fl > 0)
    above = r > max(ratio, chance_ratio(n_averages, f.size))
    above[:MIN_FREQ_BINS] = False
    excess = np.clip(p - fl, 0.0, None)
    out = []
    for a, b in _runs(above, GAP_BINS):
        power = float(excess[a:b + 1].sum() * df)
        share = power / total_var
        if share < min_share:
            continue
        k = a + int(np.argmax(r[a:b + 1]))
        out.append(Line(float(f[k]), (float(f[a]), float(f[b])), share, float(np.sqrt(power)), float(r[k]), unit))
    return out


def find_lines(x: np.ndarray, freq: float, *, unit: str = "", ratio: float = RATIO,
               min_share: float = MIN_SHARE) -> list[Line]:
    """Narrowband lines of one axis's static record ``x`` at ``freq`` [Hz] (module docstring).

    Returns
    -------
    list of Line
        Strongest share first; empty for broadband data.
    """
    x = np.asarray(x, dtype=float)
    f, p = welch_psd(x, freq)
    k = welch_averages(x.size, int(min(max(16, round(SEGMENT_S * freq)), x.size)))
    found = lines_in_psd(f, p, float(np.var(x)), unit=unit, ratio=ratio, min_share=min_share, n_averages=k)
    return sorted(found, key=lambda ln: -ln.share)


def lines_text(axis: str, lines: list[Line]) -> list[str]:
    """One line of text per narrowband line of ``axis`` (for the summary, the report and the exports)."""
    return [f"{axis}: narrowband {ln.text()}; removed before fitting" for ln in lines]


STOP_SEGMENT_S = 2.56
"""Welch segment length [s] for the stops of a drive (256 samples at 100 Hz, 0.39 Hz resolution): a stop of
20 s gives ≈ 14 half-overlapping segments, and every stop of a log adds its own."""


def pooled_lines(segments: list[np.ndarray], freq: float, *, unit: str = "",
                 segment_s: float = STOP_SEGMENT_S) -> list[Line]:
    """The lines of an axis's stops: the Welch PSD of each stop (bias removed) averaged with weights its
    sample count, against the pooled variance (the vibration of an engine at idle, :func:`lines_in_psd`).
    Stops shorter than one segment are left out; no line when none is long enough."""
    n = int(round(segment_s * freq))
    used = [np.asarray(x, dtype=float) - np.mean(x) for x in segments if len(x) >= n]
    if not used:
        return []
    w = np.array([x.size for x in used], dtype=float)
    psds = [welch_psd(x, freq, segment_s) for x in used]
    f = psds[0][0]
    p = np.average(np.stack([q for _, q in psds]), axis=0, weights=w)
    total = float(np.average([np.var(x) for x in used], weights=w))
    k = sum(welch_averages(x.size, n) for x in used)
    return sorted(lines_in_psd(f, p, total, unit=unit, n_averages=k), key=lambda ln: -ln.share)
