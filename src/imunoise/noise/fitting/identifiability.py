"""Which fitted quantities the data identify: what the delta-method intervals of
:meth:`~imunoise.noise.fitting.result.GMWMFit.confidence_intervals` cannot see by themselves."""

from __future__ import annotations

import math
from typing import Any


def collapsed_components(intervals: dict[str, tuple[float, float]], model: Any) -> dict[str, tuple[float, float]]:
    """``intervals`` with every quantity of a component whose variance is not identified marked so too.

    A Gauss–Markov (or MA1) process whose innovation variance collapsed to its bound contributes nothing to the
    wavelet variance, so its φ (and T_c) is not identified either, however tight the delta method makes it
    look: the optimiser leaves φ wherever it was when σ² went to zero, and another start leaves it elsewhere
    with the same objective.
    """
    out = dict(intervals)
    for comp in {name.split(".")[0] for name in model.param_names}:
        var = f"{comp}.sigma2"
        shape = [n for n in model.param_names if n.split(".")[0] == comp and n != var]
        if var in out and math.isnan(out[var][0]) and shape:
            for name in out:
                if name.split(".")[0] == comp:
                    out[name] = (math.nan, math.nan)
    return out
