"""The per-axis pooled fit of the stops and :func:`calibrate` itself
(docs/guide/theory.rst, 'Static detection' and 'Online engine'; :mod:`imunoise.calibrate`)."""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from imunoise.calibrate.logs import ACCEL_UNIT, GYRO_UNIT, ImuLog, read_log
from imunoise.calibrate.result import CalibrationResult, axis_calibration
from imunoise.calibrate.stops import LEARN_S, MAX_STOPS_PER_MIN, LogStops, detect_stops, implausible_stops
from imunoise.detect import DetectorConfig
from imunoise.errors import DataError
from imunoise.imu import AXES

MIN_STATIC_S = 20.0
"""Pooled static time [s] needed before a model is identified (the online engine's ``min_static_s``): with
less the white noise rests on too few wavelet levels to be told from the rest."""

RATE_TOLERANCE = 0.01
"""Relative difference of sample rates above which two logs are not pooled (their densities differ)."""

def pooled_fit(
    segments: Sequence[np.ndarray],
    *,
    freq: float,
    unit: str = "u",
    complete: str | None = None,
    criterion: str = "wvic",
    weights: str = "efficient",
    seed: int = 0,
) -> Any:
    """The model of one axis from its pooled stops: WV pooled over the segments (no coefficient spans two),
    structure selected (:func:`imunoise.noise.selection.select_model`), its parameters estimated as
    :func:`imunoise.noise.estimator.gmwm` estimates a given structure, and a richer candidate where the selected one
    leaves the WV band (:func:`imunoise.noise.fitting.quality.within_band`).

    Why the re-estimate: the selection fits every candidate on one Ω built from ν̂, which favours the levels
    whose estimate fell low; on drive_0708's accel_z the top level (τ = 20.5 s, 52 coefficients of one stop,
    ν̂ 1/3.7 of the WN line's) pulled that one-step WN estimate to N = 1.53e-3 while the WVIC had ranked WN
    at its likelihood estimate, N = 1.09e-2; iterated, N = 1.04e-2 (σ/√f of the stops 1.08e-2).

    Parameters
    ----------
    segments : sequence of numpy.ndarray
        The stops' samples of the axis, bias removed [u].
    freq : float
        Sample rate [Hz].
    unit, complete, criterion, weights, seed
        As for :func:`imunoise.noise.selection.select_model`.

    Returns
    -------
    GMWMFit
        With ``extra["data_allan"]`` (dense Allan curve of the stops), ``data_span``, ``selection`` and
        ``fit_check`` (the band check and what the retry gave).
    """
    from imunoise.lines.detect import pooled_lines
    from imunoise.noise.allan import allan_variance, curve_to_dict
    from imunoise.noise.fitting.quality import within_band
    from imunoise.noise.selection import select_model
    from imunoise.noise.wv import WVAccumulator

    acc = WVAccumulator(freq=freq)
    for x in segments:
        acc.add(x)
    ranking = select_model(acc.result(), freq=freq, complete=complete, criterion=criterion, weights=weights,
                           unit=unit, seed=seed)
    settled = within_band(ranking)
    fit = settled.fit
    fit.extra["data_allan"] = curve_to_dict(allan_variance(list(segments), freq=freq, grid="dense"))
    fit.extra["data_span"] = {"n_samples": int(sum(x.size for x in segments)), "n_segments": len(segments)}
    fit.extra["selection"] = {"criterion": criterion, "n_candidates": len(ranking.fits), "selected": settled.selected}
    fit.extra["fit_check"] = settled.to_dict()
    # reported, not removed: a stop's Welch resolution (0.39 Hz) cannot cut a line without the broadband
    # noise around it; the export notes and the report name it
    found = pooled_lines(list(segments), freq, unit=unit)
    fit.extra["lines"] = {"removed": False, "found": [ln.to_dict() for ln in found]}
    return fit


def _same_samples(a: LogStops, b: LogStops) -> bool:
    """Two logs that hold the same samples (the same file under two names, or a copy): same rate, span and
    stops, and the same samples in their first stop."""
    if a.log.rate_hz != b.log.rate_hz or a.stops != b.stops or not a.stops:
        return False
    sa = a.log.span_s or (float(a.log.t[0]), float(a.log.t[-1]))
    sb = b.log.span_s or (float(b.log.t[0]), float(b.log.t[-1]))
    return sa == sb and all(np.array_equal(x, y) for x, y in zip(a.stop_samples(0)[:1], b.stop_samples(0)[:1],
                                                                    strict=True))


def _refuse_repeats(found: Sequence[LogStops]) -> None:
    """A log given twice would be pooled twice (its stops counted double, the CIs too narrow): refused."""
    seen: dict[str, str] = {}
    for ls in found:
        if not Path(ls.log.name).exists():
            continue  # a log built in memory: its name says nothing, its samples do (below)
        key = str(Path(ls.log.name).resolve())
        if key in seen:
            raise DataError(f"{ls.log.name} is given twice (also as {seen[key]}): a log is pooled once; drop the "
                            "repeat")
        seen[key] = ls.log.name
    for i, a in enumerate(found):
        for b in found[i + 1 :]:
            if _same_samples(a, b):
                raise DataError(f"{b.log.name} holds the same samples as {a.log.name} (same span and stops): a log "
                                "is pooled once; drop the copy")


def _topic_of(found: Sequence[LogStops]) -> dict[str, Any]:
    """The ROS topic the logs were read from, for the model's source and every export that names one
    (``{}`` for logs that are not bags). Bags read on different topics: the first log's, all of them beside it
    (``topics``) and a warning, since an export names one topic."""
    topics = list(dict.fromkeys(t for ls in found if (t := ls.log.meta.get("topic"))))
    if not topics:
        return {}
    if len(topics) > 1:
        from imunoise.io.kfgins import DataWarning

        warnings.warn(f"the logs were read on {len(topics)} topics ({', '.join(topics)}); the exports name the "
                      f"first, {topics[0]}: edit rostopic where the tool reads another", DataWarning, stacklevel=3)
        return {"topic": topics[0], "topics": topics}
    return {"topic": topics[0]}


def _no_stop_error(ls: LogStops, need_s: float) -> DataError:
    det = ls.detection
    found = f"{ls.dropped[0]}; " if ls.dropped and "no stop" in ls.dropped[0] else ""
    return DataError(
        f"{ls.log.name}: no usable stop: {found}{det.static_time_s:.1f} s called static by the detector "
        f"({len(det.segments)} segments ≥ {det.config.min_duration_s:g} s, λ0 = {ls.lambda0:.3g} m/s²), "
        f"{ls.static_s:.1f} s left after the rate gate and the speed check, in {ls.log.duration_s:.0f} s of log; "
        f"calibrate needs ≥ {need_s:g} s of pooled stops for the white noise N, and stops several times "
        "longer than an averaging time to state K there; pool more logs or record stops"
    )


def calibrate(
    logs: Sequence[ImuLog | str | Path],
    *,
    detector: DetectorConfig | None = None,
    lambda0: float | None = None,
    learn_from_s: float | None = None,
    learn_s: float = LEARN_S,
    criterion: str = "wvic",
    complete: str | None = None,
    weights: str = "efficient",
    min_static_s: float = MIN_STATIC_S,
    seed: int = 0,
    progress: Callable[[Any, str], Any] | None = None,
    max_stops_per_min: float = MAX_STOPS_PER_MIN,
) -> CalibrationResult:
    """Noise model of an IMU from the stops of its moving logs (module docstring).

    Parameters
    ----------
    logs : sequence of ImuLog, LogStops, str or Path
        Logs of the same IMU (paths are read with :func:`read_log`'s defaults; a :class:`LogStops`, e.g. from
        :func:`stream_stops`, is taken as detected); pooled.
    detector : DetectorConfig, optional
        Detector settings (its λ_0 is learned per log unless ``lambda0`` is given).
    lambda0 : float, optional
        Fixed λ_0 [m/s²] for every log.
    learn_from_s : float, optional
        Learn λ_0 from the first this many seconds of each log (a known stop there).
    learn_s : float
        Length of the quietest stretch λ_0 is learned from [s] (default).
    criterion : {"wvic", "gof"}
        Selection criterion (:func:`imunoise.noise.selection.select_model`).
    complete : str, optional
        Largest structure searched (default the paper's 4*AR1+DR+WN+QN+RW).
    weights : str
        Ω of the GMWM.
    min_static_s : float
        Pooled static time needed [s].
    seed : int
        Seed of the random starts of the selection.
    progress : callable, optional
        ``progress(iterable, desc)`` wrapping the per-log and per-axis loops (e.g. a tqdm factory).
    max_stops_per_min : float
        A log without a speed source with more stops per minute (and at least 10) is refused as cruising taken
        for stops (:func:`imunoise.calibrate.stops.implausible_stops`); ``inf`` turns the check off.

    Returns
    -------
    CalibrationResult

    Raises
    ------
    DataError
        A log without a usable stop, implausibly many stops without a speed source, too little pooled static
        time, or logs at different rates.
    """
    from imunoise.noise.imu_model import ImuModel

    if not logs:
        raise DataError("calibrate needs at least one log")
    wrap = progress or (lambda it, desc: it)
    found: list[LogStops] = []
    for item in wrap(list(logs), "logs"):
        if isinstance(item, LogStops):  # detected already (a streamed log, :func:`stream_stops`)
            found.append(item)
            continue
        log = item if isinstance(item, ImuLog) else read_log(item)
        found.append(detect_stops(log, detector, lambda0=lambda0, learn_from_s=learn_from_s, learn_s=learn_s))
    for ls in found:
        if not ls.stops:
            raise _no_stop_error(ls, min_static_s)
        if (why := implausible_stops(ls, max_stops_per_min)) is not None:
            raise DataError(why)
    f = found[0].log.rate_hz
    for ls in found[1:]:
        if abs(ls.log.rate_hz - f) > RATE_TOLERANCE * f:
            raise DataError(f"{ls.log.name} is at {ls.log.rate_hz:.4g} Hz, {found[0].log.name} at {f:.4g} Hz: "
                            "logs of different rates cannot be pooled (the densities are per rate); resample one")
    total = sum(ls.static_s for ls in found)
    if total < min_static_s:
        parts = ", ".join(f"{ls.log.name}: {ls.static_s:.1f} s in {len(ls.stops)} stops" for ls in found)
        raise DataError(f"only {total:.1f} s of stops pooled ({parts}); calibrate needs ≥ {min_static_s:g} s for the "
                        "white noise N, and stops several times longer than an averaging time to state K there; "
                        "pool more logs")
    _refuse_repeats(found)
    fits: dict[str, Any] = {}
    for k, axis in enumerate(wrap(list(AXES), "axes")):
        # bias removed per stop (docs/guide/theory.rst, 'Static detection')
        segs = [x - x.mean() for ls in found for x in ls.stop_samples(k)]
        unit = GYRO_UNIT if k < 3 else ACCEL_UNIT
        fits[axis] = pooled_fit(segs, freq=f, unit=unit, complete=complete, criterion=criterion, weights=weights,
                                seed=seed)
    axes = {ax: axis_calibration(ax, fit) for ax, fit in fits.items()}
    source = {
        "calibrate": [ls.log.name for ls in found],
        "freq_hz": f,
        "static_s": total,
        "n_stops": int(sum(len(ls.stops) for ls in found)),
        "horizon_s": float(max(a.horizon_s for a in axes.values())),
        **_topic_of(found),
    }
    if source.get("topic"):
        for fit in fits.values():  # a single fit exported later names the topic too
            fit.extra["topic"] = source["topic"]
    model = ImuModel.from_fits(fits, source=source)
    return CalibrationResult(found, fits, axes, model, f, criterion)
