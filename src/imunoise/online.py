"""Online engine: static detection → online GMWM → model hot-swap in the EKF (SPEC §0, §9; paper Fig. 1).

Per IMU sample the navigator (1) feeds the static detector (SPEC §7), (2) sets the angular-rate gate,
(3) propagates the loosely coupled EKF (SPEC §8) and applies queued GNSS fixes, (4) optionally applies
ZUPT/ZARU while the detector says "static", (5) applies a new error model whose effect time has come.

Modelling (paper §2.2–2.3). Every completed static segment (trimmed, bias removed = segment mean, all six
axes) is added to one :class:`~imunoise.wv.WVAccumulator` per axis (pooled WV, no junction crosses two
stops). Once ``min_static_s`` of static data exist, the structure is identified per axis over every
sub-model of ``complete`` (:func:`imunoise.selection.select_model`, criterion ``"gof"`` as the paper, the
default, or ``"wvic"``); after every later stop the fixed structure is re-estimated on all static data so far,
warm-started from the previous fit (:func:`imunoise.selection.refit`). A fit is rejected (the current
model is kept and the reason logged) when it has non-finite parameters or when its GOF on the new WV is
worse than the current parameters' GOF on the same WV and Ω.

From a GMWM fit to filter noise (``ekf_axis_model``). The static fit describes the sensor at rest; the
EKF needs a model of the error that drives the navigation states while driving. The mapping:

* WN → white noise of δv/φ (density N² = σ²/f);
* AR1 with T_c ≥ ``fold_tau_s`` → an augmented Gauss–Markov state; faster AR1 → white noise with the
  same low-frequency density (per sample σ²/(1 − φ)², the AR1 spectrum at f = 0): a state that decorrelates
  between two covariance steps carries no information the filter can use, and folding keeps the
  state vector small;
* QN → white noise with the per-sample variance 2Q² (as ``Model.white_variance``), by default
  (``qn="white"``). True quantisation noise has zero density at f = 0 (its integral is bounded), which
  ``qn="drop"`` models; but on a car standing with its engine running the τ⁻² part of the WV is engine
  vibration (2.4 °/s per sample on gyro y of the shared drive), and while driving the vibration is larger
  still. Measured on the shared drive (five 60 s outages): mean end drift 338 m plain, 337 m with QN
  dropped, 226 m with QN as white; the simulator (no QN in the truth) is indifferent.
* AR1 with T_c·f beyond the longest Haar scale of the static data → random walk with the AR1's innovation
  variance (the same WV at every scale the data has). Kept as a state, such a fit (T_c = 3·10⁵ s, σ_GM =
  1 °/s on a simulated gyro) entered the filter with its extrapolated stationary σ as initial uncertainty;
  two GNSS fixes before an outage moved that bias and the outage ended 3 km off;
* DR → the random walk with the same Haar WV at the longest scale of the static data (``dr="rw"``, the
  default; :func:`dr_equivalent_rw`). On seconds-long stops a rate random walk and a ramp are two readings
  of the same rising WV (GOF often picks DR where the truth is RW); a ramp state would extrapolate one
  fitted slope, and dropping it (``dr="drop"``, the earlier behaviour) throws away the evidence that the
  bias wanders. RW → bias random walk.
* ``floor="default"`` (the default): white density, RW and the slow Gauss–Markov bias of the plain
  default model (``EkfConfig.fallback``) are lower bounds. The static model never makes the filter more
  confident than the plain filter about the low-frequency error it cannot see in seconds-long stops,
  nor about the white noise of a moving car (vibration grows with speed). ``floor="none"`` uses the
  static model as is (measured in the experiments: overconfident on the real drive).

Swap (``swap="preserve"``, default; :func:`swap_preserving`): a refit of the same structure keeps every
augmented state (estimate and covariance) and only changes Φ and Q; on the first swap the floor's slow
Gauss–Markov state, common to the plain default and the new model, is kept too. ``swap="reset"`` uses
:meth:`LooselyCoupledEKF.swap_model` (every new AR1 starts at 0 with its stationary variance): measured on
20 simulated drives that reset at every stop costs +30 % mean outage drift against plain (6 drives:
128 m reset, 105 m preserve, 109 m plain); on the real drive 225 m reset vs 215 m preserve.

Criterion. GOF always prefers the biggest nested model; WVIC (GOF + 2·#identifiable parameters) penalises
size. Measured (20 simulated drives, real drive): GOF 88 m vs WVIC 96 m vs plain 92 m mean outage drift on the
simulator (before the collapse rule below, excluding one GOF divergence), 209 m vs 216 m vs 338 m on the
real drive. With GOF, components that collapsed to the parameter bound (σ² ~ 1e-57, kept by the nesting
guarantee of the selection) are dropped from the filter model (``NEGLIGIBLE``): kept, they made P
ill-conditioned and the filter diverged on one simulated drive (4 km drift). Default: ``"gof"``.

Worker. ``worker="inline"`` (replay, deterministic): a model is computed at the stop's completion and takes
effect at that time plus ``latency`` (a fixed delay; ``None`` = the measured compute time, as the paper's
Table 6 time-taken). ``worker="thread"`` (live use): the fit runs in a background thread and the filter
never waits; the model takes effect at the first sample after the thread finished.

``run(imu, gnss)`` (batch) and ``push_imu``/``push_gnss``/``solution`` (streaming) run the same code: batch
only precomputes the detector over all samples (:meth:`StaticDetector.push_chunk`, identical to per-sample
pushes) and interleaves the GNSS fixes by time (a fix at t_g is applied after the first IMU sample with
t ≥ t_g, as in :func:`imunoise.nav.ekf.run_ekf`).
"""

from __future__ import annotations

import json
import logging
import math
import time
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from imunoise.detect import DetectorConfig, StaticDetector, StaticSegment, learn_lambda0
from imunoise.errors import DataError, ImunoiseError
from imunoise.gmwm import GMWMFit
from imunoise.model import Model
from imunoise.nav.defaults import EkfConfig, default_axis_models
from imunoise.nav.earth import dcm_to_euler, radii
from imunoise.nav.ekf import AXES, InitialState, LooselyCoupledEKF, _sensor_errors
from imunoise.nav.mechanization import I_DTH, I_Q, NAV_LEN, quat_to_dcm
from imunoise.processes import AR1, RW, WN
from imunoise.wv import WVAccumulator

log = logging.getLogger(__name__)

__all__ = [
    "OnlineConfig",
    "OnlineNavigator",
    "OnlineResult",
    "ModelUpdate",
    "ekf_axis_model",
    "dr_equivalent_rw",
    "data_horizon",
    "swap_preserving",
    "run_online",
]

COMPLETE = "4*AR1 + DR + WN + QN + RW"
NEGLIGIBLE = 1e-12  # relative stationary variance below which a fitted AR1 is treated as absent


@dataclass(frozen=True)
class OnlineConfig:
    """Settings of :class:`OnlineNavigator` (SI units; times in s).

    ``detector``: static detector settings; ``None`` learns λ_0 from the first ``learn_lambda0_s`` of the
    IMU stream (which must be a stop, as for the alignment; :func:`imunoise.detect.learn_lambda0`).
    ``min_static_s``: static data needed before the structure identification (paper: the first long
    stop). ``complete``/``criterion``/``top``: the selection (SPEC §5). ``modelling=False`` runs the EKF
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
    ``dr``/``qn``: the mapping of a fit to filter noise (module docstring).
    """

    ekf: EkfConfig = field(default_factory=EkfConfig)
    detector: DetectorConfig | None = None
    learn_lambda0_s: float = 10.0
    min_static_s: float = 20.0
    complete: str = COMPLETE
    criterion: str = "gof"
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

    def __post_init__(self) -> None:
        if self.criterion not in ("gof", "wvic"):
            raise ImunoiseError(f"criterion must be 'gof' or 'wvic', got {self.criterion!r}")
        if self.worker not in ("inline", "thread"):
            raise ImunoiseError(f"worker must be 'inline' or 'thread', got {self.worker!r}")
        if self.swap not in ("preserve", "reset"):
            raise ImunoiseError(f"swap must be 'preserve' or 'reset', got {self.swap!r}")
        if self.qn not in ("drop", "white"):
            raise ImunoiseError(f"qn must be 'drop' or 'white', got {self.qn!r}")
        if self.dr not in ("rw", "drop", "state"):
            raise ImunoiseError(f"dr must be 'rw', 'drop' or 'state', got {self.dr!r}")
        if self.floor not in ("default", "none"):
            raise ImunoiseError(f"floor must be 'default' or 'none', got {self.floor!r}")
        if self.latency is not None and not (math.isfinite(self.latency) and self.latency >= 0):
            raise ImunoiseError(f"latency must be ≥ 0 s or None, got {self.latency!r}")
        if not self.min_static_s > 0:
            raise ImunoiseError(f"min_static_s must be > 0 s, got {self.min_static_s}")

    def with_(self, **kw: Any) -> OnlineConfig:
        return replace(self, **kw)


# --------------------------------------------------------------------------------------------------
# fit → filter model
# --------------------------------------------------------------------------------------------------
def data_horizon(fit: Any) -> float | None:
    """The longest Haar scale (samples) of the WV a fit was made on: the ``horizon`` of :func:`ekf_axis_model`;
    None when the fit carries no WV (e.g. an Allan-variance model built without one)."""
    wv = getattr(fit, "wv", None)
    return float(wv.scales[-1]) if wv is not None else None


def dr_equivalent_rw(omega: float, horizon: float) -> float:
    """γ² (per sample) of the random walk with the same Haar WV as a drift ω at scale τ = ``horizon`` samples:
    ω²τ²/16 = γ²(τ² + 2)/(12τ) (SPEC §2), so γ² = 3ω²τ³/(4(τ² + 2)).

    Over the scales a static record covers, a ramp and a random walk are two readings of the same rising
    WV; a ramp state in the filter would extrapolate one fitted slope over the whole drive, while the
    random walk lets the filter track a bias that keeps wandering at the rate the data showed.
    """
    tau = float(horizon)
    return 3.0 * omega * omega * tau**3 / (4.0 * (tau * tau + 2.0))


def ekf_axis_model(model: Model, freq: float, floor: Model | None = None, *, fold_tau_s: float = 1.0,
                   dr: str = "rw", horizon: float | None = None, qn: str = "white") -> Model:
    """Filter model of one axis from a static GMWM model (module docstring: WN, slow AR1s, RW kept; fast
    AR1s folded into WN with the density σ²/(1 − φ)² per sample; QN as white (2Q² per sample) or dropped
    (``qn="drop"``); DR as the equivalent random walk at ``horizon`` (``dr="rw"``, :func:`dr_equivalent_rw`),
    dropped (``dr="drop"``) or kept as a ramp state (``dr="state"``)). ``horizon``: the longest Haar
    scale of the data the model was fitted on, in samples (required when the model has a DR and
    ``dr="rw"``); an AR1 whose T_c·f exceeds it becomes a random walk with its innovation variance.

    ``floor`` (a WN + RW + AR1 model with known parameters, per sample at ``freq``) bounds the white
    variance and γ² from below and contributes its AR1 (the slow bias instability) when the model has no
    AR1 at least as slow. Parameters per sample at ``freq``.
    """
    white = 0.0
    gamma2 = 0.0
    ar1: list[tuple[float, float]] = []
    ramp = None
    phi_fold = math.exp(-1.0 / (fold_tau_s * freq)) if fold_tau_s > 0 else 0.0
    for c in model.components:
        if c.kind == "WN":
            white += c.values[0]
        elif c.kind == "RW":
            gamma2 += c.values[0]
        elif c.kind == "AR1":
            phi, s2 = c.values
            if horizon is not None and phi > 0 and -1.0 / math.log(phi) > horizon:
                # T_c beyond the longest scale of the data: its WV rises like a random walk's over every
                # scale the data has, and its stationary σ (what a new state would start with) is an
                # extrapolation; a random walk with the same innovation carries what the data showed
                gamma2 += s2
            elif phi >= phi_fold:
                ar1.append((phi, s2))
            else:
                white += s2 / (1.0 - phi) ** 2
        elif c.kind == "DR" and dr == "state":
            ramp = c.values[0]
        elif c.kind == "DR" and dr == "rw":
            if horizon is None or not horizon >= 2:
                raise ImunoiseError("ekf_axis_model: a DR maps to a random walk at the data's longest scale; "
                                    "pass horizon (samples, ≥ 2) or dr='drop'/'state'")
            gamma2 += dr_equivalent_rw(c.values[0], horizon)
        elif c.kind == "QN" and qn == "white":
            white += 2.0 * c.values[0]
    if floor is not None:
        for c in floor.components:
            if c.kind == "WN":
                white = max(white, c.values[0])
            elif c.kind == "RW":
                gamma2 = max(gamma2, c.values[0])
            elif c.kind == "AR1":
                phi_f, s2_f = c.values
                var_f = s2_f / (1 - phi_f**2)
                slow = [(p, s) for p, s in ar1 if p >= phi_f]
                if not slow or max(s / (1 - p * p) for p, s in slow) < var_f:
                    ar1.append((phi_f, s2_f))
    # a process that collapsed to zero amplitude in the fit (GOF keeps such "nested" components at the
    # parameter bound, σ²_GM ~ 1e-57) carries nothing and would make P ill-conditioned: drop it
    total = white + sum(s / (1 - p * p) for p, s in ar1)
    comps: list = [AR1(phi=p, sigma2=s) for p, s in ar1 if s / (1 - p * p) > NEGLIGIBLE * total]
    if white > 0:
        comps.append(WN(sigma2=white))
    if gamma2 > NEGLIGIBLE * max(total, 1e-300):
        comps.append(RW(gamma2=gamma2))
    if ramp is not None:
        from imunoise.processes import DR

        comps.append(DR(omega=ramp))
    if not comps:
        comps.append(WN(sigma2=1e-30))
    return Model(comps)


# --------------------------------------------------------------------------------------------------
# results
# --------------------------------------------------------------------------------------------------
@dataclass
class ModelUpdate:
    """One modelling job: ``kind`` "identify" or "refit"; ``t_stop`` completion time of the stop that
    triggered it; ``t_effect`` when the filter used it (None if rejected on every axis); ``fits`` the six
    accepted fits (or None per axis when rejected); ``elapsed_s`` per axis compute times."""

    kind: str
    t_stop: float
    t_effect: float | None
    static_s: float
    fits: list[GMWMFit | None]
    elapsed_s: list[float]
    rankings: list[Any] = field(default_factory=list)
    rejected: list[str | None] = field(default_factory=list)


@dataclass
class OnlineResult:
    """Output of the online run at every IMU epoch the filter processed (IMU point)."""

    t: np.ndarray
    llh: np.ndarray
    vel_ned: np.ndarray
    euler: np.ndarray
    gyro_error: np.ndarray
    accel_error: np.ndarray
    std: np.ndarray
    events: list[dict]
    updates: list[ModelUpdate]
    segments: list[StaticSegment]
    gate_open: np.ndarray
    static_raw: np.ndarray
    lambda0: float
    elapsed_s: float
    final_models: list[tuple[Model, float]]
    fits: list[GMWMFit | None] = field(default_factory=list)
    sample_t: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def timing(self) -> dict[str, Any]:
        """``identification_s`` (total and per axis) and ``refit_s`` (per job, max over axes)."""
        ident = [u for u in self.updates if u.kind == "identify"]
        refits = [u for u in self.updates if u.kind == "refit"]
        return {
            "identification_s": float(sum(ident[0].elapsed_s)) if ident else None,
            "identification_per_axis_s": list(ident[0].elapsed_s) if ident else [],
            "refit_s": [float(sum(u.elapsed_s)) for u in refits],
            "refit_max_axis_s": [float(max(u.elapsed_s)) for u in refits],
        }

    def antenna_llh(self, lever_arm) -> np.ndarray:
        """Positions of the point at ``lever_arm`` (body FRD, m) from the IMU (e.g. the GNSS antenna)."""
        x, y, z = (float(v) for v in np.asarray(lever_arm, dtype=float))
        out = self.llh.copy()
        if not (x or y or z):
            return out
        r, p, w = self.euler[:, 0], self.euler[:, 1], self.euler[:, 2]
        sr, cr, sp, cp, sy, cy = np.sin(r), np.cos(r), np.sin(p), np.cos(p), np.sin(w), np.cos(w)
        # C_b^n = R_z(yaw) R_y(pitch) R_x(roll) (nav.earth.euler_to_dcm) applied to the lever arm
        dn = cp * cy * x + (-cr * sy + sr * sp * cy) * y + (sr * sy + cr * sp * cy) * z
        de = cp * sy * x + (cr * cy + sr * sp * sy) * y + (-sr * cy + cr * sp * sy) * z
        dd = -sp * x + sr * cp * y + cr * cp * z
        rm, rn = radii(out[:, 0])
        out[:, 0] += dn / (rm + out[:, 2])
        out[:, 1] += de / ((rn + out[:, 2]) * np.cos(out[:, 0]))
        out[:, 2] -= dd
        return out

    def write_events(self, path: str | Path) -> Path:
        """JSON lines, one event per line (SPEC §9, §11)."""
        p = Path(path)
        with p.open("w") as fh:
            for e in self.events:
                fh.write(json.dumps(e, default=_json_default) + "\n")
        return p


def _json_default(o: Any) -> Any:
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer, np.bool_)):
        return o.item()
    return str(o)


class _Store:
    """Growing per-epoch storage (t, position, velocity, quaternion, sensor errors, σ)."""

    COLS = 1 + 3 + 3 + 4 + 6 + 9

    def __init__(self, capacity: int = 65536):
        self.buf = np.empty((max(capacity, 16), self.COLS))
        self.n = 0

    def add(self, row: np.ndarray) -> None:
        if self.n == self.buf.shape[0]:
            self.buf = np.concatenate([self.buf, np.empty_like(self.buf)])
        self.buf[self.n] = row
        self.n += 1

    def arrays(self):
        b = self.buf[: self.n]
        eul = np.empty((self.n, 3))
        for k in range(self.n):
            eul[k] = dcm_to_euler(quat_to_dcm(b[k, 7:11]))
        return b[:, 0].copy(), b[:, 1:4].copy(), b[:, 4:7].copy(), eul, b[:, 11:14].copy(), b[:, 14:17].copy(), \
            b[:, 17:26].copy()


# --------------------------------------------------------------------------------------------------
# modelling job (pure function of the pooled WVs and the current fits; runs inline or in a thread)
# --------------------------------------------------------------------------------------------------
def _model_job(kind: str, wvs: list, current: list[GMWMFit | None], config: OnlineConfig, freq: float) -> dict:
    from imunoise.selection import refit, select_model

    fits: list[GMWMFit | None] = []
    elapsed: list[float] = []
    rankings: list[Any] = []
    rejected: list[str | None] = []
    for a in range(6):
        t0 = time.perf_counter()
        unit = "rad/s" if a < 3 else "m/s²"
        reason = None
        fit = None
        ranking = None
        try:
            if kind == "identify" or current[a] is None:
                ranking = select_model(wvs[a], freq=freq, complete=config.complete, criterion=config.criterion,
                                       top=config.top, weights=config.weights, unit=unit)
                fit = ranking.best
            else:
                fit = refit(current[a], wvs[a], start=current[a], freq=freq, weights=config.weights, unit=unit)
        except ImunoiseError as exc:
            reason = f"fit failed: {exc}"
        except (ValueError, FloatingPointError, np.linalg.LinAlgError) as exc:  # never crash the filter
            reason = f"fit failed ({type(exc).__name__}): {exc}"
        if fit is not None:
            reason = _implausible(fit, current[a])
        elapsed.append(time.perf_counter() - t0)
        rankings.append(ranking)
        rejected.append(reason)
        fits.append(None if reason else fit)
    return {"fits": fits, "elapsed": elapsed, "rankings": rankings, "rejected": rejected}


def _implausible(fit: GMWMFit, current: GMWMFit | None) -> str | None:
    """Reason to reject a fit, or None (SPEC §9: non-finite, GOF worse than the current model's)."""
    v = fit.model.vector
    if not (np.all(np.isfinite(v)) and math.isfinite(fit.objective)):
        return "non-finite parameters or GOF"
    if current is not None and current.model.unknown() == fit.model.unknown():
        try:
            gof_cur = fit.objective_at(current.model)
        except (ImunoiseError, ValueError):
            gof_cur = math.inf
        if fit.objective > gof_cur * (1 + 1e-9) + 1e-12:
            return f"GOF {fit.objective:.4g} worse than the current model's {gof_cur:.4g} on the same WV"
    return None


def swap_preserving(ekf: LooselyCoupledEKF, axis_models, rate: float) -> dict:
    """Model hot-swap that keeps what the filter has learned (SPEC §8 hot-swap, refined for online use).

    Per axis, an augmented state of the old model is carried over 1:1 (estimate, variance and all
    cross-covariances) when it has a counterpart in the new model: for a refit of the same structure every
    AR1/DR state by position (the parameters change, the states keep their meaning); otherwise an AR1 of
    the new model whose φ equals an old one's (e.g. the floor's slow Gauss–Markov bias, present in the plain
    default and in every floored GMWM model). All other old states are summed into the new bias state
    (h·x̂ with the exact linear map of their covariance), and the remaining new AR1/DR states start at 0
    with their stationary variance / the configured σ, as :meth:`LooselyCoupledEKF.swap_model` does.
    Without this, every refit would reset the Gauss–Markov states to their stationary variance at every
    stop, i.e. forget the bias knowledge right before the drive continues. Returns counts of kept/reset states.
    """
    from imunoise.nav.ekf import ModelLayout, _initial_P, normalize_axis_models

    ekf._flush()
    new = ModelLayout.build(normalize_axis_models(axis_models, rate), ekf.dt_nom)
    old = ekf.layout
    T = np.zeros((9 + new.nm, 9 + old.nm))
    T[0:9, 0:9] = np.eye(9)
    fresh: list[int] = []
    kept = 0
    phi_old = np.diag(old.phi_pow[1])
    phi_new = np.diag(new.phi_pow[1])
    for a in range(6):
        io, inew = old.index(a), new.index(a)
        so = [int(x) for x in io if old.kind[x] != 0]
        sn = [int(x) for x in inew if new.kind[x] != 0]
        pairs: dict[int, int] = {}
        if [old.kind[x] for x in so] == [new.kind[x] for x in sn]:
            pairs = dict(zip(sn, so))
        else:
            used: set[int] = set()
            for x in sn:
                if new.kind[x] != 1:
                    continue
                for y in so:
                    if y not in used and old.kind[y] == 1 and abs(phi_new[x] - phi_old[y]) <= 1e-12:
                        pairs[x] = y
                        used.add(y)
                        break
        b_new = int(inew[0])
        paired_old = set(pairs.values())
        for y in io:
            if int(y) not in paired_old:
                T[9 + b_new, 9 + int(y)] = old.hvec[y]
        for x, y in pairs.items():
            T[9 + x, 9 + y] = 1.0
        kept += len(pairs)
        fresh += [x for x in sn if x not in pairs]
    x_old = np.concatenate([np.zeros(9), ekf.xm])
    P_new = T @ ekf.P @ T.T
    P_init = _initial_P(ekf.config, new)
    for x in fresh:
        P_new[9 + x, :] = 0.0
        P_new[:, 9 + x] = 0.0
        P_new[9 + x, 9 + x] = P_init[9 + x, 9 + x]
    ekf.xm = (T @ x_old)[9:]
    ekf.P = 0.5 * (P_new + P_new.T)
    ekf.layout = new
    return {"kept": kept, "reset": len(fresh)}


# --------------------------------------------------------------------------------------------------
# navigator
# --------------------------------------------------------------------------------------------------
class OnlineNavigator:
    """Online GMWM INS/GNSS navigator (SPEC §9). See the module docstring.

    ``init``: initial state at ``init.t`` (samples at or before it only feed the detector and the
    modeller). ``initial_models``: the filter's models until the first identification (default: the
    plain default, ``EkfConfig.fallback``), e.g. an AV or EM model for the baselines with
    ``modelling=False``. ``imu_rate_hz``: nominal IMU rate. ``job_cache``: a dict shared by replays of
    the *same IMU record* (e.g. the per-window outage runs of an experiment): a modelling job on the same
    static segments with the same settings is computed once, and its measured compute time is reused so
    the model takes effect at the same time in every replay (inline worker only).
    """

    def __init__(self, config: OnlineConfig, init: InitialState, *, imu_rate_hz: float = 100.0,
                 initial_models=None, job_cache: dict | None = None):
        if not (math.isfinite(imu_rate_hz) and imu_rate_hz > 0):
            raise DataError(f"imu_rate_hz must be a positive rate in Hz, got {imu_rate_hz!r}")
        self.config = config
        self.rate = float(imu_rate_hz)
        self.dt_nom = 1.0 / self.rate
        self.init = init
        models = initial_models if initial_models is not None else default_axis_models(self.rate,
                                                                                        config.ekf.fallback)
        self.ekf = LooselyCoupledEKF(config.ekf, models, init, imu_rate_hz=self.rate)
        self._floor = [m for m, _ in default_axis_models(self.rate, config.ekf.fallback)]
        self._started = False  # first sample after init.t seen
        self._t_last = -math.inf  # time of the last sample the filter/detector processed
        self._t_in = -math.inf  # time of the last sample pushed (held while λ0 is learned)
        self._n = 0
        self.detector: StaticDetector | None = None
        self.lambda0: float | None = None
        self._stop_start_n = -1
        self._zupt_rejected = False
        if config.detector is not None:
            self._make_detector(config.detector)
        self._learn: list[np.ndarray] = []
        self._learn_t0: float | None = None
        self._pending_samples: list[tuple[float, np.ndarray, np.ndarray]] = []
        self._rows: list[np.ndarray] = []  # raw samples (rates) kept for the segments
        self._raw_t0 = 0  # absolute index of _rows[0]
        self._gnss: list[tuple[float, np.ndarray, np.ndarray]] = []
        self._acc = [WVAccumulator(freq=self.rate) for _ in range(6)]
        self.static_s = 0.0
        self.segments: list[StaticSegment] = []
        self.fits: list[GMWMFit | None] = [None] * 6
        self.updates: list[ModelUpdate] = []
        self._scheduled: list[tuple[float, ModelUpdate]] = []
        self._executor: ThreadPoolExecutor | None = None
        self._future: Future | None = None
        self._future_meta: tuple[str, float, float] | None = None
        self._dirty = False  # new static data arrived while a thread job runs
        self.events: list[dict] = []
        self._gate = False
        self._static_run = 0
        self._store = _Store() if config.store else None
        self._static_raw: list[bool] = []
        self._sample_t: list[float] = []
        self._gate_log: list[bool] = []
        self._elapsed = 0.0
        self.current_models = models
        self._job_cache = job_cache
        self._ekf_models_log: list[tuple[float, list[str]]] = []
        self._event("start", init.t, lambda0=self.lambda0, config=_config_summary(config))

    # -- helpers ----------------------------------------------------------------------------------
    def _event(self, event: str, t: float, **kw: Any) -> None:
        e = {"t": float(t), "event": event}
        e.update(kw)
        self.events.append(e)

    def _make_detector(self, cfg: DetectorConfig) -> None:
        self.detector = StaticDetector(cfg, self.rate)
        self.lambda0 = float(cfg.lambda0)
        self._stop_start_n = int(math.ceil((cfg.min_duration_s + 2 * cfg.margin_s) * self.rate)) + 1

    # -- streaming API ----------------------------------------------------------------------------
    def push_gnss(self, t: float, llh: np.ndarray, sigma_ned: np.ndarray) -> None:
        """A GNSS antenna fix (lat, lon rad, h m) with 1σ NED (m). Applied after the first IMU sample with
        time ≥ t (immediately, referred back with the velocity, if that sample was already pushed)."""
        t = float(t)
        fix = (t, np.asarray(llh, dtype=float).copy(), np.asarray(sigma_ned, dtype=float).copy())
        if t <= self._t_last:
            if self._started and t > self.init.t:
                self.ekf.update_gnss(*fix)
            return
        self._gnss.append(fix)

    def push_imu(self, t: float, dtheta: np.ndarray, dv: np.ndarray) -> None:
        """One IMU increment (Δθ rad, Δv m/s over (t_prev, t], body FRD)."""
        t0 = time.perf_counter()
        t = float(t)
        if not t > self._t_in:
            raise DataError(f"push_imu: time {t!r} does not follow {self._t_in!r}; stamps must increase")
        dth = np.asarray(dtheta, dtype=float)
        dvv = np.asarray(dv, dtype=float)
        dt = t - self._t_in if math.isfinite(self._t_in) else self.dt_nom
        self._t_in = t
        gyro, accel = dth / dt, dvv / dt
        if self.detector is None:
            self._learn_push(t, dth, dvv, gyro, accel)
        else:
            segs = self.detector.push(t, accel, gyro)
            self._sample(t, dth, dvv, gyro, accel, self.detector.is_static, self.detector.gate_open, segs)
        self._elapsed += time.perf_counter() - t0

    def solution(self) -> dict:
        """Current filter solution (IMU point): see :meth:`LooselyCoupledEKF.state`."""
        return self.ekf.state()

    def finish(self) -> OnlineResult:
        """Close the stream: flush samples held for λ_0 learning, wait for a running thread job, and
        return the result."""
        t0 = time.perf_counter()
        if self.detector is None and self._pending_samples:
            self._learn_finish()
        if self._future is not None:
            self._future.result()
            self._collect_thread(self._t_last)
        if self._executor is not None:
            self._executor.shutdown(wait=True)
        if self.detector is not None:
            self.detector.finish()
        self._elapsed += time.perf_counter() - t0
        self._event("end", self._t_last, static_s=self.static_s, n_updates=len(self.updates))
        return self._result()

    # -- batch ------------------------------------------------------------------------------------
    def run(self, imu, gnss, *, progress: Any = None) -> OnlineResult:
        """Replay a whole record (ImuData increments, GnssData); same result as pushing every sample and
        fix in time order through the streaming API. ``progress(n_done, n_total)`` is called now and then."""
        t0 = time.perf_counter()
        t = np.asarray(imu.t, dtype=float)
        dth_all, dv_all = imu.increments() if hasattr(imu, "increments") else (imu.dtheta, imu.dv)
        if t.size < 2:
            raise DataError("the IMU record needs at least 2 samples")
        if np.any(np.diff(t) <= 0):
            k = int(np.flatnonzero(np.diff(t) <= 0)[0]) + 1
            raise DataError(f"IMU time stamps must increase strictly (sample {k}: {t[k]!r} after {t[k - 1]!r})")
        dt = np.diff(t, prepend=t[0] - self.dt_nom)
        gyro = dth_all / dt[:, None]
        accel = dv_all / dt[:, None]
        gt = np.asarray(gnss.t, dtype=float)
        order = np.argsort(gt, kind="stable")
        gt, gllh, gsig = gt[order], np.asarray(gnss.llh)[order], np.asarray(gnss.sigma_ned)[order]
        if self.detector is None:
            lam_mask = t < t[0] + self.config.learn_lambda0_s
            self._learn_from(accel[lam_mask], t[0])
        det = self.detector.push_chunk(t, accel, gyro)
        raw = det.static_raw
        # completion index of each segment: the first non-static sample after its run
        done_at: dict[int, list[StaticSegment]] = {}
        for s in det.segments:
            rest = np.flatnonzero(~raw[s.i1:])
            k = s.i1 + int(rest[0]) if rest.size else t.size
            done_at.setdefault(k, []).append(s)
        self._elapsed += time.perf_counter() - t0
        gi = 0
        n = t.size
        every = max(n // 100, 1)
        for k in range(n):
            tk = t[k]
            t1 = time.perf_counter()
            while gi < gt.size and gt[gi] <= tk:
                self.push_gnss(gt[gi], gllh[gi], gsig[gi])
                gi += 1
            self._sample(tk, dth_all[k], dv_all[k], gyro[k], accel[k], bool(raw[k]), bool(det.gate_open[k]),
                         done_at.get(k, []))
            self._elapsed += time.perf_counter() - t1
            if progress is not None and k % every == 0:
                progress(k, n)
        while gi < gt.size:
            self.push_gnss(gt[gi], gllh[gi], gsig[gi])
            gi += 1
        if progress is not None:
            progress(n, n)
        # the detector state was advanced by push_chunk; close a run still open as the stream would
        return self.finish()

    # -- λ0 learning --------------------------------------------------------------------------------
    def _learn_push(self, t, dth, dvv, gyro, accel) -> None:
        if self._learn_t0 is None:
            self._learn_t0 = t
        if t < self._learn_t0 + self.config.learn_lambda0_s:
            self._pending_samples.append((t, dth, dvv, gyro, accel))
            return
        self._learn_finish()
        self._after_learning(t, dth, dvv, gyro, accel)

    def _after_learning(self, t, dth, dvv, gyro, accel) -> None:
        segs = self.detector.push(t, accel, gyro)
        self._sample(t, dth, dvv, gyro, accel, self.detector.is_static, self.detector.gate_open, segs)

    def _learn_finish(self) -> None:
        held = self._pending_samples
        self._pending_samples = []
        acc = np.array([s[4] for s in held]) if held else np.zeros((0, 3))
        self._learn_from(acc, self._learn_t0 if self._learn_t0 is not None else 0.0)
        for s in held:
            self._after_learning(*s)

    def _learn_from(self, accel_static: np.ndarray, t0: float) -> None:
        base = DetectorConfig()
        try:
            lam = learn_lambda0(accel_static, window=base.window)
            src = f"learned from the first {self.config.learn_lambda0_s:g} s"
        except ImunoiseError as exc:
            lam = base.lambda0
            src = f"default (could not learn: {exc})"
        self._make_detector(replace(base, lambda0=lam))
        self._event("lambda0", t0, lambda0=lam, source=src)

    # -- one sample -----------------------------------------------------------------------------------
    def _sample(self, t, dth, dvv, gyro, accel, is_static: bool, gate_open: bool, segs) -> None:
        cfg = self.config
        self._rows.append(np.concatenate([gyro, accel]))
        self._static_raw.append(is_static)
        self._sample_t.append(t)
        self._t_last = t
        self._n += 1
        self._static_run = self._static_run + 1 if is_static else 0
        if not is_static:
            self._zupt_rejected = False
        if self._static_run == self._stop_start_n and self.detector is not None:
            # the raw static run is now long enough to become a segment: a stop has started
            self._event("stop_start", t, t0=self._sample_t[-self._static_run])
        gate = bool(gate_open) and cfg.gate
        if gate != self._gate:
            self._gate = gate
            self._event("gate_open" if gate else "gate_closed", t)
        self._gate_log.append(gate)
        if t > self.init.t:
            if not self._started:
                self._started = True
                # previous increment for the coning/sculling terms, as run_ekf does
                self.ekf.nav[I_DTH:I_DTH + 3] = dth
                self.ekf.nav[I_DTH + 3:I_DTH + 6] = dvv
                self.ekf.nav[NAV_LEN - 1] = 1.0
            self.ekf.set_gate(gate)
            self.ekf.propagate(dth, dvv, t)
            while self._gnss and self._gnss[0][0] <= t:
                fix = self._gnss.pop(0)
                if fix[0] > self.init.t:
                    self.ekf.update_gnss(*fix)
            if cfg.zupt and self._static_run >= cfg.zupt_after and self._static_run % cfg.zupt_every == 0 \
                    and not gate and math.hypot(self.ekf.nav[3], self.ekf.nav[4]) < cfg.zupt_max_speed:
                if self._zupt_consistent(cfg.zupt_sigma_v):
                    self.ekf.zupt_update(cfg.zupt_sigma_v)
                    self.ekf.zaru_update(self._zaru_sigma())
                elif not self._zupt_rejected:
                    self._zupt_rejected = True
                    self._event("zupt_rejected", t, speed_mps=float(np.linalg.norm(self.ekf.nav[3:6])))
        else:
            while self._gnss and self._gnss[0][0] <= t:
                self._gnss.pop(0)
        for s in segs:
            self._segment(s, t)
        self._poll(t)
        if self._store is not None and self._started:
            L = self.ekf.layout
            e = _sensor_errors(self.ekf.xm, L.hvec, L.axis_of)
            row = np.empty(_Store.COLS)
            row[0] = t
            row[1:7] = self.ekf.nav[0:6]
            row[7:11] = self.ekf.nav[I_Q:I_Q + 4]
            row[11:17] = e
            row[17:26] = np.sqrt(np.abs(np.diag(self.ekf.P)[:9]))
            self._store.add(row)
        # raw samples are needed only back to the start of a possible segment
        if not is_static and len(self._rows) > 4096:
            drop = len(self._rows) - 16
            del self._rows[:drop]
            self._raw_t0 += drop

    def _zupt_consistent(self, sigma_v: float) -> bool:
        """χ² test of the zero-velocity pseudo-measurement, NIS = vᵀ(P_vv + σ²I)⁻¹v ≤ ``zupt_chi2`` (3 dof):
        a detector false positive on a moving car (a noisy IMU's learned λ0 lets smooth cruising pass
        Eq. 9) would otherwise be forced into the filter."""
        if not self.config.zupt_chi2 > 0:
            return True
        self.ekf._flush()
        v = self.ekf.nav[3:6]
        S = self.ekf.P[3:6, 3:6] + sigma_v**2 * np.eye(3)
        try:
            nis = float(v @ np.linalg.solve(S, v))
        except np.linalg.LinAlgError:
            return False
        return math.isfinite(nis) and nis <= self.config.zupt_chi2

    def _zaru_sigma(self) -> float:
        """σ of one ZARU sample: the larger of the configured σ, the current gyro model's per-sample white σ
        and the gyro scatter measured over this stop so far (the update uses a single increment, whose noise
        on a vibrating car is the vibration, not the datasheet's)."""
        s = self.config.zaru_sigma_w
        for m, _ in self.current_models[:3]:
            s = max(s, math.sqrt(m.white_variance()))
        n = min(self._static_run, 200, len(self._rows))
        if n >= 10:
            g = np.array(self._rows[-n:])[:, :3]
            s = max(s, float(np.max(np.std(g, axis=0))))
        return s

    # -- modelling ------------------------------------------------------------------------------------
    def _segment(self, seg: StaticSegment, t_now: float) -> None:
        a, b = seg.i0 - self._raw_t0, seg.i1 - self._raw_t0
        if a < 0:
            log.warning("static segment %.2f–%.2f s starts before the kept raw data; skipped", seg.t0, seg.t1)
            return
        data = np.array(self._rows[a:b])
        ok = np.all(np.isfinite(data), axis=1)
        # a non-finite sample splits the segment (no wavelet coefficient may span it)
        edges = np.flatnonzero(np.diff(np.concatenate([[0], ok.astype(np.int8), [0]])))
        pieces = [data[p:q] for p, q in zip(edges[::2], edges[1::2]) if q - p >= 16]
        if not ok.all():
            self._event("rejected", t_now, reason=f"{int((~ok).sum())} non-finite samples in the stop "
                        f"{seg.t0:.2f}–{seg.t1:.2f} s; used the {len(pieces)} finite pieces")
        for piece in pieces:
            piece = piece - piece.mean(axis=0)  # bias removal (SPEC §7)
            for ax in range(6):
                self._acc[ax].add(piece[:, ax])
        self.static_s += seg.duration
        self.segments.append(seg)
        self._event("stop_end", t_now, t0=seg.t0, t1=seg.t1, duration_s=seg.duration, static_total_s=self.static_s)
        if not self.config.modelling:
            return
        if self.static_s < self.config.min_static_s:
            self._event("waiting", t_now, static_total_s=self.static_s, need_s=self.config.min_static_s)
            return
        kind = "identify" if all(f is None for f in self.fits) else "refit"
        if self.config.worker == "thread":
            if self._future is not None:
                self._dirty = True
                return
            self._submit(kind, t_now)
            return
        self._run_inline(kind, t_now)

    def _wvs(self) -> list:
        return [acc.result() for acc in self._acc]

    def _run_inline(self, kind: str, t_now: float) -> None:
        try:
            wvs = self._wvs()
        except ImunoiseError as exc:
            self._event("rejected", t_now, reason=f"wavelet variance: {exc}")
            return
        key = None
        if self._job_cache is not None:
            c = self.config
            key = (kind, tuple((sg.i0, sg.i1) for sg in self.segments), c.criterion, c.complete, c.weights, c.top,
                   tuple(None if f is None else (str(f.model), tuple(f.model.vector)) for f in self.fits))
        out = self._job_cache.get(key) if key is not None else None
        if out is None:
            out = _model_job(kind, wvs, self.fits, self.config, self.rate)
            if key is not None:
                self._job_cache[key] = out
        delay = self.config.latency if self.config.latency is not None else float(sum(out["elapsed"]))
        self._accept(kind, t_now, out, t_now + delay)

    def _submit(self, kind: str, t_now: float) -> None:
        try:
            wvs = self._wvs()
        except ImunoiseError as exc:
            self._event("rejected", t_now, reason=f"wavelet variance: {exc}")
            return
        if self._executor is None:
            self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="imunoise-gmwm")
        self._future = self._executor.submit(_model_job, kind, wvs, list(self.fits), self.config, self.rate)
        self._future_meta = (kind, t_now, self.static_s)
        self._dirty = False

    def _collect_thread(self, t_now: float) -> None:
        fut, (kind, t_stop, _) = self._future, self._future_meta
        self._future = None
        try:
            out = fut.result()
        except Exception as exc:  # noqa: BLE001 - a worker failure must never stop the filter
            self._event("rejected", t_now, reason=f"worker failed: {type(exc).__name__}: {exc}")
            return
        self._accept(kind, t_stop, out, t_now)
        if self._dirty:
            self._submit("refit" if any(f is not None for f in self.fits) else "identify", t_now)

    def _accept(self, kind: str, t_stop: float, out: dict, t_effect: float) -> None:
        fits = out["fits"]
        for a, reason in enumerate(out["rejected"]):
            if reason:
                self._event("rejected", t_stop, axis=AXES[a], job=kind, reason=reason)
                log.info("%s fit of %s rejected: %s", kind, AXES[a], reason)
        ok = any(f is not None for f in fits)
        upd = ModelUpdate(kind, t_stop, t_effect if ok else None, self.static_s, fits, out["elapsed"],
                          out["rankings"], out["rejected"])
        self.updates.append(upd)
        per_axis = {
            AXES[a]: {"structure": str(f.model), "gof": f.objective, "time_s": out["elapsed"][a],
                      "wvic": f.extra.get("wvic")}
            for a, f in enumerate(fits) if f is not None
        }
        self._event("identified" if kind == "identify" else "refit", t_stop, static_total_s=self.static_s,
                    axes=per_axis, elapsed_s=float(sum(out["elapsed"])), t_effect=upd.t_effect)
        if ok:
            for a, f in enumerate(fits):
                if f is not None:
                    self.fits[a] = f
            self._scheduled.append((upd.t_effect, upd))
            self._scheduled.sort(key=lambda x: x[0])

    def _poll(self, t: float) -> None:
        if self._future is not None and self._future.done():
            self._collect_thread(t)
        while self._scheduled and self._scheduled[0][0] <= t:
            _, upd = self._scheduled.pop(0)
            self._swap(t, upd)

    def filter_models(self) -> list[tuple[Model, float]]:
        """The six (model, freq) the filter gets from the current fits (plain default where none)."""
        out = []
        for a in range(6):
            f = self.fits[a]
            floor = self._floor[a] if self.config.floor == "default" else None
            if f is None:
                out.append((self._floor[a], self.rate))
            else:
                out.append((ekf_axis_model(f.model, f.freq, floor, fold_tau_s=self.config.fold_tau_s,
                                           dr=self.config.dr, horizon=data_horizon(f), qn=self.config.qn),
                            self.rate))
        return out

    def _swap(self, t: float, upd: ModelUpdate) -> None:
        models = self.filter_models()
        if self.config.swap == "preserve":
            counts = swap_preserving(self.ekf, models, self.rate)
        else:
            self.ekf.swap_model(models)
            counts = {}
        self.current_models = models
        self._ekf_models_log.append((t, [str(m) for m, _ in models]))
        self._event("swap", t, job=upd.kind, t_stop=upd.t_stop, filter_models=[str(m) for m, _ in models],
                    **counts)

    # -- result ---------------------------------------------------------------------------------------
    def _result(self) -> OnlineResult:
        if self._store is not None and self._store.n:
            t, pos, vel, eul, eg, ea, std = self._store.arrays()
        else:
            z = np.zeros((0, 3))
            t, pos, vel, eul, eg, ea, std = np.zeros(0), z, z, z, z, z, np.zeros((0, 9))
        return OnlineResult(
            t=t, llh=pos, vel_ned=vel, euler=eul, gyro_error=eg, accel_error=ea, std=std,
            events=self.events, updates=self.updates, segments=list(self.segments),
            gate_open=np.array(self._gate_log, dtype=bool), static_raw=np.array(self._static_raw, dtype=bool),
            lambda0=float(self.lambda0) if self.lambda0 is not None else float("nan"),
            elapsed_s=self._elapsed, final_models=list(self.current_models), fits=list(self.fits),
            sample_t=np.array(self._sample_t),
        )


def _config_summary(c: OnlineConfig) -> dict:
    return {
        "min_static_s": c.min_static_s, "complete": c.complete, "criterion": c.criterion, "latency": c.latency,
        "worker": c.worker, "gate": c.gate, "zupt": c.zupt, "floor": c.floor, "fold_tau_s": c.fold_tau_s,
        "modelling": c.modelling,
    }


def run_online(imu, gnss, init: InitialState, config: OnlineConfig | None = None, *, initial_models=None,
               progress: Any = None) -> OnlineResult:
    """Batch convenience: ``OnlineNavigator(config, init).run(imu, gnss)``."""
    config = config or OnlineConfig()
    nav = OnlineNavigator(config, init, imu_rate_hz=float(imu.rate_hz), initial_models=initial_models)
    return nav.run(imu, gnss, progress=progress)
