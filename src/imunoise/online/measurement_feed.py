"""The online engine's measurement streams besides GNSS position (GNSS velocity, odometer, ...): the whole record's
epochs of each kind, applied as the filter reaches them.

The streams (:class:`~imunoise.nav.streams.Epochs`, one per registered kind of :mod:`imunoise.nav.streams`) are
bound once to the filter's lever arm and gate. Both paths of the engine apply an epoch at the first IMU sample at
or after its time, after the GNSS position fixes of that sample, exactly as the batch engine
(:func:`imunoise.nav.filter_loop.run_steps`) does:

* a kernel span (:mod:`imunoise.online.chunks`) takes the epochs inside (t_filter, t_end] as views
  (:meth:`MeasurementFeed.span`), so the status lands in the record's arrays, and hands back the rejection
  counters (:meth:`MeasurementFeed.after_span`);
* the per-sample path (:meth:`~imunoise.online.navigator.OnlineNavigator.step_sample`) applies the due epochs one
  by one through :func:`~imunoise.nav.filter_loop.stream_update` (:meth:`MeasurementFeed.step`).

Epochs at or before the initial time are never applied (status −1), as in the batch engine.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from imunoise.errors import DataError
from imunoise.nav.filter_loop import stream_update
from imunoise.nav.streams import S_NEXT, S_REJECT, Epochs, Stream, StreamSet, bind

__all__ = ["MeasurementFeed"]


class MeasurementFeed:
    """The measurement streams of one online run (module docstring); ``streams`` by kind."""

    def __init__(self, ekf: Any, epochs: Sequence[Epochs], t0: float) -> None:
        self.streams: dict[str, Stream] = {}
        for e in epochs:
            if e.kind == "gnss_position":
                raise DataError("GNSS position fixes go to the online engine through push_gnss / run(imu, gnss)")
            if e.kind in self.streams:
                raise DataError(f"two measurement streams of kind {e.kind!r}; give one per kind")
            st = bind(e, ekf.lever, ekf.config.chi2_gate)
            st.state[S_NEXT] = int(np.searchsorted(st.t, t0, side="right"))
            self.streams[e.kind] = st

    def span(self, fixes: StreamSet, lo: float, hi: float) -> StreamSet:
        """``fixes`` with every stream's epochs in (lo, hi] added as views, each with the stream's rejection
        counter."""
        for st in self.streams.values():
            i = int(st.state[S_NEXT])
            j = int(np.searchsorted(st.t, hi, side="right"))
            i = max(i, int(np.searchsorted(st.t, lo, side="right")))
            part = st._replace(t=st.t[i:j], z=st.z[i:j], sigma=st.sigma[i:j], status=st.status[i:j],
                               nis=st.nis[i:j], state=np.array([0, st.state[S_REJECT]], dtype=np.int64))
            fixes.add(part)
        return fixes

    def after_span(self, fixes: StreamSet, hi: float) -> None:
        """Take back the counters of a span that ended at ``hi``."""
        for kind, st in self.streams.items():
            part = fixes.get(kind)
            st.state[S_REJECT] = part.state[S_REJECT]
            st.state[S_NEXT] = max(int(st.state[S_NEXT]), int(np.searchsorted(st.t, hi, side="right")))

    def step(self, ekf: Any) -> int:
        """Apply every epoch at or before the filter time; returns how many were used (or forced in)."""
        used = 0
        for st in self.streams.values():
            while st.state[S_NEXT] < st.t.shape[0] and st.t[st.state[S_NEXT]] <= ekf.t:
                used += bool(stream_update(ekf.arrays(), *ekf.kernel_parts(), st, int(st.state[S_NEXT]), ekf.t)[1])
                st.state[S_NEXT] += 1
        return used

    def status(self) -> dict[str, np.ndarray]:
        """Status of every epoch by kind: 1 used, 0 rejected by the χ² gate, 2 forced in, −1 not applied."""
        return {k: st.status for k, st in self.streams.items()}
