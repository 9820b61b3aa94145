"""In-motion gyro noise learned while driving, by rehearsing GNSS outages on data already seen (``gmwm_dyn``).

Why. Stops show the sensor at rest: the white-noise level and little slower (the stops of a city drive last
seconds). While the car drives, vibration, temperature and g-sensitivity make the gyro biases wander far more
(the shared drive: std of 10 s means of the estimated gyro errors 58 / 144 / 123 °/h for x/y/z against a static
ADEV at 10 s of 64 / 37 / 6 °/h), and the outage drift depends on how the filter models that wander. On the
simulator with the motion law calibrated on that drive, the oracle's whole gain over the plain filter comes from
the gyro bias processes in motion (development seeds 1000–1003: true moving gyro models 0.69× the plain drift,
true accelerometer models 0.99×).

What is learned. An in-motion Gauss–Markov process added to the model of each gyro axis (the static model from
the stops keeps the fast part and everything it identified):

    b_k+1 = φ b_k + √(1 − φ²) σ w_k,    φ = exp(−Δt / T_c),

one of the candidates (σ, T_c) of :class:`MotionNoiseConfig` (σ = 0: nothing added, the start).

How (shadow filters and rehearsed outages). From the first moment the car moves GNSS-aided, one shadow copy of
the filter per candidate runs beside the live filter on the same IMU samples and fixes, each with its candidate
model, a few seconds behind (the batch kernel, :meth:`~imunoise.nav.ekf.LooselyCoupledEKF.rehearse`). Every
``every_s`` seconds each shadow rehearses an outage: a copy of it runs ``outage_s`` seconds on without GNSS,
and its score is log of the RMS horizontal distance between its antenna position and the fixes of that span
(all of them: the 1.8 m noise of a single fix would swamp the difference between candidates) —
the drift the candidate would have had, measured against the GNSS the filter had anyway. Each shadow has run
with its own model since it started, so the rehearsal sees the candidate's steady state (a copy of the live
filter switched to a candidate for half a minute does not: its bias estimate is still the live model's, and on
development seeds that preferred far too much noise). The live filter takes the candidate with the lowest
mean paired score once ``min_pairs`` rehearsals exist and the paired difference to the current choice is below
−``margin`` with a paired t statistic below −``min_t``.

Guard. A move is refused (event ``motion_noise_rejected``) when the candidate's shadow is inconsistent with
the GNSS it was aided by: the mean NIS of its fixes (3 dof) outside the two-sided 95 % χ² band of their number,
and farther from 3 than the current choice's.

Online. The shadows and rehearsals run in the navigator's worker: ``inline`` computes them when due
(deterministic; the same in :meth:`~imunoise.online.navigator.OnlineNavigator.run` and the push API);
``thread`` runs them in a background thread (the kernel releases the GIL) and the choice takes effect at the
first sample after the thread finished. Events: ``motion_noise`` (σ, T_c, the paired score and its count).
The navigator composes the learned part with every static model it swaps in, and the shadows take the new
static model at the same filter time.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.stats import chi2

from imunoise.errors import ModelError
from imunoise.model import Model
from imunoise.nav.earth import radii
from imunoise.nav.solution import antenna_llh
from imunoise.processes import AR1

__all__ = ["MotionNoiseConfig", "MotionNoiseLearner", "add_motion_gm", "ned_offset", "horizontal_distance"]

_DPH = math.pi / 180.0 / 3600.0  # °/h → rad/s


@dataclass(frozen=True)
class MotionNoiseConfig:
    """Settings of the in-motion noise learner (module docstring).

    ``sigma_dph``: candidate σ of the added Gauss–Markov process [°/h] (the same on the three gyro axes; 0 is
    always a candidate, the start); ``tc_s``: candidate correlation times [s]; ``outage_s``: length of a
    rehearsed outage [s]; ``every_s``: one rehearsal per shadow every this many seconds; ``min_speed_mps``:
    rehearse only while the filter's horizontal speed exceeds this; ``min_pairs``: rehearsals a move needs;
    ``margin``: paired mean log-score a move must beat (0.02 ≈ 2 % less drift); ``min_t``: and its paired t
    statistic must be below −``min_t``; ``guard``: the NIS guard."""

    sigma_dph: tuple[float, ...] = (30.0, 100.0, 300.0)
    tc_s: tuple[float, ...] = (3.0, 30.0)
    outage_s: float = 30.0
    every_s: float = 10.0
    min_speed_mps: float = 2.0
    min_pairs: int = 5
    margin: float = 0.02
    min_t: float = 2.0
    guard: bool = True
    criterion: str = "drift"

    def __post_init__(self) -> None:
        sg = tuple(float(x) for x in self.sigma_dph)
        tc = tuple(float(x) for x in self.tc_s)
        if not sg or any(not (x > 0 and math.isfinite(x)) for x in sg):
            raise ModelError(f"MotionNoiseConfig.sigma_dph needs values > 0 °/h, got {self.sigma_dph!r}")
        if not tc or any(not (x > 0 and math.isfinite(x)) for x in tc):
            raise ModelError(f"MotionNoiseConfig.tc_s needs correlation times > 0 s, got {self.tc_s!r}")
        object.__setattr__(self, "sigma_dph", sg)
        object.__setattr__(self, "tc_s", tc)
        if not (self.outage_s > 0 and self.every_s > 0 and self.min_pairs >= 1 and self.margin >= 0
                and self.min_t >= 0 and self.min_speed_mps >= 0):
            raise ModelError("MotionNoiseConfig: outage_s, every_s > 0 s; min_pairs ≥ 1; margin, min_t, "
                             "min_speed_mps ≥ 0")

    @property
    def candidates(self) -> list[tuple[float, float]]:
        """(σ °/h, T_c s) pairs; (0, first T_c) first."""
        return [(0.0, self.tc_s[0])] + [(s, tc) for s in self.sigma_dph for tc in self.tc_s]


def add_motion_gm(models: Sequence[Any], sigma_dph: float, tc_s: float, rate_hz: float) -> list:
    """The six (model, freq) pairs with a Gauss–Markov process of σ ``sigma_dph`` [°/h] and correlation time
    ``tc_s`` added to each gyro axis (module docstring; σ = 0 adds nothing); accelerometer axes unchanged."""
    out = []
    for a, mm in enumerate(models):
        m, fr = mm if isinstance(mm, tuple) else (mm, rate_hz)
        if a < 3 and sigma_dph > 0:
            phi = math.exp(-1.0 / (tc_s * fr))
            m = Model([*m.components, AR1(phi=phi, sigma2=(sigma_dph * _DPH) ** 2 * (1.0 - phi * phi))])
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
    choice : int
        Index of the current candidate in ``config.candidates`` (0: nothing added).
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
        self.choice = 0
        self.history: list[dict] = []
        self.n_rehearsals = 0
        self.scores: list[np.ndarray] = []  # per rehearsal round: log RMS drift per candidate
        self._nis = np.zeros((len(self.cands), 2))  # per shadow: sum of NIS, number of fixes
        self._shadows: list[Any] | None = None
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
    def sigma_dph(self) -> float:
        return self.cands[self.choice][0]

    @property
    def tc(self) -> float:
        return self.cands[self.choice][1]

    def compose(self, static_models: Sequence[Any], choice: int | None = None) -> list:
        """``static_models`` with the in-motion part of candidate ``choice`` (default the current one)."""
        s, tc = self.cands[self.choice if choice is None else choice]
        return add_motion_gm(static_models, s, tc, self.rate)

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

    def observe(self, nav: Any, t: float, dth: np.ndarray, dv: np.ndarray, fixes: Sequence[tuple]) -> None:
        """One filter step of the navigator ``nav`` (after the fixes ``fixes`` were applied at ``t``). Starts
        the shadows at the first aided moving step; runs a rehearsal round when one is due; a decision lands in
        :attr:`history` (the navigator swaps it in)."""
        self._keep(t, dth, dv)
        self._fixes.extend(fixes)
        c = self.config
        if self._shadows is None:
            moving = math.hypot(nav.ekf.nav[3], nav.ekf.nav[4]) >= c.min_speed_mps
            if fixes and moving:
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
        self._shadows = []
        for k in range(len(self.cands)):
            e = copy.deepcopy(nav.ekf)
            e.swap_model(self.compose(nav.static_models, k), preserve=True)
            self._shadows.append(e)
        self._t_sh = float(t)
        self._fixes = [f for f in self._fixes if f[0] > t]
        # the buffer starts at the shadows' time (this sample, already kept)
        self._t[0], self._dth[0], self._dv[0] = self._t[self._n - 1], self._dth[self._n - 1], self._dv[self._n - 1]
        self._n = 1

    def _job(self) -> dict | None:
        """The data of the next round (copied, so a thread can run it), or None in a stretch without GNSS
        (e.g. a rehearsed window of the experiments), which the shadows then skip."""
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
        out = np.nonzero((ft > t0) & (ft <= t0 + c.outage_s))[0]
        statics = [s for s in self._static if s[0] <= tb[i1 - 1]]
        self._static = [s for s in self._static if s[0] > tb[i1 - 1]]
        i_out = int(np.searchsorted(tb, t0 + c.outage_s, side="right"))
        job = {"t": tb[i0:i2].copy(), "n_out": i_out - i0, "dth": self._dth[i0:i2].copy(), "dv": self._dv[i0:i2].copy(), "n_adv": i1 - i0,
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
        t, dth, dv, n_adv = job["t"], job["dth"], job["dv"], job["n_adv"]
        ot, ollh, osig = job["out"]
        at, allh, asig = job["adv"]
        speed_ok = True
        scores = np.full(len(self.cands), np.nan)
        nis = np.zeros((len(self.cands), 2))
        ks = np.minimum(np.searchsorted(t, ot, side="left"), t.size - 1)
        no_fix = (np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)))
        for k, e in enumerate(job["shadows"]):
            speed_ok = math.hypot(e.nav[3], e.nav[4]) >= self.config.min_speed_mps if k == 0 else speed_ok
            if ot.size and speed_ok:
                n_out = job["n_out"]
                llh, eul = e.rehearse(t[:n_out], dth[:n_out], dv[:n_out], *no_fix)
                dn, de = ned_offset(antenna_llh(llh[ks], eul[ks], self.lever), ollh)
                scores[k] = math.log(max(float(np.sqrt(np.mean(dn * dn + de * de))), 1e-3))
            # advance in place, taking a new static model at its time
            j0 = 0
            for ts, models in job["statics"]:
                j1 = int(np.searchsorted(t[:n_adv], ts, side="right"))
                if j1 - j0 >= 2:
                    m = (at > t[j0]) & (at <= t[j1 - 1])
                    _, _, g = e.rehearse(t[j0:j1], dth[j0:j1], dv[j0:j1], at[m], allh[m], asig[m], with_nis=True,
                                         in_place=True)
                    nis[k] += (np.nansum(g), np.isfinite(g).sum())
                    j0 = j1 - 1
                e.swap_model(self.compose(models, k), preserve=True)
            if n_adv - j0 >= 2:
                m = (at > t[j0]) & (at <= t[n_adv - 1])
                _, _, g = e.rehearse(t[j0:n_adv], dth[j0:n_adv], dv[j0:n_adv], at[m], allh[m], asig[m], with_nis=True,
                                     in_place=True)
                nis[k] += (np.nansum(g), np.isfinite(g).sum())
        return {"scores": scores, "nis": nis}

    def _decide(self, res: dict) -> None:
        self._nis += res["nis"]
        if np.all(np.isfinite(res["scores"])):
            self.scores.append(res["scores"])
            self.n_rehearsals += 1
        c = self.config
        if len(self.scores) < c.min_pairs:
            return
        if c.criterion == "nis":
            m = self._nis[:, 0] / np.maximum(self._nis[:, 1], 1.0)
            best = int(np.argmin(np.abs(np.log(np.maximum(m, 1e-9) / 3.0))))
            if best != self.choice:
                self.history.append({"from_sigma_dph": self.sigma_dph, "sigma_dph": self.cands[best][0],
                                     "tc_s": self.cands[best][1], "nis_mean": float(m[best]),
                                     "nis_mean_current": float(m[self.choice]), "n_rehearsals": len(self.scores),
                                     "accepted": True})
                self.choice = best
            return
        S = np.array(self.scores)
        diff = S - S[:, [self.choice]]
        mean = diff.mean(axis=0)
        sd = diff.std(axis=0, ddof=1)
        tstat = np.where(sd > 0, mean / (sd / math.sqrt(S.shape[0]) + 1e-300), 0.0)
        ok = (mean < -c.margin) & (tstat < -c.min_t)
        if not np.any(ok):
            return
        best = int(np.argmin(np.where(ok, mean, np.inf)))
        info = {"from_sigma_dph": self.sigma_dph, "sigma_dph": self.cands[best][0], "tc_s": self.cands[best][1],
                "paired_log_score": float(mean[best]), "t_stat": float(tstat[best]), "n_rehearsals": int(S.shape[0])}
        if c.guard:
            ok_nis, nis_info = self._consistent(best)
            info.update(nis_info)
            if not ok_nis:
                if not self.history or self.history[-1].get("sigma_dph") != info["sigma_dph"] \
                        or self.history[-1]["accepted"]:
                    self.history.append({**info, "accepted": False})
                return
        self.choice = best
        self.history.append({**info, "accepted": True})

    def _consistent(self, new: int) -> tuple[bool, dict]:
        """NIS guard (module docstring)."""
        def mean_nis(k: int) -> tuple[float, float]:
            s, n = self._nis[k]
            return s / max(n, 1.0), n

        m_new, n = mean_nis(new)
        m_cur, _ = mean_nis(self.choice)
        lo, hi = chi2.ppf([0.025, 0.975], 3 * max(n, 1.0)) / max(n, 1.0)
        inside = bool(lo <= m_new <= hi)
        closer = abs(math.log(max(m_new, 1e-9) / 3.0)) <= abs(math.log(max(m_cur, 1e-9) / 3.0))
        return inside or closer, {"nis_mean": float(m_new), "nis_mean_current": float(m_cur),
                                  "nis_band": [float(lo), float(hi)]}
