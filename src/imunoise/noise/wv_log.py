"""The wavelet variance of every axis of a long IMU log in one streamed pass (issue "Calibrate from the logs
people already have", §3): :func:`stream_wavelet_variance` feeds the SI blocks of
:func:`imunoise.io.imu_stream.open_imu_blocks` into one :class:`imunoise.noise.wv_stream.WVStream`, so memory is set by
the coarsest level, not by the log's length; the result equals the whole-file path's WV
(docs/guide/theory.rst, 'Wavelet variance') to 1e-9.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imunoise.errors import DataError
from imunoise.io.imu_input import decimate, describe_series, unknown_unit_messages
from imunoise.io.imu_stream import ImuBlocks, StreamOrderError
from imunoise.io.tabular import TimeReport, TimingWarning, UnitWarning, clean_time
from imunoise.noise.wv import WaveletVariance
from imunoise.noise.wv_stream import WVStream

__all__ = ["StreamedImu", "stream_wavelet_variance"]


@dataclass(eq=False)
class StreamedImu:
    """What :func:`stream_wavelet_variance` found: one WV per axis and the series' description, with the
    attributes of :class:`imunoise.io.imu_input.ImuSeries` a fit records (no ``data``)."""

    source: str
    wv: dict[str, WaveletVariance]
    unit: dict[str, str]
    source_unit: dict[str, str]
    freq: float
    n_samples: int
    report: TimeReport | None = None
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def axes(self) -> list[str]:
        return list(self.wv)

    def describe(self) -> str:
        return describe_series(self.source, self.n_samples, self.freq, self.axes, self.report, self.meta,
                               " (streamed)")



# ----------------------------------------------------------------------------------------------
# one pass: wavelet variance per axis
# ----------------------------------------------------------------------------------------------
def stream_wavelet_variance(
    blocks: ImuBlocks,
    *,
    freq: float | None = None,
    decimate_by: int = 1,
    decimate_method: str = "average",
    max_scale_s: float | None = None,
    levels: int | None = None,
    progress: Callable[[int], Any] | None = None,
) -> StreamedImu:
    """One pass over ``blocks``: the WV of every axis (module docstring), the timing report and warnings.

    ``freq`` is the rate the user gave (checked against the stamps, as :func:`clean_time` does);
    ``decimate_by`` block-averages as :func:`~imunoise.io.imu_input.decimate`; ``max_scale_s`` or ``levels``
    caps the levels (and the memory: 2^J − 1 sums per axis, :class:`~imunoise.noise.wv_stream.WVStream`);
    ``progress(advance)`` is called after each block with its bytes or messages.

    Raises
    ------
    StreamOrderError
        When the time stamps go back (the whole-file path sorts them; a stream cannot).
    DataError
        For what :func:`read_imu_source` refuses, and too short or constant data.
    """
    k_dec = int(decimate_by) if float(decimate_by).is_integer() and decimate_by >= 1 else decimate_by
    decimate(np.zeros(2 * k_dec if isinstance(k_dec, int) else 2), k_dec, decimate_method)  # same refusals
    k_dec = int(k_dec)
    n_axes = len(blocks.axes)
    inc = np.array(blocks.increment, dtype=bool)
    f = float(freq) if freq else blocks.freq
    t_rel_parts: list[np.ndarray] = []
    t_abs_parts: list[np.ndarray] = []
    last_t: float | None = None
    carry = np.zeros((0, n_axes))
    stream: WVStream | None = None
    offset = None
    s1 = np.zeros(n_axes)
    s2 = np.zeros(n_axes)
    n_kept = 0
    for vals, t_rel, t_abs, adv in blocks.blocks:
        if t_rel is not None and t_rel.size:
            prev = t_rel[0] if last_t is None else last_t
            d = np.diff(t_rel, prepend=prev)
            back = np.flatnonzero(d < 0)
            if back.size:
                src = blocks.time_source or blocks.meta.get("_time_source", {}).get("text", blocks.source)
                raise StreamOrderError(
                    f"{src}: the time stamps go back at sample {len(np.concatenate(t_rel_parts)) if t_rel_parts else 0}"
                    f"+{int(back[0])}; a stream keeps the file order — run without --stream (the whole-file path "
                    "sorts them)"
                )
            keep = d != 0
            if last_t is None:
                keep[0] = True
            last_t = float(t_rel[-1])
            t_rel_parts.append(t_rel)
            if k_dec > 1:
                t_abs_parts.append(t_abs)
            if not keep.all():
                vals = vals[keep]
        if vals.shape[0]:
            if offset is None:
                offset = vals.mean(axis=0)
            dv = vals - offset
            s1 += dv.sum(axis=0)
            s2 += (dv * dv).sum(axis=0)
            n_kept += vals.shape[0]
            if f is not None and inc.any():
                vals = vals.copy()
                vals[:, inc] *= f
            if k_dec > 1:
                vals = np.concatenate([carry, vals])
                m = vals.shape[0] // k_dec
                carry = vals[m * k_dec :]
                vals = vals[: m * k_dec].reshape(m, k_dec, n_axes).mean(axis=1)
            if vals.shape[0]:
                if stream is None:
                    stream = _new_stream(f, t_rel, k_dec, max_scale_s, levels)
                stream.add(vals)
        if progress is not None:
            progress(adv)
    if stream is None:
        raise DataError(f"{blocks.source}: no samples")
    report = None
    t_source = blocks.time_source or blocks.meta.get("_time_source", {}).get("text")
    if t_rel_parts:
        t_all = np.concatenate(t_rel_parts)
        _, report = clean_time(t_all, source=t_source, freq=freq)
        f_in = float(freq) if freq else report.rate_hz
    else:
        f_in = float(f)
    gain = f_in if (blocks.freq is None and not freq and inc.any()) else None  # increments fed unscaled
    meta = {k: v for k, v in blocks.meta.items() if not k.startswith("_")}
    source = blocks.source
    if report is not None and not 1.0 <= report.rate_hz <= 1e5:
        warnings.warn(
            f"{source}: the time stamps give {report.rate_hz:.6g} Hz, unusual for an IMU; check --time-unit",
            TimingWarning,
            stacklevel=2,
        )
    unknown = [a for a in blocks.axes if blocks.unit[a] == "u"]
    if unknown and n_kept:
        mean = offset + s1 / n_kept
        var = np.maximum(s2 / n_kept - (s1 / n_kept) ** 2, 0.0)
        i = {a: j for j, a in enumerate(blocks.axes)}
        found = unknown_unit_messages(
            source, unknown, {a: float(mean[i[a]]) for a in unknown}, {a: float(math.sqrt(var[i[a]])) for a in unknown}
        )
        for msg in found:
            warnings.warn(msg, UnitWarning, stacklevel=2)
        if found:
            meta.setdefault("warnings", []).extend(found)
    f_out = f_in
    if k_dec > 1:
        if n_kept // k_dec < 2:
            raise DataError(f"only {n_kept} samples: cannot decimate by {k_dec}")
        if t_abs_parts:
            t_dec = decimate(np.concatenate(t_abs_parts)[_kept_mask(t_all)], k_dec)
            _, report = clean_time(t_dec - t_dec[0], source=f"{source} (block-averaged by {k_dec})")
        meta["decimated"] = {"k": k_dec, "method": decimate_method, "freq_in": f_in}
        f_out = f_in / k_dec
    res = stream.result()
    res = res if isinstance(res, list) else [res]
    wv = {a: _rescaled(w, f_out, gain if inc[j] else None) for j, (a, w) in enumerate(zip(blocks.axes, res))}
    return StreamedImu(
        source=source,
        wv=wv,
        unit=dict(blocks.unit),
        source_unit=dict(blocks.source_unit),
        freq=f_out,
        n_samples=stream.n_samples,
        report=report,
        meta=meta,
    )


def _kept_mask(t: np.ndarray) -> np.ndarray:
    keep = np.ones(t.size, dtype=bool)
    keep[1:] = np.diff(t) != 0
    return keep


def _new_stream(
    f: float | None, t_rel: np.ndarray | None, k: int, max_scale_s: float | None, levels: int | None
) -> WVStream:
    """A WVStream whose level cap follows ``max_scale_s`` at the (decimated) rate: the given rate, else one
    estimated from the first block's stamps (the exact rate is only known at the end; it sets the WV's
    ``freq`` then, :func:`_rescaled`)."""
    if max_scale_s is None:
        # the rate may be known only at the end: the WV is given it then (_rescaled), 1 Hz holds the place
        return WVStream(levels=levels, freq=f / k if f else 1.0)
    if f is None:
        d = np.diff(t_rel) if t_rel is not None and t_rel.size > 1 else np.zeros(0)
        d = d[d > 0]
        if not d.size:
            raise DataError("cannot tell the sample rate from the first block of stamps; give --freq")
        f = 1.0 / float(np.median(d))
    cap = WVStream(max_scale_s=max_scale_s, freq=f / k).levels
    return WVStream(levels=cap, freq=f / k)


def _rescaled(wv: WaveletVariance, freq: float, gain: float | None) -> WaveletVariance:
    """``wv`` at rate ``freq``; with ``gain`` the WV of gain·x (ν² and CIs × gain², Cov × gain⁴)."""
    if gain is None:
        return dataclasses.replace(wv, freq=freq)
    g2 = gain * gain
    return dataclasses.replace(
        wv,
        freq=freq,
        variance=wv.variance * g2,
        ci_low=wv.ci_low * g2,
        ci_high=wv.ci_high * g2,
        cov=wv.cov * (g2 * g2),
    )
