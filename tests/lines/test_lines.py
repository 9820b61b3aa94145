"""Narrowband lines: none found on broadband records, a sinusoid and a hump found with their share and
removed to the floor, the broadband noise kept."""

import numpy as np
import pytest

from imunoise.lines import find_lines, remove_lines, suppress_lines
from imunoise.lines.detect import Line

F = 100.0


def _broadband(seed: int, n: int = 2**18, ar1: bool = False) -> np.ndarray:
    rng = np.random.default_rng(seed)
    x = 0.1 * rng.standard_normal(n) + np.cumsum(2e-4 * rng.standard_normal(n))
    if ar1:  # a Gauss-Markov knee at ~0.16 Hz
        from scipy.signal import lfilter

        x = x + lfilter([1.0], [1.0, -0.99], 0.02 * rng.standard_normal(n))
    return x


@pytest.mark.parametrize("seed", range(3700, 3710))
def test_broadband_records_hold_no_line_and_are_left_alone(seed):
    x = _broadband(seed, ar1=seed % 2 == 1)
    assert find_lines(x, F) == []
    assert suppress_lines(x, F, []) is x


def test_a_sinusoid_is_found_with_its_share_and_removed():
    rng = np.random.default_rng(3720)
    n = 2**18
    white = 0.1 * rng.standard_normal(n)
    t = np.arange(n) / F
    line = 0.05 * np.sin(2 * np.pi * 10.0 * t + 0.3)
    x = white + line
    found = find_lines(x, F, unit="rad/s")
    assert len(found) == 1
    ln = found[0]
    assert abs(ln.freq_hz - 10.0) < 0.05
    truth = 0.05**2 / 2 / x.var()
    assert ln.share == pytest.approx(truth, rel=0.1)
    assert ln.rms == pytest.approx(0.05 / np.sqrt(2), rel=0.1)
    y = suppress_lines(x, F, found)
    assert find_lines(y, F) == []
    # the line's power is gone, the white noise's stays (its variance within 1 %)
    assert np.var(y) == pytest.approx(np.var(white), rel=0.01)
    assert np.mean(y) == pytest.approx(np.mean(x), abs=1e-12)


def test_a_hump_is_one_line_and_round_trips_through_its_dict():
    from scipy.signal import butter, sosfilt

    rng = np.random.default_rng(3721)
    n = 2**18
    sos = butter(4, [17.0, 22.0], btype="band", fs=F, output="sos")
    hump = sosfilt(sos, rng.standard_normal(n)) * 0.3
    white = 0.05 * rng.standard_normal(n)
    x = white + hump
    found = find_lines(x, F)
    assert len(found) == 1 and 17.0 < found[0].freq_hz < 22.0
    assert found[0].share == pytest.approx(np.var(hump) / np.var(x), rel=0.1)
    assert Line.from_dict(found[0].to_dict()) == found[0]
    y = suppress_lines(x, F, found)
    assert np.var(y) == pytest.approx(np.var(white), rel=0.03)
    z, again = remove_lines(x, F)
    assert find_lines(z, F) == [] and again[0].freq_hz == found[0].freq_hz
    assert remove_lines(white, F) == (white, [])


def test_vibration_in_the_stops_is_named_pooled_over_them():
    from imunoise.lines.detect import pooled_lines

    rng = np.random.default_rng(3722)
    stops = []
    for k in range(6):  # 6 stops of 20-40 s, an engine at idle near 31 Hz with its own phase in each
        n = int((20 + 4 * k) * F)
        t = np.arange(n) / F
        stops.append(0.02 * rng.standard_normal(n) + 0.03 * np.sin(2 * np.pi * 31.0 * t + k))
    found = pooled_lines(stops, F, unit="m/s^2")
    assert len(found) == 1 and abs(found[0].freq_hz - 31.0) < 0.4
    assert found[0].share == pytest.approx(0.03**2 / 2 / (0.03**2 / 2 + 0.02**2), rel=0.15)
    quiet = [0.02 * rng.standard_normal(int(30 * F)) for _ in range(6)]
    assert pooled_lines(quiet, F) == []
    assert pooled_lines([np.zeros(10)], F) == []
