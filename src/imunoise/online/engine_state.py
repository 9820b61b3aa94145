"""The online engine's state: what the navigator and its collaborators (detector feed, stop guard, ZUPT, learner
host, chunked replay) read and write per IMU sample, in one explicit object instead of the navigator's private
attributes.

The navigator (:class:`~imunoise.online.navigator.OnlineNavigator`) owns one :class:`EngineState` and hands it
to each collaborator at construction; every collaborator writes only the fields its docstring names. A branch of
a running navigator (:meth:`OnlineNavigator.fork`) copies the state with everything that refers to it, so the
references between the navigator and its collaborators stay consistent in the copy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from imunoise.online.result import EpochStore, log_event

__all__ = ["EngineState"]


@dataclass(eq=False)
class EngineState:
    """Per-sample state of the online engine (module docstring).

    ``init_t``: the initial time (samples at or before it only feed the detector and the modeller);
    ``events``: the event log (shared with the stop modeller); ``started``: the first sample after ``init_t`` was
    seen (the strapdown is primed there); ``t_last``: time of the last sample the filter/detector processed;
    ``t_in``: time of the last sample pushed (held while λ_0 is learned); ``n_samples``: samples processed;
    ``static_run``: length of the current raw static run (0 when not static); ``stop_start_n``: the run length at
    which a raw static run becomes a segment (−1 without a detector); ``zupt_rejected``: a ZUPT of the current
    static run was refused by its χ² test (logged once per run); ``gate``: the angular-rate gate of the last
    sample; ``rows``: raw samples (rates, (6,) each) kept for the segments, ``rows[0]`` being sample
    ``raw_t0``; ``static_raw``, ``sample_t``, ``gate_log``: per-sample detector flag, time and gate;
    ``gnss``: queued fixes (t, llh, σ) not applied yet; ``t_aided``: filter time of the last GNSS fix used;
    ``elapsed``: CPU seconds spent in the engine; ``store``: stored epochs (None: not stored);
    ``event_sources``: extra event sources, (sorted sample indices, hook) each; ``streams``: the measurement streams
    besides GNSS position (:class:`~imunoise.online.measurement_feed.MeasurementFeed`; None: none).
    """

    init_t: float
    store: EpochStore | None = None
    events: list[dict] = field(default_factory=list)
    started: bool = False
    t_last: float = -math.inf
    t_in: float = -math.inf
    n_samples: int = 0
    static_run: int = 0
    stop_start_n: int = -1
    zupt_rejected: bool = False
    gate: bool = False
    rows: list[np.ndarray] = field(default_factory=list)
    raw_t0: int = 0
    static_raw: list[bool] = field(default_factory=list)
    sample_t: list[float] = field(default_factory=list)
    gate_log: list[bool] = field(default_factory=list)
    gnss: list[tuple[float, np.ndarray, np.ndarray]] = field(default_factory=list)
    t_aided: float = -math.inf
    elapsed: float = 0.0
    event_sources: list[tuple[np.ndarray, Any]] = field(default_factory=list)
    streams: Any = None

    def event(self, event: str, t: float, **kw: Any) -> None:
        """Append one event to the log (:func:`~imunoise.online.result.log_event`)."""
        log_event(self.events, event, t, **kw)

    def drop_old_rows(self, keep: int) -> None:
        """Forget all raw samples but the last ``keep`` (they are needed only back to the start of a possible
        segment)."""
        drop = len(self.rows) - keep
        if drop > 0:
            del self.rows[:drop]
            self.raw_t0 += drop
