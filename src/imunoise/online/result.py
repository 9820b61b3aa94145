"""What the online engine returns: one :class:`ModelUpdate` per modelling job, the :class:`OnlineResult` of a
run (trajectory, sensor errors, σ, events, updates) and the :class:`EpochStore` the navigator fills per epoch."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from imunoise.detect import StaticSegment
from imunoise.io.jsonutil import json_default as _json_default
from imunoise.nav.filter_loop import euler_rows
from imunoise.nav.solution import NavSolution
from imunoise.noise.estimator import GMWMFit
from imunoise.noise.model import Model

__all__ = ["ModelUpdate", "OnlineResult", "EpochStore", "log_event"]


# --------------------------------------------------------------------------------------------------
# results
# --------------------------------------------------------------------------------------------------
def log_event(events: list[dict], event: str, t: float, **kw: Any) -> None:
    """Append one entry ``{"t", "event", **kw}`` to an online run's event log (:attr:`OnlineResult.events`)."""
    e = {"t": float(t), "event": event}
    e.update(kw)
    events.append(e)


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
class OnlineResult(NavSolution):
    """Output of the online run at every IMU epoch the filter processed (IMU point).

    ``detected_segments``: every segment the static detector completed (IMU only); ``segments``: what was
    modelled of them (all, or the pieces the stop guard kept, ``OnlineConfig.stop_guard``);
    ``rejected_segments``: the pieces the navigation solution contradicted, never modelled;
    ``static_raw``/``sample_t``: the detector's per-sample test over every pushed sample; ``static_pieces``:
    every static piece the model was fitted on, (N, 6) each: those given as ``earlier_static`` unchanged, then
    this drive's stops with their bias removed; the ``earlier_static`` of the next drive of the same IMU."""

    events: list[dict]
    updates: list[ModelUpdate]
    segments: list[StaticSegment]
    gate_open: np.ndarray
    static_raw: np.ndarray
    lambda0: float
    elapsed_s: float
    final_models: list[Model]
    fits: list[GMWMFit | None] = field(default_factory=list)
    sample_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    rejected_segments: list[StaticSegment] = field(default_factory=list)
    detected_segments: list[StaticSegment] = field(default_factory=list)
    static_pieces: list[np.ndarray] = field(default_factory=list)

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


    def write_events(self, path: str | Path) -> Path:
        """JSON lines, one event per line (docs/guide/theory.rst, 'Online engine' and 'Experiments')."""
        p = Path(path)
        with p.open("w") as fh:
            for e in self.events:
                fh.write(json.dumps(e, default=_json_default) + "\n")
        return p


class EpochStore:
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

    @property
    def t(self) -> np.ndarray:
        """Times [s] of the stored epochs (a view)."""
        return self.buf[: self.n, 0]

    def extend(self, rows: np.ndarray) -> None:
        """:meth:`add` of each row of ``rows`` (k, COLS), in order (a kernel span's epochs)."""
        need = self.n + rows.shape[0]
        if need > self.buf.shape[0]:
            cap = self.buf.shape[0]
            while cap < need:
                cap *= 2
            buf = np.empty((cap, self.COLS))
            buf[: self.n] = self.buf[: self.n]
            self.buf = buf
        self.buf[self.n:need] = rows
        self.n = need

    def arrays(self, rows: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
        """(t, llh, velocity NED, Euler angles, gyro errors, accel errors, σ) of the stored epochs, or of the
        epochs ``rows`` (indices); the Euler angles of the quaternions in one kernel call
        (:func:`~imunoise.nav.filter_loop.euler_rows`, the per-sample outputs' conversion)."""
        b = self.buf[: self.n] if rows is None else self.buf[: self.n][rows]
        eul = euler_rows(np.ascontiguousarray(b[:, 7:11]))
        return b[:, 0].copy(), b[:, 1:4].copy(), b[:, 4:7].copy(), eul, b[:, 11:14].copy(), b[:, 14:17].copy(), \
            b[:, 17:26].copy()
