"""What the horizon determines per axis: :class:`AxisCalibration`, :class:`CalibrationResult` and the K bound
(docs/guide/theory.rst, 'Static detection' and 'Online engine'; :mod:`imunoise.calibrate`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from imunoise.calibrate.stops import LogStops

K_CI_SPAN = 4.0
"""A fitted K is stated as a value only when its 95 % CI spans less than this factor (±2×); else as a bound."""

# --------------------------------------------------------------------------------------------------
# what the horizon determines
# --------------------------------------------------------------------------------------------------
def k_upper_bound(wv: Any) -> tuple[float, float]:
    """Upper bound on the random-walk density K [u/√s] that holds whatever else the sensor has.

    Any model's Allan variance is at least its random walk's, AV(T) ≥ K²T/3 (exact for the Haar form:
    AV(T) = 2ν²(2Tf) = γ²(4m² + 2)/(12m) ≥ γ²m/3 with m = Tf, K² = γ²f), so K ≤ √(3·AV(T)/T) at every
    averaging time; read on the upper limit of the WV's confidence band, the smallest over the levels.

    Parameters
    ----------
    wv : imunoise.noise.wv.WaveletVariance
        The pooled WV (with its chi-square band).

    Returns
    -------
    (float, float)
        The bound [u/√s] and the averaging time T [s] where it is reached.
    """
    T = np.asarray(wv.scales, dtype=float) / (2.0 * float(wv.freq))
    av_hi = 2.0 * np.asarray(wv.ci_high, dtype=float)
    k = np.sqrt(3.0 * av_hi / T)
    j = int(np.nanargmin(k))
    return float(k[j]), float(T[j])


@dataclass(frozen=True)
class AxisCalibration:
    """What the pooled stops say about one axis (module docstring).

    Attributes
    ----------
    axis, unit : str
        Axis name and SI unit of the rate.
    model : str
        The selected structure.
    N : float
        White-noise density as exported [u/√Hz].
    N_ci : tuple of float
        95 % CI of N when N is the model's WN term alone (NaN otherwise, or without a CI).
    K : float
        Random-walk density as exported [u/s/√Hz] (the export's matched, capped value; read ``K_status``).
    K_status : str
        ``"value"`` (the model's RW rises above the white noise inside the horizon and its 95 % CI spans
        less than a factor :data:`K_CI_SPAN`) or ``"bound"``.
    K_fit : float
        The model's own RW density [u/s/√Hz] (0 when it has none): the value when ``K_status`` is ``"value"``.
    K_ci : tuple of float
        95 % CI of the model's RW density (NaN when none).
    K_bound : float
        Upper bound on K that holds for any model (:func:`k_upper_bound`), at ``K_bound_at_s``.
    K_bound_at_s : float
        Averaging time of that bound [s].
    crossover_s : float
        T_x = √3·N/K: where the random walk would overtake the white noise [s].
    horizon_s : float
        Longest averaging time the stops support [s].
    tau_range_s : tuple of float
        Averaging times the exported pair is matched on [s].
    worst_ratio : float
        Worst factor between the pair's AV and the fitted **model's** there (not the data's: ``pair_data``).
    determined, undetermined : tuple of str
        Per process of the model: what the horizon determines, and what it does not (with why).
    band : imunoise.noise.fitting.quality.BandCheck
        The fitted model's WV against the pooled WV's 95 % band (``refused``: outside over a range of scales).
    pair_data : imunoise.noise.fitting.quality.PairCheck
        The exported pair's AV against the **data's** AV and its band over ``tau_range_s``.
    retry : str, optional
        What the selection's richer candidates gave when the selected structure left the band.
    """

    axis: str
    unit: str
    model: str
    N: float
    N_ci: tuple[float, float]
    K: float
    K_status: str
    K_fit: float
    K_ci: tuple[float, float]
    K_bound: float
    K_bound_at_s: float
    crossover_s: float
    horizon_s: float
    tau_range_s: tuple[float, float] | None
    worst_ratio: float
    determined: tuple[str, ...]
    undetermined: tuple[str, ...]
    band: Any = None
    pair_data: Any = None
    retry: str | None = None
    gate: Any = None

    @property
    def refused(self) -> bool:
        """The exported pair misses the data (:class:`imunoise.export.gate.PairGate`): an export is refused
        without ``--force`` (the WV band check is a diagnostic)."""
        return bool(self.gate is not None and self.gate.refused)

    @property
    def K_reported(self) -> float:
        """K as a value when determined, else the bound."""
        return self.K_fit if self.K_status == "value" else self.K_bound

    def to_dict(self) -> dict[str, Any]:
        return {
            "axis": self.axis, "unit": self.unit, "model": self.model,
            "N": self.N, "N_ci": list(self.N_ci), "K": self.K, "K_status": self.K_status, "K_fit": self.K_fit,
            "K_ci": list(self.K_ci),
            "K_bound": self.K_bound, "K_bound_at_s": self.K_bound_at_s, "crossover_s": self.crossover_s,
            "horizon_s": self.horizon_s, "tau_range_s": list(self.tau_range_s) if self.tau_range_s else None,
            "worst_av_ratio": self.worst_ratio, "worst_av_ratio_against": "the fitted model",
            "determined": list(self.determined), "undetermined": list(self.undetermined),
            "band": self.band.to_dict() if self.band is not None else None,
            "pair_vs_data": self.pair_data.to_dict() if self.pair_data is not None else None,
            "retry": self.retry, "export_refused": self.refused,
            "export_gate": self.gate.to_dict() if self.gate is not None else None,
        }


def axis_calibration(axis: str, fit: Any) -> AxisCalibration:
    from imunoise.export import axis_noise
    from imunoise.export.gate import pair_gate
    from imunoise.noise.equivalent_noise import default_horizon_s
    from imunoise.noise.fitting.quality import band_check, pair_check

    h = float(default_horizon_s(fit))
    a = axis_noise(fit, axis)
    ci = fit.confidence_intervals()
    cont = fit.continuous()
    nan2 = (math.nan, math.nan)
    N_ci = ci.get("WN.noise_density", nan2)
    if not math.isclose(cont.get("WN.noise_density", math.nan), a.N, rel_tol=1e-6):
        N_ci = nan2  # N holds more than the WN term (QN, fast AR1): the term's CI is not N's
    K_ci = ci.get("RW.random_walk", nan2)
    kb, kb_at = k_upper_bound(fit.wv)
    has_rw = any(c.reading == "random_walk" for c in fit.model.components)
    det, und = [], []
    for name, c in zip(fit.model.component_names(), fit.model.components):
        own = {k: v for k, v in cont.items() if k.startswith(name + ".")}
        if c.reading == "white":
            det += [f"{k} = {v:.4g}" for k, v in own.items()]
        elif c.reading == "gauss_markov":
            v = own[f"{name}.tau_c"]
            if v <= h:
                det.append(f"{name}: T_c = {v:.4g} s ≤ horizon {h:.3g} s, σ_GM = {own[name + '.sigma_gm']:.4g}")
            else:
                und.append(f"{name}: T_c = {v:.4g} s beyond the horizon {h:.3g} s (a slow Gauss–Markov term reads "
                           f"as a random walk there): not a value; inside K ≤ {kb:.3g}")
        elif c.reading == "ramp":
            und += [f"{k}: a ramp over {h:.3g} s is a reading of the rising WV, not a value; inside K ≤ {kb:.3g}"
                    for k in own]
    k_fit = a.K_rw
    tx = math.sqrt(3.0) * a.N / k_fit if k_fit > 0 else math.inf
    narrow = math.isfinite(K_ci[0]) and K_ci[0] > 0 and K_ci[1] / K_ci[0] <= K_CI_SPAN
    status = "value" if (has_rw and tx <= h and narrow) else "bound"
    if status == "value":
        det.append(f"K = {k_fit:.4g} (random walk above the white noise from T = {tx:.3g} s ≤ horizon {h:.3g} s)")
    else:
        if not has_rw:
            why = "no random walk in the model up to the horizon"
        elif tx > h:
            why = f"the random walk would overtake the white noise only at T = {tx:.3g} s > horizon {h:.3g} s"
        else:
            why = f"its 95 % CI spans more than a factor {K_CI_SPAN:g}"
        und.append(f"K: {why}; K ≤ {kb:.3g} (the WV band's bound at T = {kb_at:.3g} s)")
    band = band_check(fit.wv, fit.theoretical_wv)
    pair = pair_check(fit.wv, a.N, a.K, a.tau_range_s)
    retry = (fit.extra.get("fit_check") or {}).get("note")
    gate = pair_gate(fit.wv, a.N, a.K, horizon_s=(a.tau_range_s or (None, h))[1],
                     lines=list((fit.extra.get("lines") or {}).get("found", ())))
    fit.extra["export_gate"] = gate.to_dict()
    return AxisCalibration(axis, fit.unit, str(fit.model), a.N, tuple(N_ci), a.K, status, k_fit, tuple(K_ci), kb, kb_at,
                           tx, h, a.tau_range_s, a.worst_ratio, tuple(det), tuple(und), band, pair, retry, gate)


# --------------------------------------------------------------------------------------------------
# the calibration
# --------------------------------------------------------------------------------------------------
@dataclass(eq=False)
class CalibrationResult:
    """Outcome of :func:`calibrate`.

    Attributes
    ----------
    logs : list of LogStops
        Per log: λ_0, the detection, the stops modelled and what was dropped.
    fits : dict
        Per axis the selected :class:`~imunoise.noise.estimator.GMWMFit` (parameters per sample at ``freq_hz``).
    axes : dict
        Per axis the :class:`AxisCalibration`.
    model : imunoise.noise.imu_model.ImuModel
        The six fits as one model (``imu_model.json``; the input of the exports).
    freq_hz : float
        Sample rate [Hz].
    criterion : str
        Selection criterion.
    """

    logs: list[LogStops]
    fits: dict[str, Any]
    axes: dict[str, AxisCalibration]
    model: Any
    freq_hz: float
    criterion: str

    @property
    def static_s(self) -> float:
        """Pooled static time [s]."""
        return float(sum(ls.static_s for ls in self.logs))

    @property
    def n_stops(self) -> int:
        return int(sum(len(ls.stops) for ls in self.logs))

    @property
    def horizon_s(self) -> float:
        """Longest averaging time the pooled stops support [s] (the same on every axis)."""
        return float(max(a.horizon_s for a in self.axes.values()))

    @property
    def longest_stop_s(self) -> float:
        return float(max((s.duration for ls in self.logs for s in ls.stops), default=0.0))

    def summary(self) -> str:
        """Stops, horizon and a table of N and K per axis (values, CIs, bounds), the stops' narrowband lines."""
        from imunoise.lines import Line

        lines = [
            f"calibration from {len(self.logs)} log(s): {self.n_stops} stops, {self.static_s:.1f} s static "
            f"(longest {self.longest_stop_s:.1f} s) at {self.freq_hz:g} Hz; criterion {self.criterion}",
            f"horizon: averaging times up to {self.horizon_s:.3g} s are supported by the pooled stops",
        ]
        for ls in self.logs:
            lines.append(f"  {ls.log.name}: {ls.log.duration_s:.1f} s, λ0 = {ls.lambda0:.4g} m/s² "
                         f"({ls.lambda0_source}); {len(ls.stops)} stops, {ls.static_s:.1f} s")
        lines += ["", f"  {'axis':<9}{'model':<20}{'N [u/√Hz]':>12}  {'95% CI':^23}  {'K [u/s/√Hz]':>12}  "
                  f"{'K is':<6}{'K bound':>11}  {'T_x [s]':>8}  unit"]
        for ax, a in self.axes.items():
            nci = f"[{a.N_ci[0]:.3e}, {a.N_ci[1]:.3e}]" if math.isfinite(a.N_ci[0]) else "—"
            lines.append(f"  {ax:<9}{a.model:<20}{a.N:>12.4e}  {nci:^23}  {a.K_reported:>12.4e}  {a.K_status:<6}"
                         f"{a.K_bound:>11.3e}  {a.crossover_s:>8.3g}  {a.unit}")
        lines.append("  K: the fitted random walk when it is a value, else the bound that holds (exports: see "
                     "their τ range and AV ratio)")
        lines.append("")
        for ax, a in self.axes.items():
            for u in a.undetermined:
                lines.append(f"  {ax}: not determined: {u}")
        for ax, fit in self.fits.items():
            for d in ((fit.extra or {}).get("lines") or {}).get("found", ()):
                lines.append(f"  {ax}: narrowband {Line.from_dict(d).text()} in the stops (vibration; kept in "
                             "the fitted data, named in every export)")
        lines += ["", "exported pair against the data (export refused without --force where it misses the data's AV "
                  "by more than 2x outside its band; the WV band check is a diagnostic):"]
        for ax, a in self.axes.items():
            if a.band is None:
                continue
            tag = "REFUSED" if a.refused else "ok"
            if a.gate is not None:
                lines.append(f"  {ax:<9}{tag:<8}{a.gate.text()}")
            lines.append(f"  {'':<17}{a.model}: {a.band.text()}")
            lines.append(f"  {'':<17}{a.pair_data.text()}; pair/model AV: worst {a.worst_ratio:.3g}×")
            if a.retry:
                lines.append(f"  {'':<17}{a.retry}")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (stops, λ_0, horizon, per-axis values and bounds)."""
        return {
            "freq_hz": self.freq_hz,
            "criterion": self.criterion,
            "static_s": self.static_s,
            "n_stops": self.n_stops,
            "horizon_s": self.horizon_s,
            "logs": [
                {"name": ls.log.name, "duration_s": ls.log.duration_s, "lambda0_m_s2": ls.lambda0,
                 "lambda0_source": ls.lambda0_source, "static_s": ls.static_s, "dropped": ls.dropped,
                 "stops": [{"t0": s.t0, "t1": s.t1, "duration_s": s.duration} for s in ls.stops],
                 **({"warnings": ls.log.meta["warnings"]} if ls.log.meta.get("warnings") else {})}
                for ls in self.logs
            ],
            "axes": {ax: a.to_dict() for ax, a in self.axes.items()},
        }
