"""CSV/TXT readers: column mapping, units to SI, time column, rate/jitter/gap checks, decimation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imunoise.errors import DataError, UnitError
from imunoise.io.imu_input import decimate, read_imu_source
from imunoise.io.tabular import TimingWarning, clean_time, read_columns, read_series, read_table
from imunoise.units import G0


def _write_csv(path, header, data, fmt="%.17g"):
    np.savetxt(path, data, delimiter=",", header=",".join(header), comments="", fmt=fmt)
    return path


def test_read_series_keeps_api_and_converts(tmp_path):
    x = np.array([1.0, -2.0, 0.5, 4.0])
    p = _write_csv(tmp_path / "a.csv", ["t", "gx"], np.column_stack([np.arange(4) * 0.01, x]))
    s = read_series(p, column="gx", units="deg/s")
    assert s.unit == "rad/s" and s.source_unit == "deg/s" and s.name == "gx"
    np.testing.assert_allclose(s.values, x * math.pi / 180, rtol=0, atol=0)
    with pytest.raises(DataError, match="columns are"):
        read_series(p, column="nope")
    assert read_table(p).columns == ["t", "gx"]


def test_read_columns_mapping_units_and_ns_time(tmp_path):
    n = 50
    t_ns = 1_700_000_000_000_000_000 + np.arange(n, dtype=np.int64) * 5_000_000  # 200 Hz in ns
    gx, az = np.linspace(-1, 1, n), np.linspace(0.9, 1.1, n)
    p = tmp_path / "imu.csv"
    with open(p, "w") as fh:
        fh.write("# exported by a logger\nstamp,gx,junk,az\n")
        for k in range(n):
            fh.write(f"{t_ns[k]},{float(gx[k])!r},7,{float(az[k])!r}\n")
    cols = read_columns(
        p, "gyro_x=gx,accel_z=3", units={"gyro": "deg/s", "accel": "g"}, time_column="stamp", time_unit="ns"
    )
    assert cols.names == ["gyro_x", "accel_z"]
    np.testing.assert_array_equal(cols.values["gyro_x"], gx * (math.pi / 180))
    np.testing.assert_array_equal(cols.values["accel_z"], az * G0)
    assert cols.unit == {"gyro_x": "rad/s", "accel_z": "m/s²"}
    assert cols.source_unit == {"gyro_x": "deg/s", "accel_z": "g"}
    assert cols.report.rate_hz == 200.0 and cols.report.n_duplicates == 0
    with pytest.raises(UnitError, match="unknown unit"):
        read_columns(p, ["gx"], units="furlong/s")
    with pytest.raises(DataError, match="the time stamps give 200 Hz"):
        read_columns(p, ["gx"], time_column="stamp", time_unit="ns", freq=100.0)


def test_clean_time_sorts_drops_duplicates_reports_gaps_and_jitter():
    t = np.arange(100) * 0.01
    t = np.concatenate([t[:40], t[45:]])  # a gap of 6 steps
    t = np.insert(t, 10, t[10])  # one duplicate
    t[[20, 21]] = t[[21, 20]]  # one swap
    with pytest.warns(TimingWarning) as rec:
        idx, rep = clean_time(t, source="x")
    msgs = " ".join(str(w.message) for w in rec)
    assert "sorted" in msgs and "duplicated" in msgs and "gaps" in msgs
    assert rep.n_duplicates == 1 and rep.n_unsorted == 1 and rep.n_gaps == 1
    assert rep.largest_gap_s == pytest.approx(0.06)
    assert np.all(np.diff(t[idx]) > 0) and idx.size == 95
    assert rep.rate_hz == pytest.approx(100.0) and rep.jitter_s < 1e-12
    rng = np.random.default_rng(0)
    tj = np.arange(20000) * 0.01 + rng.normal(0, 1e-4, 20000)  # 1 % jitter
    _, rj = clean_time(tj)
    assert rj.jitter_rel == pytest.approx(0.01 * math.sqrt(2), rel=0.05)  # steps difference two stamps


def test_increments_become_rates_with_nominal_step(tmp_path):
    dth = np.array([1e-3, 2e-3, -1e-3, 5e-4])
    dv = np.array([0.098, 0.1, 0.097, 0.099])
    p = _write_csv(tmp_path / "inc.txt", ["dthx", "dvz"], np.column_stack([np.degrees(dth), dv]))
    s = read_imu_source(
        p, columns={"gyro_x": "dthx", "accel_z": "dvz"}, units={"gyro": "deg", "accel": "m/s"}, freq=100
    )
    np.testing.assert_allclose(s.data["gyro_x"], dth * 100, rtol=1e-15)
    np.testing.assert_allclose(s.data["accel_z"], dv * 100, rtol=1e-15)
    assert s.unit == {"gyro_x": "rad/s", "accel_z": "m/s²"}
    with pytest.raises(DataError, match="--freq"):
        read_imu_source(p, columns=["dthx"])


def test_decimation_average_keeps_noise_density_and_drop_is_refused():
    f, k, sigma = 200.0, 8, 0.3
    x = np.random.default_rng(3).normal(0, sigma, 2**18)
    y = decimate(x, k)
    n_in = np.std(x) / math.sqrt(f)
    n_out = np.std(y) / math.sqrt(f / k)  # N = σ·√Δt at the new rate
    assert n_out == pytest.approx(n_in, rel=0.03)
    kept = x[::k]  # what dropping would do: N inflated by √k
    assert np.std(kept) / math.sqrt(f / k) == pytest.approx(math.sqrt(k) * n_in, rel=0.03)
    with pytest.raises(DataError, match=r"√8"):
        decimate(x, k, "drop")
    np.testing.assert_array_equal(decimate(np.arange(10.0), 3), [1.0, 4.0, 7.0])


def test_a_cut_first_or_last_line_is_skipped_with_a_warning(tmp_path):
    """A logger started or stopped mid-write (rtklibexplorer walk0827's raw IMU has both): the cut lines are
    skipped, the rows in between read exactly; a ragged line inside the file is still an error."""
    import warnings

    from imunoise.io.tabular import CutLineWarning

    rng = np.random.default_rng(0)
    full = rng.normal(size=(30, 7)).round(6)
    lines = [",".join(f"{v:.6f}" for v in row) for row in full]
    cut = [lines[0].rsplit(",", 1)[0]] + lines[1:-1] + [",".join(lines[-1].split(",")[:5])]
    p = tmp_path / "cut.csv"
    p.write_text("\n".join(cut) + "\n")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        t = read_table(p)
    assert [str(w.message).split(":")[0].split(", ")[-1] for w in caught if w.category is CutLineWarning] == \
        ["line 1", "line 30"]
    np.testing.assert_array_equal(t.data, full[1:-1])
    assert len(t.columns) == 7
    inner = lines[:10] + [lines[10].rsplit(",", 1)[0]] + lines[11:]
    p.write_text("\n".join(inner) + "\n")
    with pytest.raises(DataError, match="line 11: 6 fields, expected 7"):
        read_table(p)
