"""Measurement streams: the filter's aiding measurements as a registry of typed streams (times, values, σ, settings).

A :class:`Stream` is one kind of measurement over a run: its times (sorted, the IMU time base), a value row and a
1σ row per epoch, the lever arm, the gate settings (``cfg``: χ² threshold, consecutive rejections before one is
forced in, the absolute innovation floor of the gate) and what the filter writes back (``status``: 1 used, 0
rejected by the χ² gate, 2 forced in, −1 outside the run; the gate's ``nis``; the innovation ``nll`` when it has
a row per epoch) and its own counters (``state``: next epoch, consecutive rejections). The engine
(:func:`imunoise.nav.filter_loop.run_steps`) applies, after each IMU sample's propagation, every due epoch of
every stream, in the order of :data:`KINDS`, through :func:`measure`, the one place that maps a kind to its
``(dz, H, R)`` function of :mod:`imunoise.nav.measurements`.

Adding a measurement: its ``(dz, H, R)`` module under :mod:`imunoise.nav.measurements`, its name in
:data:`KINDS` and a branch in :func:`measure`; every path into the filter (batch, the step filter, the online
engine's spans, rehearsals, the noise-schedule pieces) then takes it through :class:`StreamSet`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from imunoise.errors import DataError
from imunoise.nav.measurements.gnss_position import gnss_position
from imunoise.nav.measurements.gnss_velocity import gnss_velocity
from imunoise.nav.measurements.odometer import odometer

__all__ = ["KINDS", "K_GNSS_POSITION", "K_GNSS_VELOCITY", "K_ODOMETER", "C_CHI2", "C_MAX_REJECT", "C_GATE_ABS",
           "CFG_LEN", "Stream", "make_stream", "empty_stream", "measure", "StreamSet", "S_NEXT", "S_REJECT", "Epochs",
           "bind"]

KINDS = ("gnss_position", "gnss_velocity", "odometer")
"""Registered kinds, in the order the engine applies them within one IMU sample."""
K_GNSS_POSITION, K_GNSS_VELOCITY, K_ODOMETER = range(len(KINDS))

C_CHI2, C_MAX_REJECT, C_GATE_ABS = 0, 1, 2
"""``cfg`` columns: χ² gate (≤ 0 off), consecutive rejections before the next epoch is forced in (< 0 never),
absolute innovation floor added to S in the gate (value units)."""
CFG_LEN = 4

S_NEXT, S_REJECT = 0, 1
"""``state`` entries: index of the next epoch to apply, consecutive rejections so far."""


class Stream(NamedTuple):
    """One measurement stream (module docstring); every array C-contiguous so that all streams share one
    numba type."""

    kind: int
    t: np.ndarray
    z: np.ndarray
    sigma: np.ndarray
    lever: np.ndarray
    cfg: np.ndarray
    status: np.ndarray
    nis: np.ndarray
    nll: np.ndarray
    state: np.ndarray


def make_stream(kind: str, t, z, sigma, lever, *, chi2: float = 0.0, max_reject: int = -1, gate_abs: float = 0.0,
                with_nll: bool = False) -> Stream:
    """A stream of ``kind`` (:data:`KINDS`) with epochs ``t`` [s], values ``z`` (n, d) and 1σ ``sigma`` (n, d),
    all taken as given (the readers check and sort them); status −1 and NaN NIS until the engine writes them."""
    if kind not in KINDS:
        raise DataError(f"unknown measurement kind {kind!r}; registered: {', '.join(KINDS)}")
    t = np.ascontiguousarray(t, dtype=float)
    n = t.shape[0]
    z = np.ascontiguousarray(z, dtype=float)
    sigma = np.ascontiguousarray(sigma, dtype=float)
    z = z.reshape(n, -1) if z.ndim != 2 else z
    sigma = sigma.reshape(n, -1) if sigma.ndim != 2 else sigma
    cfg = np.zeros(CFG_LEN)
    cfg[C_CHI2], cfg[C_MAX_REJECT], cfg[C_GATE_ABS] = float(chi2), float(max_reject), float(gate_abs)
    return Stream(KINDS.index(kind), t, z, sigma, np.ascontiguousarray(lever, dtype=float), cfg,
                  np.full(n, -1, dtype=np.int64), np.full(n, np.nan), np.full(n if with_nll else 0, np.nan),
                  np.zeros(2, dtype=np.int64))


class Epochs(NamedTuple):
    """A stream as a reader or the simulator gives it, before a filter binds its lever arm and gate
    (:func:`bind`): kind (:data:`KINDS`), times [s] (sorted, the IMU time base), values (n, d), 1σ (n, d), the
    gate's guards (innovation floor ``gate_abs`` in value units, consecutive rejections before one is forced in,
    < 0 never; ``chi2`` None: the filter's ``EkfConfig.chi2_gate``), rows dropped by the reader (NaN), where
    the epochs came from (a file, a bag topic; for messages) and the sensor's lever arm (body FRD, m; None: the
    filter's GNSS antenna lever arm)."""

    kind: str
    t: np.ndarray
    z: np.ndarray
    sigma: np.ndarray
    gate_abs: float = 0.0
    max_reject: int = -1
    chi2: float | None = None
    dropped: int = 0
    source: str = ""
    lever: tuple | None = None


def bind(e: Epochs, lever, chi2: float) -> Stream:
    """The stream of ``e`` in a filter with antenna lever arm ``lever`` and χ² gate ``chi2`` (``e.lever`` and
    ``e.chi2`` win)."""
    return make_stream(e.kind, e.t, e.z, e.sigma, lever if e.lever is None else e.lever,
                       chi2=chi2 if e.chi2 is None else e.chi2,
                       max_reject=e.max_reject, gate_abs=e.gate_abs)


def empty_stream(kind: str, lever) -> Stream:
    """A stream of ``kind`` without epochs."""
    return make_stream(kind, np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)), lever)


_EMPTY: dict[str, Stream] = {}


def _empty(kind: str) -> Stream:
    """One shared empty stream per kind (nothing in it is ever written: it has no epoch)."""
    if kind not in _EMPTY:
        _EMPTY[kind] = empty_stream(kind, np.zeros(3))
    return _EMPTY[kind]


@njit(cache=True)
def measure(nav, n, last_dt, st, i, tk):
    """``(dz, H, R)`` of epoch ``i`` of stream ``st`` applied at filter time ``tk`` (``last_dt``: the last
    IMU interval, for the angular rate). A kind without a branch raises: numba's cache follows a change of a
    kernel's own file only, so a step sequence cached before a kind was added runs the dispatch it was compiled
    with, and must stop there rather than hand the new kind to another measurement's function."""
    if st.kind == K_GNSS_POSITION:
        return gnss_position(nav, n, st.z[i], st.lever, tk - st.t[i], st.sigma[i])
    if st.kind == K_GNSS_VELOCITY:
        return gnss_velocity(nav, n, st.z[i], st.lever, last_dt, st.sigma[i])
    if st.kind == K_ODOMETER:
        return odometer(nav, n, st.z[i], st.lever, last_dt, st.sigma[i])
    raise DataError("measurement kind unknown to the compiled filter kernels (cached before the kind was added?): "
                     "delete numba's cache, find src -name '*.nb[ic]' -delete")


class StreamSet:
    """The streams of one run, by kind; :meth:`kernel` gives the engine its tuple (one slot per registered kind,
    empty where absent, so that every run compiles to the same kernel)."""

    def __init__(self, lever, streams: dict[str, Stream] | None = None) -> None:
        self.lever = np.ascontiguousarray(lever, dtype=float)
        self.streams: dict[str, Stream] = dict(streams or {})

    def add(self, stream: Stream) -> StreamSet:
        """Add (or replace) the stream of its kind; returns self."""
        self.streams[KINDS[stream.kind]] = stream
        return self

    def get(self, kind: str) -> Stream | None:
        """The stream of ``kind`` or None."""
        return self.streams.get(kind)

    def kernel(self) -> tuple[Stream, ...]:
        """The engine's argument: one stream per registered kind, in :data:`KINDS` order."""
        return tuple(self.streams.get(k) or _empty(k) for k in KINDS)

    def start_after(self, t0: float) -> None:
        """Skip (status −1) every epoch at or before ``t0``: a batch run starts at the state of ``t0``."""
        for st in self.streams.values():
            i = int(np.searchsorted(st.t, t0, side="right"))
            st.status[:i] = -1
            st.state[S_NEXT] = i

    def slice(self, lo: float, hi: float) -> StreamSet:
        """The epochs with lo < t ≤ hi as views (the engine's status/NIS land in these streams); fresh counters."""
        out = {}
        for k, st in self.streams.items():
            i, j = np.searchsorted(st.t, [lo, hi], side="right")
            out[k] = st._replace(t=st.t[i:j], z=st.z[i:j], sigma=st.sigma[i:j], status=st.status[i:j],
                                 nis=st.nis[i:j], nll=st.nll[i:j] if st.nll.shape[0] == st.t.shape[0] else st.nll,
                                 state=np.zeros(2, dtype=np.int64))
        return StreamSet(self.lever, out)
