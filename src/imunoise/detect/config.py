"""Parameters of the static detector (docs/guide/theory.rst, 'Static detection', paper Eq. 9 and 10)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imunoise.errors import ModelError

__all__ = ["DetectorConfig"]


@dataclass(frozen=True)
class DetectorConfig:
    """Parameters of the static detector (docs/guide/theory.rst, 'Static detection').

    ``window`` N [samples] of Eq. (9); ``lambda0`` λ_0 [m/s²] of Eq. (10) (paper: 0.02, which suits a
    quiet IMU; learn it per sensor with :func:`learn_lambda0`); ``min_duration_s`` minimum length of a
    trimmed segment [s]; ``margin_s`` trimmed at each end of a run [s]; ``gate_rate`` [rad/s] of the
    angular-rate gate; ``adaptive`` False uses the fixed threshold λ_0 (Eq. 9 alone);
    ``max_gap_samples``: a time step longer than this many nominal periods restarts the window.
    """

    window: int = 100
    lambda0: float = 0.02
    min_duration_s: float = 2.0
    margin_s: float = 0.5
    gate_rate: float = float(np.deg2rad(30.0))
    adaptive: bool = True
    max_gap_samples: float = 5.0

    def __post_init__(self) -> None:
        # invalid settings are a malformed detector model: ModelError (a ValueError), naming the field to fix
        w = self.window
        if isinstance(w, bool) or not isinstance(w, int | np.integer | float) or not np.isfinite(w) \
                or int(w) != w or w < 2:
            raise ModelError(
                f"DetectorConfig.window must be a whole number of samples ≥ 2 (paper: 100), got {w!r}"
            )
        for name, rule in (("lambda0", "> 0 m/s² (paper: 0.02; or learn it with learn_lambda0)"),
                           ("gate_rate", "> 0 rad/s (docs/guide/theory.rst, 'Static detection': 30 °/s = 0.5236 "
                                         "rad/s)"),
                           ("max_gap_samples", "> 0 sample periods (default 5)"),
                           ("min_duration_s", "≥ 0 s (default 2)"), ("margin_s", "≥ 0 s (default 0.5)")):
            try:
                v = float(getattr(self, name))
            except (TypeError, ValueError):
                v = float("nan")
            ok = v >= 0 if name in ("min_duration_s", "margin_s") else v > 0
            if not (np.isfinite(v) and ok):
                raise ModelError(f"DetectorConfig.{name} must be a finite number {rule}, got {getattr(self, name)!r}")
        object.__setattr__(self, "window", int(w))
