"""Settings of the online engine: :class:`OnlineConfig` (docs/guide/theory.rst, 'Online engine'), the complete model the
structure is identified from (``COMPLETE``), the threshold below which a fitted component counts as absent in the filter
(``NEGLIGIBLE``) and the settings summary written in the ``start`` event (:func:`config_summary`). What the
settings do: :mod:`imunoise.online.navigator` (the engine) and :mod:`imunoise.online.to_filter` (the fit →
filter mapping)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from typing import Any

from imunoise.detect import DetectorConfig
from imunoise.errors import ModelError
from imunoise.nav.defaults import EkfConfig
from imunoise.nav.filter_model import NEGLIGIBLE  # re-exported: the engine's name for it
from imunoise.online.motion_noise import MotionNoiseConfig

__all__ = ["COMPLETE", "NEGLIGIBLE", "OnlineConfig", "config_summary"]

COMPLETE = "4*AR1 + DR + WN + QN + RW"


@dataclass(frozen=True)
class OnlineConfig:
    """Settings of :class:`OnlineNavigator` (SI units; times in s).

    ``detector``: static detector settings; ``None`` learns λ_0 from the first ``learn_lambda0_s`` of the
    IMU stream (which must be a stop, as for the alignment; :func:`imunoise.detect.learn_lambda0`).
    ``min_static_s``: static data needed before the structure identification (paper: the first long
    stop). ``complete``/``criterion``/``top``: the selection (docs/guide/theory.rst, 'Model selection').
    ``modelling=False`` runs the EKF
    with its initial models only (the plain/AV/EM baselines use this with ``initial_models``).
    ``latency``: fixed delay from a stop's completion to the model's effect (``None``: measured compute
    time). ``worker``: ``"inline"`` (replay) or ``"thread"``. ``gate``: use the 30 °/s angular-rate gate.
    ``zupt``: zero-velocity and zero-angular-rate updates every ``zupt_every`` samples while the
    detector has been static for ``zupt_after`` samples and the filter's horizontal speed is below
    ``zupt_max_speed`` (default ∞: a finite guard, e.g. 1 m/s, blocks false ZUPTs on a car cruising smoothly
    but also the ZUPTs that matter most, at stops inside a GNSS outage when the drifting filter believes it
    moves: measured on the simulator, mean outage drift 47 → 105 m with a 1 m/s guard) (σ ``zupt_sigma_v``
    m/s; the ZARU σ: see :meth:`_zaru_sigma`); a ZUPT whose NIS exceeds ``zupt_chi2`` (3 dof; default 0 =
    off) is skipped and logged once per stop (``zupt_rejected``). Measured: a 21.1 gate rejects the valid
    ZUPTs of an overconfident filter at stops inside outages (drive_0708 plain + ZUPT 247 → 342 m) and does
    not cure the false static detections of a noisy IMU, so it is off. ``floor``/``fold_tau_s``/
    ``dr``/``qn``: the mapping of a fit to filter noise (module docstring). ``warm_up``: compile (or load
    from numba's on-disk cache) the modelling kernels at construction (:func:`imunoise.noise.fitting.warm.warm_up`;
    inline, or in the worker thread with ``worker="thread"``) and log it as a ``warm_up`` event, so the first
    identification does not wait for the compiler (8–10 s of CPU in a fresh clone, measured on drive_0708).
    ``stop_guard``: ``"nav"`` (default) models a detected stop only where the navigation solution agrees
    (:mod:`imunoise.online.stops`): while GNSS-aided (a fix used within ``stop_aided_s``) the horizontal speed
    must stay below max(``stop_max_speed``, ``stop_sigma_k``·σ_h); unaided samples are tested by the
    zero-velocity NIS ≤ ``stop_chi2`` (3 dof, σ ``zupt_sigma_v``) when > 0, else not at all; a violation within
    ``stop_edge_s`` of a segment end trims the segment. A rejected segment never reaches the wavelet variance
    (``stop_rejected`` event, :attr:`OnlineResult.rejected_segments`). ``"none"``: every detected stop is
    modelled (the IMU-only test; a noisy IMU's learned λ_0 lets smooth cruising pass it).
    ``motion_noise``: learn in-motion gyro noise while driving by rehearsing GNSS outages on the data seen
    (:class:`~imunoise.online.motion_noise.MotionNoiseConfig`; ``None``, the default, = off; the ``gmwm_dyn``
    method of the experiments).
    """

    ekf: EkfConfig = field(default_factory=EkfConfig)
    detector: DetectorConfig | None = None
    learn_lambda0_s: float = 10.0
    min_static_s: float = 20.0
    complete: str = COMPLETE
    criterion: str = "wvic"
    top: int = 3
    weights: str = "efficient"
    modelling: bool = True
    latency: float | None = None
    worker: str = "inline"
    gate: bool = True
    zupt: bool = False
    zupt_every: int = 10
    zupt_after: int = 50
    zupt_sigma_v: float = 0.02
    zupt_max_speed: float = math.inf
    zupt_chi2: float = 0.0
    zaru_sigma_w: float = 1e-3
    floor: str = "default"
    fold_tau_s: float = 1.0
    dr: str = "rw"
    qn: str = "white"
    swap: str = "preserve"
    store: bool = True
    warm_up: bool = True
    stop_guard: str = "nav"
    stop_max_speed: float = 1.0
    stop_aided_s: float = 3.0
    stop_edge_s: float = 3.0
    stop_sigma_k: float = 3.0
    stop_chi2: float = 0.0
    motion_noise: MotionNoiseConfig | None = None

    def __post_init__(self) -> None:
        if self.criterion not in ("gof", "wvic"):
            raise ModelError(f"criterion must be 'gof' or 'wvic', got {self.criterion!r}")
        if self.worker not in ("inline", "thread"):
            raise ModelError(f"worker must be 'inline' or 'thread', got {self.worker!r}")
        if self.swap not in ("preserve", "reset"):
            raise ModelError(f"swap must be 'preserve' or 'reset', got {self.swap!r}")
        if self.qn not in ("drop", "white"):
            raise ModelError(f"qn must be 'drop' or 'white', got {self.qn!r}")
        if self.dr not in ("rw", "drop", "state"):
            raise ModelError(f"dr must be 'rw', 'drop' or 'state', got {self.dr!r}")
        if self.floor not in ("default", "none"):
            raise ModelError(f"floor must be 'default' or 'none', got {self.floor!r}")
        if self.latency is not None and not (math.isfinite(self.latency) and self.latency >= 0):
            raise ModelError(f"latency must be ≥ 0 s or None, got {self.latency!r}")
        if not self.min_static_s > 0:
            raise ModelError(f"min_static_s must be > 0 s, got {self.min_static_s}")
        if self.stop_guard not in ("nav", "none"):
            raise ModelError(f"stop_guard must be 'nav' or 'none', got {self.stop_guard!r}")
        for name, rule in (("stop_max_speed", "> 0 m/s (default 1)"), ("stop_aided_s", "> 0 s (default 3)"),
                           ("stop_edge_s", "≥ 0 s (default 3)"), ("stop_sigma_k", "≥ 0 (default 3)"),
                           ("stop_chi2", "≥ 0 (0 = off)")):
            v = getattr(self, name)
            x = float(v) if isinstance(v, int | float) and not isinstance(v, bool) else math.nan
            ok = x > 0 if name in ("stop_max_speed", "stop_aided_s") else x >= 0
            if not (math.isfinite(x) and ok):
                raise ModelError(f"{name} must be a finite number {rule}, got {v!r}")

    def with_(self, **kw: Any) -> OnlineConfig:
        return replace(self, **kw)


def config_summary(c: OnlineConfig) -> dict:
    return {
        "min_static_s": c.min_static_s, "complete": c.complete, "criterion": c.criterion, "latency": c.latency,
        "worker": c.worker, "gate": c.gate, "zupt": c.zupt, "floor": c.floor, "fold_tau_s": c.fold_tau_s,
        "modelling": c.modelling, "stop_guard": c.stop_guard,
        "motion_noise": None if c.motion_noise is None else asdict(c.motion_noise),
    }
