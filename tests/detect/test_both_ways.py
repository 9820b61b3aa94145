"""Static detection both ways (:func:`imunoise.detect.both_ways.detect_static_both_ways`) on a synthetic
record with a slow (jerk-limited) departure: the forward pass keeps the departure's first samples, the
intersection with the time-reversed pass does not, and it is the forward pass mirrored on a mirrored record."""

from __future__ import annotations

import numpy as np

from imunoise.detect import DetectorConfig, detect_static
from imunoise.detect.both_ways import detect_static_both_ways, segments_of_mask

F = 100.0


def record(seed: int = 3):
    """10 s moving, 30 s still, then a departure whose forward acceleration ramps at 0.3 m/s³ (white noise
    0.01 m/s² throughout). Returns t, accel, gyro and the index of the first moving sample of the departure."""
    rng = np.random.default_rng(seed)
    n = int(60 * F)
    t = np.arange(n) / F
    acc = rng.normal(0.0, 0.01, (n, 3))
    gyro = rng.normal(0.0, 1e-3, (n, 3))
    acc[: int(10 * F), :2] += rng.normal(0.0, 0.3, (int(10 * F), 2))  # driving
    dep = int(40 * F)
    acc[dep:, 0] += 0.3 * (t[dep:] - t[dep])  # jerk-limited start
    return t, acc, gyro, dep


def test_both_ways_keeps_no_sample_of_the_departure():
    t, acc, gyro, dep = record()
    cfg = DetectorConfig(lambda0=0.03)
    fwd = detect_static(t, acc, gyro, cfg, rate_hz=F)
    both = detect_static_both_ways(t, acc, gyro, cfg, rate_hz=F)
    (sf,), (sb,) = fwd.segments, both.segments
    assert sf.i1 > dep  # the forward window lags the slow start: motion kept after the 0.5 s margin
    assert sb.i1 <= dep  # both ways: the stop ends before the departure
    assert sb.i0 == sf.i0  # the start is the forward pass's (the reversed one starts earlier)
    assert both.static.sum() == sb.i1 - sb.i0 and both.static[sb.i0 : sb.i1].all()


def test_both_ways_is_symmetric_in_time():
    """Detecting both ways a time-reversed record gives the reversed segments: no direction is preferred."""
    t, acc, gyro, _ = record()
    cfg = DetectorConfig(lambda0=0.03)
    a = detect_static_both_ways(t, acc, gyro, cfg, rate_hz=F)
    b = detect_static_both_ways(-t[::-1], acc[::-1], gyro[::-1], cfg, rate_hz=F)
    np.testing.assert_array_equal(a.static, b.static[::-1])


def test_segments_of_mask_keeps_runs_long_enough():
    t = np.arange(10) / 2.0  # 0 .. 4.5 s
    m = np.array([1, 1, 1, 0, 1, 1, 1, 1, 1, 1], dtype=bool)
    (s,) = segments_of_mask(t, m, 2.0)
    assert (s.i0, s.i1, s.t0, s.t1) == (4, 10, 2.0, 4.5)
