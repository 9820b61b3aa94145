"""The ends of a stop: the speed check looks past them (:func:`imunoise.calibrate.stops.edge_verdict`) and a
forward-only (streamed) stop loses its measured end lag (:func:`imunoise.calibrate.stops.end_trimmed`)."""

from __future__ import annotations

import numpy as np
import pytest

from imunoise.calibrate.stops import STREAM_END_TRIM_S, Stop, cut_segment, end_trimmed
from imunoise.detect import DetectorConfig

F = 100.0


def segment(t0: float, t1: float):
    t = np.arange(round(t0 * F), round(t1 * F) + 1) / F
    return Stop(float(t[0]), float(t[-1]), int(round(t0 * F)), int(round(t0 * F)) + t.size), t


def test_a_departure_after_the_end_cuts_the_stop_end():
    """Speed 0 inside the segment 10–30 s, 2 m/s² from its end: above 1 m/s from 30.51 s (the first sample past
    30.5 s), outside the segment; the samples within 3 s (stop_edge_s) of it go, the stop ends at 27.50 s. A
    check that looked only inside would cut nothing."""
    seg, t = segment(10.0, 30.0)
    speed = (np.arange(0.0, 60.0, 0.1), np.clip(np.arange(0.0, 60.0, 0.1) - 30.0, 0.0, None) * 2.0)
    (kept,), (why,) = cut_segment(seg, t, np.zeros(t.size, dtype=bool), speed, F, DetectorConfig())
    assert kept.t0 == 10.0 and kept.t1 == pytest.approx(27.5, abs=1e-9)
    assert "after its end" in why and "m/s" in why


def test_a_still_neighbourhood_cuts_nothing():
    seg, t = segment(10.0, 30.0)
    speed = (np.arange(0.0, 60.0, 0.1), np.zeros(600))
    kept, why = cut_segment(seg, t, np.zeros(t.size, dtype=bool), speed, F, DetectorConfig())
    assert kept == [seg] and why == []


def test_end_trimmed_cuts_the_measured_lag_or_drops_a_short_stop():
    seg, t = segment(10.0, 30.0)
    s = end_trimmed(seg, t, STREAM_END_TRIM_S, 2.0)
    assert (s.t0, s.i0) == (seg.t0, seg.i0) and s.t1 == pytest.approx(30.0 - STREAM_END_TRIM_S)
    assert s.i1 - s.i0 == t.size - round(STREAM_END_TRIM_S * F)
    short, ts = segment(10.0, 12.3)
    assert end_trimmed(short, ts, STREAM_END_TRIM_S, 2.0) is None
