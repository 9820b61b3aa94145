"""In-motion gyro noise learned while driving, by rehearsing GNSS outages on data already seen (``gmwm_dyn``).

Why. Stops show the sensor at rest: the white-noise level and little slower (the stops of a city drive last
seconds). While the car drives, vibration, temperature and g-sensitivity make the gyro biases wander far more
(the shared drive: std of 10 s means of the estimated gyro errors 58 / 144 / 123 °/h for x/y/z against a static
ADEV at 10 s of 64 / 37 / 6 °/h), and the outage drift depends on how the filter models that wander. On the
simulator with the motion law calibrated on that drive, the oracle's gain over the plain filter comes from the
gyro models (development seeds 1000–1003: true moving gyro models 0.69× the plain drift, true accelerometer
models 0.99×); on seeds 1000–1011 the true static models give 0.79×, the true moving ones 0.73×.

What is learned. Per gyro axis j an in-motion Gauss–Markov process added to the model of that axis (the static
model from the stops keeps the fast part and everything it identified):

    b_k+1 = φ b_k + √(1 − φ²) σ_j w_k,    φ = exp(−Δt / T_c,j),

(σ_j, T_c,j) one of the candidates of :class:`MotionNoiseConfig` or nothing (σ = 0, the start). A long T_c with
a large σ is, over an outage, a rate random walk of K ≈ σ·√(2/T_c); a short one a bias instability that
decorrelates within seconds.

How (shadow filters and rehearsed outages). From the first moment the car moves GNSS-aided, shadow copies of
the filter run beside the live filter on the same IMU samples and fixes, a few seconds behind (the batch
kernel, :meth:`~imunoise.nav.ekf.LooselyCoupledEKF.rehearse`): one with nothing added, and one per candidate on
one axis (``search="axis"``, the default: 3 axes × σ × T_c shadows; ``"shared"``: the same candidate on the
three axes). Every ``every_s`` seconds each shadow rehearses an outage: a copy of it runs ``outage_s`` seconds
on without GNSS, and its score is log of the RMS horizontal distance between its antenna position and all the
fixes of that span (one fix's 1.8 m noise would swamp the difference between candidates): the drift the
candidate would have had, measured against the GNSS the filter had anyway. Each shadow has run with its own
model since it started, so a rehearsal sees the candidate's steady state (a copy of the live filter switched
to a candidate for half a minute does not: its bias estimate is still the live model's, and on development
seeds that preferred far too much noise).

Decision. Every round, per axis, the live filter takes the candidate with the lowest mean paired score against
the shadow with nothing added, once ``min_pairs`` rounds exist and if that paired difference is below
−``margin`` with a paired t statistic below −``min_t`` (else nothing on that axis; the rounds overlap, so t is
a ranking statistic, not a test). Hysteresis: an axis leaves its choice only for a candidate that beats it by
``margin`` too, and falls back to nothing only when its choice has become worse than nothing by ``margin``
(development seed 1011 flipped six times without it). The axes are chosen separately: roll and pitch errors
drift the position across and along the track, a heading error across it, growing with speed, so their effects
on the drift add up to first order; a joint grid of 3 axes × 7 choices would need 343 shadows.
``criterion="nis"`` picks instead the shadow whose GNSS NIS mean is closest to 3 (covariance matching across the
shadows; worse on the development seeds).

Guard. A candidate is refused (event ``motion_noise_rejected``, logged once) when its shadow is inconsistent
with the GNSS it was aided by: the mean NIS of its fixes (3 dof) outside the two-sided 95 % χ² band of their
number and farther from 3 than the shadow with nothing added.

Carried evidence. The in-motion noise is a property of the IMU in its vehicle, so what one drive learned
serves the next: :meth:`MotionNoiseLearner.evidence` returns the current choice and every rehearsal round's
scores (a :class:`MotionNoisePrior`; ``imunoise online`` writes it into ``metrics.json``), and
``MotionNoiseConfig(prior=...)`` starts a learner with them. The live filter then uses the carried choice from
its first sample, and every decision of the new drive is made on the carried rounds and its own together (the
same rule and guard from the new drive's first round on). A drive of a different vehicle or IMU must start
without a prior.

Online. The shadows and rehearsals run in the navigator's worker: ``inline`` computes them when due
(deterministic; the same in :meth:`~imunoise.online.navigator.OnlineNavigator.run` and the push API);
``thread`` runs them in a background thread (the kernel releases the GIL) and the choice takes effect at the
first sample after the thread finished. Events: ``motion_noise`` (σ and T_c per axis, the paired scores, the
NIS means, the number of rounds). The navigator composes the learned part with every static model it swaps
in, and the shadows take the new static model at the same filter time.
"""

from __future__ import annotations

import copy
import json
import math
from collections.abc import Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.stats import chi2

from imunoise.errors import DataError, ModelError
from imunoise.model import Model
from imunoise.nav.earth import radii
from imunoise.nav.solution import antenna_llh
from imunoise.processes import AR1

__all__ = ["MotionNoiseConfig", "MotionNoisePrior", "MotionNoiseLearner", "add_motion_gm", "ned_offset",
           "horizontal_distance"]

_DPH = math.pi / 180.0 / 3600.0  # °/h → rad/s


Spec = tuple[tuple[float, float], tuple[float, float], tuple[float, float]]


@dataclass(frozen=True)
class MotionNoisePrior:
    """What a learner learned on earlier drives of the same IMU in the same vehicle (module docstring).

    ``spec``: the choice per gyro axis, (σ °/h, T_c s), σ = 0 nothing added; ``scores``: per rehearsal round the
    log RMS drift [log m] of every shadow, in the order of ``candidates`` (the shadows' specs, which must be
    the learner's own)."""

    spec: Spec
    scores: tuple[tuple[float, ...], ...]
    candidates: tuple[Spec, ...]

    def __post_init__(self) -> None:
        def as_spec(x: Any) -> tuple[tuple[float, float], ...]:
            return tuple((float(a[0]), float(a[1])) for a in x)

        try:
            spec = as_spec(self.spec)
            cands = tuple(as_spec(c) for c in self.candidates)
            scores = tuple(tuple(float(v) for v in row) for row in self.scores)
        except (TypeError, ValueError, IndexError) as exc:
            spec = cands = ()  # the message below says what is wrong
            bad: BaseException | None = exc
        else:
            bad = None
        if bad is not None or len(spec) != 3 or any(len(c) != 3 for c in cands):
            raise ModelError("a motion-noise prior needs spec = 3 (σ °/h, T_c s) pairs, candidates = a list of "
                             "such specs and scores = rows of one number per candidate") from bad
        if any(len(r) != len(cands) or not all(math.isfinite(v) for v in r) for r in scores):
            raise ModelError(f"motion-noise prior: every score row needs {len(cands)} finite values "
                             "(one per candidate)")
        object.__setattr__(self, "spec", spec)
        object.__setattr__(self, "candidates", cands)
        object.__setattr__(self, "scores", scores)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (``imunoise online`` writes it as ``metrics.json["motion_noise"]["evidence"]``)."""
        return {"spec": [list(a) for a in self.spec], "candidates": [[list(a) for a in c] for c in self.candidates],
                "scores": [list(r) for r in self.scores]}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> MotionNoisePrior:
        """From :meth:`to_dict`, or from a whole ``metrics.json`` of ``imunoise online --learn-motion-noise``."""
        if isinstance(d, dict) and "motion_noise" in d:
            d = d["motion_noise"]
        if isinstance(d, dict) and "evidence" in d:
            d = d["evidence"]
        if not isinstance(d, dict) or not {"spec", "candidates", "scores"} <= set(d):
            raise ModelError("not a motion-noise prior: expected the metrics.json of `imunoise online "
                             "--learn-motion-noise` or a dict with spec, candidates and scores")
        return cls(d["spec"], d["scores"], d["candidates"])

    @classmethod
    def load(cls, path: str | Path) -> MotionNoisePrior:
        """Read a prior from a JSON file (a ``metrics.json`` of ``imunoise online --learn-motion-noise`` or
        :meth:`to_dict` saved)."""
        p = Path(path)
        try:
            d = json.loads(p.read_text())
        except FileNotFoundError as exc:
            raise DataError(f"motion-noise prior {p} does not exist") from exc
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise DataError(f"motion-noise prior {p} is not a readable JSON file: {exc}") from exc
        return cls.from_dict(d)


@dataclass(frozen=True)
class MotionNoiseConfig:
    """Settings of the in-motion noise learner (module docstring).

    ``sigma_dph``: candidate σ of the added Gauss–Markov process [°/h] (nothing added is always a candidate, the
    start); ``tc_s``: candidate correlation times [s]; ``search``: ``"axis"`` (each gyro axis chosen
    separately) or ``"shared"`` (one choice for the three); ``criterion``: ``"drift"`` (rehearsed outages) or
    ``"nis"`` (shadow NIS closest to 3); ``outage_s``: length of a
    rehearsed outage [s]; ``every_s``: one rehearsal per shadow every this many seconds; ``min_speed_mps``:
    rehearse only while the filter's horizontal speed exceeds this; ``min_pairs``: rehearsals a move needs;
    ``margin``: paired mean log-score a move must beat (0.02 ≈ 2 % less drift); ``min_t``: and its paired t
    statistic must be below −``min_t``; ``guard``: the NIS guard; ``prior``: the evidence of earlier drives of
    the same IMU in the same vehicle (:class:`MotionNoisePrior`), or None."""

    sigma_dph: tuple[float, ...] = (30.0, 100.0, 300.0)
    tc_s: tuple[float, ...] = (3.0, 30.0)
    outage_s: float = 30.0
    every_s: float = 10.0
    min_speed_mps: float = 2.0
    min_pairs: int = 10
    margin: float = 0.02
    min_t: float = 1.5
    guard: bool = True
    criterion: str = "drift"
    search: str = "axis"
    prior: MotionNoisePrior | None = None

    def __post_init__(self) -> None:
        sg = tuple(float(x) for x in self.sigma_dph)
        tc = tuple(float(x) for x in self.tc_s)
        if not sg or any(not (x > 0 and math.isfinite(x)) for x in sg):
            raise ModelError(f"MotionNoiseConfig.sigma_dph needs values > 0 °/h, got {self.sigma_dph!r}")
        if not tc or any(not (x > 0 and math.isfinite(x)) for x in tc):
            raise ModelError(f"MotionNoiseConfig.tc_s needs correlation times > 0 s, got {self.tc_s!r}")
        object.__setattr__(self, "sigma_dph", sg)
        object.__setattr__(self, "tc_s", tc)
        if self.search not in ("axis", "shared") or self.criterion not in ("drift", "nis"):
            raise ModelError(f"MotionNoiseConfig: search must be 'axis' or 'shared' and criterion 'drift' or 'nis', "
                             f"got {self.search!r}, {self.criterion!r}")
        if not (self.outage_s > 0 and self.every_s > 0 and self.min_pairs >= 1 and self.margin >= 0
                and self.min_t >= 0 and self.min_speed_mps >= 0):
            raise ModelError("MotionNoiseConfig: outage_s, every_s > 0 s; min_pairs ≥ 1; margin, min_t, "
                             "min_speed_mps ≥ 0")
        if self.prior is not None:
            if not isinstance(self.prior, MotionNoisePrior):
                raise ModelError(f"MotionNoiseConfig.prior must be a MotionNoisePrior, got {type(self.prior).__name__}")
            if list(self.prior.candidates) != self.candidates:
                raise ModelError("the motion-noise prior was learned with other candidates (sigma_dph, tc_s, search) "
                                 "than this learner's; learn it again with these settings or start without it")
            if self.prior.spec not in [tuple(c) for c in self._choices()]:
                raise ModelError(f"the motion-noise prior's choice {self.prior.spec} is not a combination of this "
                                 "learner's candidates")

    def _choices(self) -> list[Spec]:
        """Every spec the learner can end in: per axis nothing or a candidate (``"axis"``), or one candidate
        for the three (``"shared"``)."""
        none = (0.0, self.tc_s[0])
        per = [none] + [(sg, tc) for sg in self.sigma_dph for tc in self.tc_s]
        if self.search == "shared":
            return [(a, a, a) for a in per]
        return [(a, b, c) for a in per for b in per for c in per]

    @property
    def candidates(self) -> list[tuple[tuple[float, float], ...]]:
        """The shadows' models: per gyro axis (σ °/h, T_c s), the first one nothing added. ``search="axis"``:
        one axis at a time (the axes are chosen separately); ``"shared"``: the same on the three axes."""
        none = (0.0, self.tc_s[0])
        out = [(none, none, none)]
        for sg in self.sigma_dph:
            for tc in self.tc_s:
                if self.search == "shared":
                    out.append(((sg, tc),) * 3)
        if self.search == "axis":
            for j in range(3):
                for sg in self.sigma_dph:
                    for tc in self.tc_s:
                        spec = [none, none, none]
                        spec[j] = (sg, tc)
                        out.append(tuple(spec))
        return out


def add_motion_gm(models: Sequence[Any], spec: Sequence[tuple[float, float]], rate_hz: float) -> list:
    """The six (model, freq) pairs with a Gauss–Markov process of σ ``spec[j][0]`` [°/h] and correlation time
    ``spec[j][1]`` [s] added to gyro axis j (module docstring; σ = 0 adds nothing); accelerometer axes
    unchanged."""
    out = []
    for a, mm in enumerate(models):
        m, fr = mm if isinstance(mm, tuple) else (mm, rate_hz)
        if a < 3 and spec[a][0] > 0:
            sg, tc_s = spec[a]
            phi = math.exp(-1.0 / (tc_s * fr))
            m = Model([*m.components, AR1(phi=phi, sigma2=(sg * _DPH) ** 2 * (1.0 - phi * phi))])
        out.append((m, fr))
    return out


def ned_offset(llh_a: np.ndarray, llh_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """North and east offsets [m] of rows of ``llh_a`` from ``llh_b`` ((n, 3) lat/lon rad, h m; local flat
    Earth)."""
    a = np.atleast_2d(llh_a)
    b = np.atleast_2d(llh_b)
    rm, rn = radii(b[:, 0])
    return (a[:, 0] - b[:, 0]) * (rm + b[:, 2]), (a[:, 1] - b[:, 1]) * (rn + b[:, 2]) * np.cos(b[:, 0])


def horizontal_distance(llh_a: np.ndarray, llh_b: np.ndarray) -> np.ndarray:
    """Horizontal distance [m] between rows of two (n, 3) lat/lon [rad]/h [m] arrays (local flat Earth)."""
    dn, de = ned_offset(llh_a, llh_b)
    return np.hypot(dn, de)


class MotionNoiseLearner:
    """The learner the navigator owns when ``OnlineConfig.motion_noise`` is set (module docstring).

    The navigator calls :meth:`observe` after every filter step with the sample and the fixes it applied,
    :meth:`static_changed` when it swaps in a new static model, :meth:`compose` to build the filter's model,
    and :meth:`poll`/:meth:`close` for a thread job.

    Attributes
    ----------
    spec : tuple
        Current (σ °/h, T_c s) per gyro axis (σ = 0: nothing added).
    history : list of dict
        One entry per decision (accepted or refused by the guard).
    n_rehearsals : int
        Rehearsal rounds so far (one per ``every_s`` while moving, every shadow rehearsed).
    """

    def __init__(self, config: MotionNoiseConfig, rate_hz: float, lever: np.ndarray, *, worker: str = "inline"):
        self.config = config
        self.cands = config.candidates
        self.rate = float(rate_hz)
        self.lever = np.asarray(lever, dtype=float)
        self.worker = worker
        self.spec = self.cands[0] if config.prior is None else config.prior.spec
        self.n_prior = 0 if config.prior is None else len(config.prior.scores)  # rounds carried from earlier drives
        self.t_start: float | None = None  # filter time the shadows started (the first aided moving step)
        self.n_starts = 0  # starts of the shadows (a restart after every stretch without GNSS)
        self.history: list[dict] = []
        self.n_rehearsals = 0
        # per rehearsal round: log RMS drift per candidate (the carried rounds first)
        self.scores: list[np.ndarray] = ([] if config.prior is None else
                                         [np.array(r, dtype=float) for r in config.prior.scores])
        self._nis = np.zeros((len(self.cands), 2))  # per shadow: sum of NIS, number of fixes
        self._shadows: list[Any] | None = None
        self._stale = False  # a round found no GNSS: the shadows wait for the next aided moving step
        self._t_sh = math.nan  # time of the shadows
        self._static: list[tuple[float, list]] = []  # (t, static models) not yet given to the shadows
        n0 = 4096
        self._t = np.empty(n0)
        self._dth = np.empty((n0, 3))
        self._dv = np.empty((n0, 3))
        self._n = 0
        self._fixes: list[tuple[float, np.ndarray, np.ndarray]] = []
        self._executor: ThreadPoolExecutor | None = None
        self._future: Future | None = None

    # -- the model ----------------------------------------------------------------------------------
    @property
    def sigma_dph(self) -> list[float]:
        """σ [°/h] of the added process per gyro axis (0: none)."""
        return [a[0] for a in self.spec]

    @property
    def tc(self) -> list[float]:
        """T_c [s] per gyro axis."""
        return [a[1] for a in self.spec]

    def evidence(self) -> MotionNoisePrior:
        """The current choice and every rehearsal round's scores (the carried ones included): the prior of the
        next drive of the same IMU in the same vehicle (module docstring)."""
        return MotionNoisePrior(self.spec, tuple(tuple(float(v) for v in r) for r in self.scores), tuple(self.cands))

    def compose(self, static_models: Sequence[Any], spec: Sequence[tuple[float, float]] | None = None) -> list:
        """``static_models`` with the in-motion part ``spec`` (default the current one)."""
        return add_motion_gm(static_models, self.spec if spec is None else spec, self.rate)

    def static_changed(self, t: float, static_models: Sequence[Any]) -> None:
        """The navigator swapped in a new static model at filter time ``t``: the shadows take it at ``t``."""
        if self._shadows is not None:
            self._static.append((float(t), list(static_models)))

    # -- data ---------------------------------------------------------------------------------------
    def _keep(self, t: float, dth: np.ndarray, dv: np.ndarray) -> None:
        if self._n == self._t.size:
            # drop what the shadows have passed before growing
            keep_from = self._t_sh if math.isfinite(self._t_sh) else t
            i = max(int(np.searchsorted(self._t[: self._n], keep_from, side="left")), 0)
            if i > 0:
                k = self._n - i
                self._t[:k], self._dth[:k], self._dv[:k] = self._t[i:self._n], self._dth[i:self._n], self._dv[i:self._n]
                self._n = k
            if self._n == self._t.size:
                self._t = np.concatenate([self._t, np.empty_like(self._t)])
                self._dth = np.concatenate([self._dth, np.empty_like(self._dth)])
                self._dv = np.concatenate([self._dv, np.empty_like(self._dv)])
        self._t[self._n], self._dth[self._n], self._dv[self._n] = t, dth, dv
        self._n += 1

    def waiting(self) -> bool:
        """The shadows wait to (re)start at the next aided moving step: every sample with a fix is an event."""
        return self._shadows is None or self._stale

    def next_round_t(self) -> float:
        """Filter time from which the next rehearsal round is due (the shadows running; inline worker)."""
        return self._t_sh + max(self.config.every_s, self.config.outage_s)

    def observe_span(self, t: np.ndarray, dth: np.ndarray, dv: np.ndarray, fixes: Sequence[tuple]) -> None:
        """:meth:`observe` over samples ``t`` (n,) none of which starts the shadows or runs a round (the chunked
        replay stops at those): keep the samples and the fixes the live filter used there."""
        m = t.size
        if self._n + m > self._t.size:
            keep_from = self._t_sh if math.isfinite(self._t_sh) else t[0]
            i = max(int(np.searchsorted(self._t[: self._n], keep_from, side="left")), 0)
            k = self._n - i
            size = self._t.size
            while k + m > size:
                size *= 2
            nt, nth, nv = np.empty(size), np.empty((size, 3)), np.empty((size, 3))
            nt[:k], nth[:k], nv[:k] = self._t[i:self._n], self._dth[i:self._n], self._dv[i:self._n]
            self._t, self._dth, self._dv, self._n = nt, nth, nv, k
        self._t[self._n:self._n + m], self._dth[self._n:self._n + m], self._dv[self._n:self._n + m] = t, dth, dv
        self._n += m
        self._fixes.extend(fixes)

    def observe(self, nav: Any, t: float, dth: np.ndarray, dv: np.ndarray, fixes: Sequence[tuple]) -> None:
        """One filter step of the navigator ``nav`` (after the fixes ``fixes`` were applied at ``t``). Starts
        the shadows at the first aided moving step; runs a rehearsal round when one is due; a decision lands in
        :attr:`history` (the navigator swaps it in)."""
        self._keep(t, dth, dv)
        self._fixes.extend(fixes)
        c = self.config
        if self._shadows is None or self._stale:
            # start (or, after a stretch without GNSS, restart) the shadows from the live filter
            moving = nav.ekf.view.speed_h >= c.min_speed_mps
            if fixes and moving and self._future is None:
                self._start(nav, t)
            return
        if self._future is not None or t < self._t_sh + max(c.every_s, c.outage_s):
            return
        job = self._job()
        if job is None:
            return
        if self.worker == "thread":
            if self._executor is None:
                self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="imunoise-motion")
            self._future = self._executor.submit(self._round, job)
            return
        self._decide(self._round(job))

    def _start(self, nav: Any, t: float) -> None:
        if self.t_start is None:
            self.t_start = float(t)
        self.n_starts += 1
        self._stale = False
        self._static = []
        self._shadows = []
        for k in range(len(self.cands)):
            e = copy.deepcopy(nav.ekf)
            e.swap_model(self.compose(nav.static_models, self.cands[k]), preserve=True)
            self._shadows.append(e)
        self._t_sh = float(t)
        self._fixes = [f for f in self._fixes if f[0] > t]
        # the buffer starts at the shadows' time (this sample, already kept)
        self._t[0], self._dth[0], self._dv[0] = self._t[self._n - 1], self._dth[self._n - 1], self._dv[self._n - 1]
        self._n = 1

    def _job(self) -> dict | None:
        """The data of the next round (copied, so a thread can run it), or None in a stretch without GNSS."""
        c = self.config
        t0, t1, t2 = self._t_sh, self._t_sh + c.every_s, self._t_sh + max(c.every_s, c.outage_s)
        tb = self._t[: self._n]
        i0 = int(np.searchsorted(tb, t0, side="left"))
        i1 = int(np.searchsorted(tb, t1, side="right"))
        i2 = int(np.searchsorted(tb, t2, side="right"))
        if i0 >= self._n or abs(tb[i0] - t0) > 1e-9:
            return None
        ft = np.array([f[0] for f in self._fixes]) if self._fixes else np.zeros(0)
        adv = np.nonzero((ft > t0) & (ft <= tb[i1 - 1]))[0]
        if adv.size == 0:
            # no GNSS for a whole round (an outage, or a rehearsed window of the experiments): nothing to score
            # and nothing the shadows could learn; they restart from the live filter when fixes return
            self._stale = True
            return None
        out = np.nonzero((ft > t0) & (ft <= t0 + c.outage_s))[0]
        statics = [s for s in self._static if s[0] <= tb[i1 - 1]]
        self._static = [s for s in self._static if s[0] > tb[i1 - 1]]
        i_out = int(np.searchsorted(tb, t0 + c.outage_s, side="right"))
        job = {"t": tb[i0:i2].copy(), "n_out": i_out - i0, "dth": self._dth[i0:i2].copy(),
               "dv": self._dv[i0:i2].copy(), "n_adv": i1 - i0,
               "adv": self._fix_arrays(adv), "out": self._fix_arrays(out), "statics": statics,
               "shadows": self._shadows}
        self._t_sh = float(tb[i1 - 1])
        self._fixes = [f for f in self._fixes if f[0] > self._t_sh]
        return job

    def _fix_arrays(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        fl = self._fixes
        return (np.array([fl[k][0] for k in idx], dtype=float), np.array([fl[k][1] for k in idx]).reshape(-1, 3),
                np.array([fl[k][2] for k in idx]).reshape(-1, 3))

    def poll(self) -> None:
        """Take a finished thread round."""
        if self._future is not None and self._future.done():
            res = self._future.result()
            self._future = None
            self._decide(res)

    def close(self) -> None:
        """Wait for a running thread round and take it."""
        if self._future is not None:
            self._future.result()
            self.poll()
        if self._executor is not None:
            self._executor.shutdown(wait=True)
            self._executor = None

    def __deepcopy__(self, memo: dict) -> MotionNoiseLearner:
        if self._future is not None or self._executor is not None:
            raise ModelError("a motion-noise learner with a worker thread cannot be copied (use worker='inline')")
        new = copy.copy(self)
        memo[id(self)] = new
        for k, v in self.__dict__.items():
            if k not in ("config", "cands", "lever"):
                setattr(new, k, copy.deepcopy(v, memo))
        return new

    # -- one round ----------------------------------------------------------------------------------
    def _round(self, job: dict) -> dict:
        """Every shadow: rehearse an outage of ``outage_s`` from its time (a copy, no GNSS; scored on the fixes
        of that span), then advance ``every_s`` with the fixes (in place). Returns the scores and the shadows'
        NIS."""
        t, dth, dv, n_adv, n_out = job["t"], job["dth"], job["dv"], job["n_adv"], job["n_out"]
        ot, ollh, _ = job["out"]
        at, allh, asig = job["adv"]
        scores = np.full(len(self.cands), np.nan)
        nis = np.zeros((len(self.cands), 2))
        ks = np.minimum(np.searchsorted(t, ot, side="left"), t.size - 1)
        no_fix = (np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)))
        sh0 = job["shadows"][0]  # one speed test per round (nothing added), so every candidate is scored alike
        rehearse = ot.size > 0 and sh0.view.speed_h >= self.config.min_speed_mps

        def advance(e: Any, j0: int, j1: int) -> np.ndarray:
            """Shadow ``e`` in place over samples j0..j1−1 with the round's fixes there; (ΣNIS, #fixes)."""
            if j1 - j0 < 2:
                return np.zeros(2)
            m = (at > t[j0]) & (at <= t[j1 - 1])
            _, _, g = e.rehearse(t[j0:j1], dth[j0:j1], dv[j0:j1], at[m], allh[m], asig[m], with_nis=True,
                                 in_place=True)
            return np.array([np.nansum(g), np.isfinite(g).sum()])

        for k, e in enumerate(job["shadows"]):
            if rehearse:
                llh, eul = e.rehearse(t[:n_out], dth[:n_out], dv[:n_out], *no_fix)
                dn, de = ned_offset(antenna_llh(llh[ks], eul[ks], self.lever), ollh)
                scores[k] = math.log(max(float(np.sqrt(np.mean(dn * dn + de * de))), 1e-3))
            # advance in place, taking a new static model at its time
            j0 = 0
            for ts, models in job["statics"]:
                j1 = int(np.searchsorted(t[:n_adv], ts, side="right"))
                if j1 - j0 >= 2:
                    nis[k] += advance(e, j0, j1)
                    j0 = j1 - 1
                e.swap_model(self.compose(models, self.cands[k]), preserve=True)
            nis[k] += advance(e, j0, n_adv)
        return {"scores": scores, "nis": nis}

    def _decide(self, res: dict) -> None:
        self._nis += res["nis"]
        if np.all(np.isfinite(res["scores"])):
            self.scores.append(res["scores"])
            self.n_rehearsals += 1
        c = self.config
        if len(self.scores) < c.min_pairs:  # carried rounds count: a warm learner decides from its first round
            return
        S = np.array(self.scores)
        nis = self._nis[:, 0] / np.maximum(self._nis[:, 1], 1.0)
        if c.criterion == "nis":
            groups = self._groups()
            pick = {g: min(ks, key=lambda k: abs(math.log(max(nis[k], 1e-9) / 3.0))) for g, ks in groups.items()}
        else:
            # paired against the shadow with nothing added (column 0): mean, t statistic, margin
            diff = S - S[:, [0]]
            mean = diff.mean(axis=0)
            sd = diff.std(axis=0, ddof=1)
            tstat = np.where(sd > 0, mean / (sd / math.sqrt(S.shape[0]) + 1e-300), 0.0)
            ok = (mean < -c.margin) & (tstat < -c.min_t)
            ok[0] = True
            mean[0] = 0.0
            pick = {}
            for g, ks in self._groups().items():
                cur = self._current_shadow(g)
                ks = [k for k in ks if ok[k]]
                best = min(ks, key=lambda k: mean[k])
                # hysteresis: leave the current choice only for a candidate that also beats it by the margin,
                # and drop it (back to nothing) only when it has become worse than nothing by the margin
                if best != cur and cur != 0:
                    if best == 0 and mean[cur] <= c.margin:
                        best = cur
                    elif best != 0 and mean[best] - mean[cur] >= -c.margin:
                        best = cur
                if c.guard and best != 0:
                    # NIS guard: the shadow must agree with its GNSS (inside the band, or closer to 3 than the
                    # shadow with nothing added)
                    lo, hi = chi2.ppf([0.025, 0.975], 3 * max(self._nis[best, 1], 1.0)) / max(self._nis[best, 1], 1.0)
                    if not (lo <= nis[best] <= hi
                            or abs(math.log(max(nis[best], 1e-9) / 3)) <= abs(math.log(max(nis[0], 1e-9) / 3))):
                        self._refused(best, nis, float(lo), float(hi))
                        best = 0
                pick[g] = best
        spec = list(self.cands[0])
        for g, k in pick.items():
            for j in (range(3) if g == "all" else [g]):
                spec[j] = self.cands[k][j]
        spec = tuple(spec)
        if spec == self.spec:
            return
        info = {"from_sigma_dph": self.sigma_dph, "sigma_dph": [a[0] for a in spec], "tc_s": [a[1] for a in spec],
                "n_rehearsals": int(S.shape[0]), "n_prior": self.n_prior,
                "paired_log_score": {str(g): float(np.mean(S[:, k] - S[:, 0])) for g, k in pick.items()},
                "nis_mean": {str(g): float(nis[k]) for g, k in pick.items()}, "nis_mean_none": float(nis[0])}
        self.spec = spec
        self.history.append({**info, "accepted": True})

    def _current_shadow(self, g) -> int:
        """Index of the shadow that runs the current choice of group ``g`` (0: nothing added)."""
        none = self.cands[0][0]
        if g == "all":
            return self.cands.index(self.spec) if self.spec in self.cands else 0
        want = tuple(self.spec[g] if i == g else none for i in range(3))
        if self.spec[g][0] == 0:
            return 0
        return self.cands.index(want) if want in self.cands else 0

    def _groups(self) -> dict:
        """Shadow indices per decision group: one group ("all") for ``search="shared"``, one per gyro axis for
        ``"axis"``; each includes 0 (nothing added)."""
        if self.config.search == "shared":
            return {"all": list(range(len(self.cands)))}
        out: dict = {j: [0] for j in range(3)}
        for k, spec in enumerate(self.cands[1:], start=1):
            j = next(i for i in range(3) if spec[i][0] > 0)
            out[j].append(k)
        return out

    def _refused(self, k: int, nis: np.ndarray, lo: float, hi: float) -> None:
        info = {"sigma_dph": [a[0] for a in self.cands[k]], "tc_s": [a[1] for a in self.cands[k]],
                "nis_mean": float(nis[k]), "nis_mean_none": float(nis[0]), "nis_band": [lo, hi],
                "n_rehearsals": self.n_rehearsals, "accepted": False}
        last = [h for h in self.history if not h["accepted"]]
        if not last or last[-1]["sigma_dph"] != info["sigma_dph"]:  # log a refusal once, not every round
            self.history.append(info)
