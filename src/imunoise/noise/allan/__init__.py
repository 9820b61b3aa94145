"""Allan-variance baseline: automated IEEE Std 952/1293 reading of the overlapping AV
(docs/guide/theory.rst, 'Baselines').

What practitioners do, made reproducible. The overlapping Allan variance at averaging time τ = mΔt is

    AVAR(m) = Σ_k (ȳ_{k+m}(m) − ȳ_k(m))² / (2(N − 2m + 1)),

computed from cumulative sums for any m (the dense log grid), and on the octave grid m = 2^{j−1} it is
exactly 2ν²_j of the Haar wavelet variance (docs/guide/theory.rst, 'Conventions'), so it comes from
:func:`imunoise.noise.wv.wavelet_variance`.

Modules: :mod:`~imunoise.noise.allan.variance` (the AVAR and its intervals), :mod:`~imunoise.noise.allan.reading` (the
automated reading of its lines and the equivalent model), :mod:`~imunoise.noise.allan.curves` (curves of a fit, the
plot). A modelling method of the data path IMU → detection → modelling → filter, next to the GMWM.
"""

from __future__ import annotations

from imunoise.noise.allan.curves import curve_from_fit, curve_to_dict, data_curve, plot_allan
from imunoise.noise.allan.reading import (
    BI_FACTOR,
    LINES,  # noqa: F401 - the line slopes, read by name
    MIN_DOF,
    AllanLine,
    AllanReading,
    allan_fit,
    read_allan,
    reading_model,
    reliable,
    rw_bound,
)
from imunoise.noise.allan.variance import AllanVariance, allan_variance

__all__ = [
    "AllanVariance",
    "AllanLine",
    "AllanReading",
    "allan_variance",
    "read_allan",
    "reading_model",
    "allan_fit",
    "curve_from_fit",
    "data_curve",
    "curve_to_dict",
    "plot_allan",
    "BI_FACTOR",
    "MIN_DOF",
    "reliable",
    "rw_bound",
]
