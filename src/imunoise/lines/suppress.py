"""Suppression of narrowband lines: the record's spectrum reshaped to its broadband floor inside each line's band.

The whole record's FFT X(f) is multiplied, in each line's band (widened by one Welch bin each side), by
g(f) = min(1, √(floor(f)/P(f))) with P the Welch PSD and floor its running median
(:func:`imunoise.lines.detect.psd_floor`), both interpolated to the FFT's bins. The phases stay the
data's, the power in the band becomes the floor's, and every bin outside the bands is untouched, so the
broadband noise (white, random walk, Gauss-Markov) keeps its spectrum and its wavelet variance. Chosen over a
sinusoid process in the model because the lines measured are not sinusoids: the ADIS16405 gyro_z line is a
5 Hz-wide hump (a sinusoid's WV fits one frequency), and a vibration's frequency drifts from stop to stop.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from imunoise.lines.detect import Line, psd_floor, welch_psd

__all__ = ["PASSES", "remove_lines", "suppress_lines"]


def suppress_lines(x: np.ndarray, freq: float, lines: Sequence[Line]) -> np.ndarray:
    """``x`` with each line's band brought down to the broadband floor (module docstring); ``x`` itself
    when there is no line. The mean is kept."""
    x = np.asarray(x, dtype=float)
    if not lines:
        return x
    f, p = welch_psd(x, freq)
    fl = psd_floor(f, p)
    df = float(f[1] - f[0])
    mean = float(x.mean())
    X = np.fft.rfft(x - mean)
    fx = np.fft.rfftfreq(x.size, 1.0 / freq)
    gain = np.ones(fx.size)
    g_welch = np.sqrt(np.minimum(1.0, np.divide(fl, p, out=np.ones_like(p), where=p > 0)))
    for ln in lines:
        sel = (fx >= ln.band_hz[0] - df) & (fx <= ln.band_hz[1] + df)
        gain[sel] = np.interp(fx[sel], f, g_welch)
    return np.fft.irfft(X * gain, n=x.size) + mean


PASSES = 3
"""Detect-and-suppress passes of :func:`remove_lines`: a wide hump's skirt stands above the floor once its
peak is gone (ADIS16405 gyro_z: a 0.4 % tail at 24 Hz after the first pass)."""


def remove_lines(x: np.ndarray, freq: float, *, unit: str = "") -> tuple[np.ndarray, list[Line]]:
    """``x`` with every line found removed (up to :data:`PASSES` passes of
    :func:`imunoise.lines.detect.find_lines` then :func:`suppress_lines`), and the lines, their shares taken
    of the variance of ``x`` as given. ``x`` itself (and no line) for broadband data."""
    from dataclasses import replace

    from imunoise.lines.detect import find_lines

    x = np.asarray(x, dtype=float)
    total = float(np.var(x))
    y, found = x, []
    for _ in range(PASSES):
        new = find_lines(y, freq, unit=unit)
        if not new:
            break
        scale = float(np.var(y)) / total if total > 0 else 1.0
        found += [replace(ln, share=ln.share * scale) for ln in new]
        y = suppress_lines(y, freq, new)
    return y, sorted(found, key=lambda ln: -ln.share)
