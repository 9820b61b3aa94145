"""What the in-motion noise learner can add to a filter model, and the candidates of one search.

A learned model is a tuple of :class:`LearnedProcess` (at most one per family = (kind, sensor)), added on top of the
static model the stops identified (the six per-axis models of the filter, gyro x, y, z then accel x, y, z):

* ``gm``: an in-motion first-order Gauss–Markov bias on the sensor's three axes, the same σ and T_c on each,
  b_k+1 = φ b_k + √(1 − φ²) σ w_k, φ = exp(−Δt/T_c) (paper Eq. 2's AR1 with σ² = σ_GM²(1 − φ²));
  σ in rad/s (gyro) or m/s² (accelerometer);
* ``white``: white-noise inflation: the per-sample white variance of each axis times the square of ``sigma``
  (a factor ≥ 1: an extra WN of variance (f² − 1)·σ²_white, Model.white_variance);
* ``step``: a departure step: the bias covariance of each axis of the sensor grows by the square of ``sigma`` at
  every start from a stop (the filter piece of the simulator's ``departure_step`` term, issue 21 §1; as
  :func:`imunoise.nav.noise_schedule.add_bias_variance` does for the law-aware oracle).

"Nothing added" is always a candidate (the empty tuple). σ lives on a continuous log scale: a search tries
``centre · ratio^k``, k ∈ {−1, 0, 1}, per family, and the next search is centred on the best σ of the last one
with ``ratio`` → √ratio (refined), see :func:`refine`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

from imunoise.errors import ModelError
from imunoise.noise.model import Model
from imunoise.noise.moved import renamed
from imunoise.noise.processes import AR1, WN

__all__ = ["LearnedProcess", "Family", "DEFAULT_FAMILIES", "LIKELIHOOD_FAMILIES", "compose", "rated", "with_process",
           "describe", "departure_variance", "search_candidates", "refine", "spec_from_dicts", "DPH"]

DPH = math.pi / 180.0 / 3600.0  # °/h → rad/s
SENSORS = ("gyro", "accel")
KINDS = ("gm", "white", "step")


@dataclass(frozen=True)
class LearnedProcess:
    """One learned process on the three axes of ``sensor`` (module docstring); ``sigma`` SI (factor for
    ``white``), ``tc_s`` the Gauss–Markov correlation time [s] (0 otherwise)."""

    kind: str
    sensor: str
    sigma: float
    tc_s: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in KINDS or self.sensor not in SENSORS:
            raise ModelError(f"learned process: kind must be one of {KINDS} and sensor one of {SENSORS}, "
                             f"got {self.kind!r}, {self.sensor!r}")
        if not (math.isfinite(self.sigma) and self.sigma > 0) or (self.kind == "white" and self.sigma <= 1.0):
            raise ModelError(f"learned process {self.kind}/{self.sensor}: sigma must be finite and > 0 "
                             f"(> 1, a factor, for white), got {self.sigma!r}")
        if self.kind == "gm" and not (math.isfinite(self.tc_s) and self.tc_s > 0):
            raise ModelError(f"learned Gauss–Markov process needs tc_s > 0 s, got {self.tc_s!r}")

    @property
    def family(self) -> tuple[str, str]:
        return (self.kind, self.sensor)

    def to_dict(self) -> dict[str, Any]:
        """JSON form with the unit in the key (rad/s, m/s² or a factor)."""
        unit = "factor" if self.kind == "white" else ("rad_s" if self.sensor == "gyro" else "m_s2")
        d: dict[str, Any] = {"kind": self.kind, "sensor": self.sensor, f"sigma_{unit}": self.sigma}
        if self.sensor == "gyro" and self.kind != "white":
            d["sigma_dph"] = self.sigma / DPH
        if self.kind == "gm":
            d["tc_s"] = self.tc_s
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> LearnedProcess:
        try:
            sig = next(v for k, v in d.items() if k.startswith("sigma_") and k != "sigma_dph")
            return cls(str(d["kind"]), str(d["sensor"]), float(sig), float(d.get("tc_s", 0.0)))
        except (KeyError, StopIteration, TypeError, ValueError) as exc:
            raise ModelError(f"not a learned process: {d!r} (needs kind, sensor and sigma_<unit>)") from exc


Spec = tuple[LearnedProcess, ...]


@dataclass(frozen=True)
class Family:
    """The σ scale of one family in a search: ``centre`` SI (factor for white), ``ratio`` > 1 between the
    tried values, ``tc_s`` the correlation times tried (gm)."""

    kind: str
    sensor: str
    centre: float
    ratio: float
    tc_s: tuple[float, ...] = ()

    def values(self) -> list[float]:
        vals = [self.centre / self.ratio, self.centre, self.centre * self.ratio]
        if self.kind == "white":  # an inflation factor: only > 1 adds anything
            vals = [v for v in vals if v > 1.05]
        return vals


# centres: gyro 100 °/h (the oracle's processes on the shared drive, issue 21), accelerometer 1 cm/s²;
# white ×2.5 (×1.6, ×4); departure steps 100 °/h and 1 cm/s²; each ×3 and ÷3
DEFAULT_FAMILIES: tuple[Family, ...] = (
    Family("gm", "gyro", 100.0 * DPH, 3.0, (10.0, 100.0)),
    Family("gm", "accel", 0.01, 3.0, (100.0,)),
    Family("white", "gyro", 2.5, 1.6),
    Family("white", "accel", 2.5, 1.6),
    Family("step", "gyro", 100.0 * DPH, 3.0),
    Family("step", "accel", 0.01, 3.0),
)

# the likelihood statistic's scales: the bias processes only (Gauss–Markov with T_c = 100 s, departure steps).
# The one-step innovation likelihood sees seconds ahead; a T_c shorter than an outage makes the filter forget,
# within the outage, the bias it had estimated, and white-noise inflation fits the fixes without better bias
# estimates: on development seeds both fitted the fixes better and drifted more in 60-s outages
# (docs/evidence/in_motion_likelihood.md)
LIKELIHOOD_FAMILIES: tuple[Family, ...] = (Family("gm", "gyro", 100.0 * DPH, 3.0, (100.0,)), DEFAULT_FAMILIES[1],
                                           *DEFAULT_FAMILIES[4:])


def with_process(spec: Spec, p: LearnedProcess) -> Spec:
    """``spec`` with ``p`` in place of the process of its family (added if the family has none)."""
    return tuple(sorted([q for q in spec if q.family != p.family] + [p], key=lambda q: (q.sensor, q.kind)))


def search_candidates(current: Spec, families: Sequence[Family]) -> list[Spec]:
    """The candidates of one search: ``current`` with one family's process set to one value of its scale (per
    family σ × T_c), and the empty model if ``current`` is not empty. Duplicates of ``current`` are left out."""
    out: list[Spec] = []
    if current:
        out.append(())
    for f in families:
        for v in f.values():
            for tc in (f.tc_s or (0.0,)):
                s = with_process(current, LearnedProcess(f.kind, f.sensor, v, tc))
                if s != current and s not in out:
                    out.append(s)
    return out


def refine(families: Sequence[Family], best: dict[tuple[str, str], LearnedProcess], min_ratio: float = 1.25) -> tuple:
    """The next search's scales: each family centred on its best process of the last search (if any), the ratio
    its square root (not below ``min_ratio``; a ratio of 1 stays 1: one value)."""
    out = []
    for f in families:
        p = best.get((f.kind, f.sensor))
        ratio = f.ratio if f.ratio <= 1.0 else max(math.sqrt(f.ratio), min_ratio)
        tcs = f.tc_s
        if p is not None and f.kind == "gm" and len(tcs) > 1:
            tcs = (p.tc_s,)  # T_c from the small set is decided once; σ keeps being refined
        out.append(replace(f, centre=p.sigma if p is not None else f.centre, ratio=ratio, tc_s=tcs))
    return tuple(out)


def compose(static_models: Sequence[Any], spec: Spec, rate_hz: float) -> list:
    """The six models of the filter (each carrying its rate; ``rate_hz`` for one without): the static models with
    the Gauss–Markov and white parts of ``spec`` added (a departure step is not a process of the model:
    :func:`departure_variance`)."""
    out = []
    for a, mm in enumerate(static_models):
        m = rated(mm, rate_hz)
        fr = m.freq
        sensor = SENSORS[a // 3]
        comps = list(m.components)
        for p in spec:
            if p.sensor != sensor:
                continue
            if p.kind == "gm":
                phi = math.exp(-1.0 / (p.tc_s * fr))
                comps.append(AR1(phi=phi, sigma2=p.sigma ** 2 * (1.0 - phi * phi)))
            elif p.kind == "white":
                extra = (p.sigma ** 2 - 1.0) * m.white_variance()
                wn = [i for i, c in enumerate(comps) if isinstance(c, WN)]
                if wn:  # one WN per model: the extra variance joins it
                    comps[wn[0]] = WN(sigma2=float(comps[wn[0]].values[0]) + extra)
                else:
                    comps.append(WN(sigma2=extra))
        out.append(Model(comps, fr) if any(p.sensor == sensor for p in spec) else m)
    return out


def rated(m: Any, rate_hz: float) -> Model:
    """``m`` as a model carrying its rate: its own, ``rate_hz`` for one without, a (model, freq) pair's freq."""
    if isinstance(m, tuple):
        return m[0].with_freq(m[0].sample_rate(m[1]))
    return m if m.freq is not None else m.with_freq(rate_hz)


def departure_variance(spec: Spec) -> list[float] | None:
    """Per axis (gyro x, y, z, accel x, y, z) the bias variance a departure adds, or None without a step."""
    steps = [p for p in spec if p.kind == "step"]
    if not steps:
        return None
    var = [0.0] * 6
    for p in steps:
        for j in range(3):
            var[3 * SENSORS.index(p.sensor) + j] = p.sigma ** 2
    return var


def describe(spec: Spec) -> list[dict[str, Any]]:
    """JSON form of a learned model (the event log and the exported model)."""
    return [p.to_dict() for p in spec]


def spec_from_dicts(items: Sequence[dict[str, Any]]) -> Spec:
    out: Spec = ()
    for d in items:
        out = with_process(out, LearnedProcess.from_dict(d))
    return out


# the old name of LearnedProcess (it clashed with imunoise.noise.processes.Process, the noise process)
__getattr__ = renamed(__name__, {"Process": (lambda: LearnedProcess, "imunoise.online.learner.candidates.Process is "
                                 "renamed LearnedProcess; the old name goes in the next release")})
