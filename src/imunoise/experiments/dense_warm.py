"""The warm methods' earlier drives of the same vehicle (simulator): what ``gmwm_dyn`` learned on them
(:func:`learn_prior`, :func:`earlier_prior`) and the stops ``gmwm`` pooled on them (:func:`earlier_stops`; the run
itself, whose fits are ``in_use``'s static part: :func:`gmwm_on_drives`); the
k-th drive before drive ``seed`` is the simulated drive of seed + k · :data:`PRIOR_SEED_OFFSET` (with a replayed
recording, its own stretch of the recording: :func:`earlier_kw`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from imunoise.errors import ModelError
from imunoise.experiments.common import Scenario
from imunoise.experiments.dense_branches import run_windows
from imunoise.experiments.dense_methods import method_setup
from imunoise.experiments.gnss_regimes import GnssRegime
from imunoise.online import MotionNoisePrior, OnlineConfig

__all__ = ["PRIOR_SEED_OFFSET", "earlier_kw", "learn_prior", "earlier_prior", "earlier_stops", "gmwm_on_drives"]

PRIOR_SEED_OFFSET = 7_000_000  # the k-th drive before drive seed on the simulator: seed + k · this


def earlier_kw(scen_kw: dict, k: int) -> dict:
    """The scenario keywords of the ``k``-th drive before a scored drive. The same as the scored drive's, except
    with a replayed recording (``imu_noise``): the earlier drive is of the same vehicle (seed + k ·
    :data:`PRIOR_SEED_OFFSET` − the shifted first seed = the vehicle's index) and takes its own stretch, the one
    ``k`` before the scored drive's (:func:`imunoise.sim.replay.stretch_index`; a vehicle without that many
    stretches is refused there, naming ``--vehicle-drives``)."""
    if not k or not scen_kw.get("imu_noise"):
        return scen_kw
    return {**scen_kw, "imu_noise_first": int(scen_kw.get("imu_noise_first", 0)) + k * PRIOR_SEED_OFFSET,
            "imu_noise_earlier": int(k)}


def learn_prior(sc: Scenario, gnss, base: OnlineConfig | None = None,
                prior: MotionNoisePrior | None = None) -> MotionNoisePrior:
    """What ``gmwm_dyn`` learns on the whole GNSS-aided drive ``sc`` (no outage), starting from ``prior`` (what
    the drives before it learned) if given: the prior of the next drive of the same vehicle
    (:class:`~imunoise.online.motion_noise.MotionNoisePrior`; its rounds are the carried ones and this drive's)."""
    cfg, models, upd = method_setup("gmwm_dyn" if prior is None else "gmwm_dyn_warm", sc, base, {}, prior=prior)
    full = run_windows(sc, cfg, gnss, [], initial_models=models, updater=upd, keep=True)["_full"]
    end = [e for e in full.events if e["event"] == "motion_noise_end"]
    return MotionNoisePrior.from_dict(end[-1]["evidence"])


def _earlier_drives(seed: int, n_drives: int, earlier: Sequence[Scenario] | None, scen_kw: dict):
    """(seed, scenario) of the ``n_drives`` earlier drives of simulated drive ``seed``, oldest first: seed + k ·
    :data:`PRIOR_SEED_OFFSET`, k = ``n_drives`` … 1; ``earlier[k - 1]`` is drive k if given, else simulated."""
    from imunoise.experiments.common import simulate_scenario

    if n_drives < 1:
        raise ModelError(f"a warm method needs at least one earlier drive, not {n_drives}")
    for k in range(n_drives, 0, -1):
        s = int(seed) + k * PRIOR_SEED_OFFSET
        yield s, (earlier[k - 1] if earlier is not None and len(earlier) >= k
                  else simulate_scenario(s, n_outages=0, **earlier_kw(scen_kw, k)))


def earlier_prior(seed: int, regime: GnssRegime, noise_seed: int, *, n_drives: int = 1,
                  base: OnlineConfig | None = None, earlier: Sequence[Scenario] | None = None,
                  **scen_kw: Any) -> MotionNoisePrior:
    """The prior of a warm method on simulated drive ``seed`` after ``n_drives`` earlier drives of the same
    vehicle: :func:`learn_prior` on the drives of seed + k · :data:`PRIOR_SEED_OFFSET`, k = ``n_drives`` … 1 in
    that order, each starting with what the ones before it learned. ``earlier[k - 1]`` is drive k if given (else
    it is simulated with ``scen_kw``); each in GNSS ``regime``, its noise seeded like a drive's own
    (``1_000_003 · drive seed + noise_seed``)."""
    prior = None
    for s, sc in _earlier_drives(seed, n_drives, earlier, scen_kw):
        prior = learn_prior(sc, regime.apply(sc.gnss, 1_000_003 * s + noise_seed), base, prior)
    assert prior is not None
    return prior


def earlier_stops(seed: int, regime: GnssRegime, noise_seed: int, *, n_drives: int = 1,
                  base: OnlineConfig | None = None, earlier: Sequence[Scenario] | None = None,
                  **scen_kw: Any) -> list[np.ndarray]:
    """The static pieces ``gmwm`` pooled on ``n_drives`` earlier drives of the same vehicle (the drives of
    :func:`earlier_prior`, in the same order and GNSS), each run online GNSS-aided starting with the pieces
    of the drives before it (:attr:`OnlineResult.static_pieces`): the ``earlier_static`` of drive ``seed``."""
    drives = [(sc, regime.apply(sc.gnss, 1_000_003 * s + noise_seed))
              for s, sc in _earlier_drives(seed, n_drives, earlier, scen_kw)]
    return gmwm_on_drives(drives, base).static_pieces


def gmwm_on_drives(drives: Sequence[tuple[Scenario, Any]], base: OnlineConfig | None = None) -> Any:
    """The ``gmwm`` row's GNSS-aided run (no outage) on each of ``drives`` ((scenario, GNSS) pairs, oldest
    first), each starting with the static pieces the runs before it pooled (``earlier_static``): the last run's
    :class:`~imunoise.online.result.OnlineResult`. Its ``fits`` are what the online engine identified at the
    drives' stops (the stop guard's kept segments, identified at the first ``min_static_s`` of them and refit at
    every later stop: :class:`~imunoise.online.modeller.StopModeller`), its ``static_pieces`` the pooled stops."""
    if not drives:
        raise ModelError("the gmwm run on earlier drives needs at least one drive")
    pieces: list[np.ndarray] | None = None
    full = None
    for sc, gnss in drives:
        cfg, models, upd = method_setup("gmwm", sc, base, {})
        full = run_windows(sc, cfg, gnss, [], initial_models=models, updater=upd, keep=True,
                           earlier_static=pieces)["_full"]
        pieces = full.static_pieces
    return full
