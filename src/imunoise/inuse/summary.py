"""The in-motion part as text: one line per axis with the factors, their intervals and units, as ``calibrate
--in-motion`` prints them."""

from __future__ import annotations

import math

from imunoise.imu import AXES
from imunoise.noise.in_motion import InMotionPart, Interval

__all__ = ["summary_lines"]

RAD_S_TO_DEG_H = 180.0 / math.pi * 3600.0


def _iv(x: Interval, fmt: str = "{:.2f}") -> str:
    if x.value is None:
        return "not identified"
    ci = "" if x.ci95 is None else f" [{fmt.format(x.ci95[0])}, {fmt.format(x.ci95[1])}]"
    return f"{fmt.format(x.value)}×{ci}"


def _sigma(a: str, v: float) -> str:
    return f"{v * RAD_S_TO_DEG_H:.3g} °/h" if a.startswith("gyro") else f"{v * 1e3:.3g} mm/s²"


def summary_lines(part: InMotionPart) -> list[str]:
    """Per axis: "gyro_y: in-use N 2.10× static [1.80, 2.50]; bias wander GM σ 120 °/h [..] τ 60 s [..]", the
    group's dispersion where it is above 1, then a bound with its reason."""
    lines = []
    for a in AXES:
        if a not in part.axes:
            continue
        ax = part.axes[a]
        s = f"{a}: in-use N {_iv(ax.white_factor)} static"
        b = ax.bias
        if b.model == "gm" and b.sigma is not None and b.tau_s is not None:
            ci_s, ci_t = b.ci95.get("sigma"), b.ci95.get("tau_s")
            s += f"; bias wander while moving GM σ {_sigma(a, b.sigma)}"
            s += f" [{_sigma(a, ci_s[0])}, {_sigma(a, ci_s[1])}]" if ci_s else ""
            s += f" τ {b.tau_s:.3g} s" + (f" [{ci_t[0]:.3g}, {ci_t[1]:.3g}] s" if ci_t else "")
        elif b.model == "rw" and b.k is not None:
            unit = "rad/s/√s" if a.startswith("gyro") else "m/s²/√s"
            ci = b.ci95.get("k")
            s += f"; bias wander while moving RW k {b.k:.3g} {unit}" + (f" [{ci[0]:.3g}, {ci[1]:.3g}]" if ci else "")
        if ax.factor_K.value is not None:
            s += f"; in-use K {_iv(ax.factor_K)} static"
        c = (part.evidence.get("dispersion") or {}).get("gyro" if a.startswith("gyro") else "accel", 1.0)
        if c > 1.0:  # imunoise.inuse.dispersion: the family's error widens the intervals
            s += f"; dispersion {c:.3g} (model error: log intervals {math.sqrt(c):.3g}× wider)"
        bd = part.bounds.get(a)
        if bd is not None:
            up = "" if bd.upper is None else f" ≤ {_sigma(a, bd.upper) if bd.what == 'bias' else f'{bd.upper:.3g}'}"
            s += f"; {bd.what}{up}: {bd.reason}"
        lines.append(s)
    return lines
