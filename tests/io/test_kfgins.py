"""KF-GINS text readers/writers: round trips, gzip, time checks, bad input, the shared real drive."""

from __future__ import annotations

import gzip
import warnings

import numpy as np
import pytest

from imunoise.errors import DataError
from imunoise.io.kfgins import (
    DataWarning,
    GnssData,
    ImuData,
    Reference,
    read_gnss,
    read_imu,
    read_outages,
    read_reference,
    write_gnss,
    write_imu,
    write_outages,
    write_reference,
)


def _imu(n: int = 500, seed: int = 1) -> ImuData:
    rng = np.random.default_rng(seed)
    t = 243000.0 + np.arange(n) * 0.01 + rng.uniform(-1e-3, 1e-3, n)
    return ImuData(t=t, dtheta=rng.normal(0, 1e-3, (n, 3)), dv=rng.normal(0, 0.1, (n, 3)))


def _gnss(n: int = 50) -> GnssData:
    rng = np.random.default_rng(2)
    t = 243000.0 + np.arange(n) * 1.0
    lat = np.radians(40.1 + rng.normal(0, 1e-3, n))
    lon = np.radians(-105.1 + rng.normal(0, 1e-3, n))
    llh = np.column_stack([lat, lon, 1600 + t - t[0]])
    return GnssData(t=t, llh=llh, sigma_ned=np.tile([0.5, 0.6, 1.2], (n, 1)))


def _ref(n: int = 40) -> Reference:
    g = _gnss(n)
    rng = np.random.default_rng(3)
    euler = rng.uniform(-3, 3, (n, 3))
    euler[:5] = np.nan
    return Reference(t=g.t, llh=g.llh, vel_ned=rng.normal(0, 5, (n, 3)), euler=euler, week=np.full(n, 2374))


@pytest.mark.parametrize("suffix", [".txt", ".txt.gz"])
def test_round_trips_exact_to_written_precision(tmp_path, suffix):
    imu, gnss, ref = _imu(), _gnss(), _ref()
    i2 = read_imu(write_imu(tmp_path / f"imu{suffix}", imu))
    np.testing.assert_allclose(i2.t, imu.t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(i2.dtheta, imu.dtheta, rtol=1e-12, atol=0)
    np.testing.assert_allclose(i2.dv, imu.dv, rtol=1e-12, atol=0)
    g2 = read_gnss(write_gnss(tmp_path / f"gnss{suffix}", gnss))
    np.testing.assert_allclose(g2.llh[:, :2], gnss.llh[:, :2], rtol=0, atol=np.radians(1e-12))
    np.testing.assert_allclose(g2.llh[:, 2], gnss.llh[:, 2], rtol=0, atol=1e-6)
    np.testing.assert_allclose(g2.sigma_ned, gnss.sigma_ned, rtol=0, atol=1e-6)
    r2 = read_reference(write_reference(tmp_path / f"ref{suffix}", ref))
    assert np.array_equal(r2.week, ref.week)
    np.testing.assert_allclose(r2.vel_ned, ref.vel_ned, rtol=0, atol=1e-9)
    np.testing.assert_allclose(r2.euler, ref.euler, rtol=0, atol=np.radians(1e-9))
    assert np.isnan(r2.euler[:5]).all()
    if suffix.endswith(".gz"):
        with gzip.open(tmp_path / f"imu{suffix}", "rt") as fh:
            assert len(fh.readline().split()) == 7


def test_outages_round_trip_and_comments(tmp_path):
    p = write_outages(tmp_path / "o.txt", [(10.0, 60.0), (200.5, 30.0)])
    assert read_outages(p) == [(10.0, 60.0), (200.5, 30.0)]
    p.write_text("# start dur\n\n5 10  # first\n  20,5\n")
    assert read_outages(p) == [(5.0, 10.0), (20.0, 5.0)]
    p.write_text("5 0\n")
    with pytest.raises(DataError, match="line 1"):
        read_outages(p)


def test_rate_csv_becomes_increments(tmp_path):
    t = np.array([0.0, 0.01, 0.03, 0.04])
    g = np.array([[1.0, 2.0, 3.0]] * 4)
    a = np.array([[0.0, 0.0, -9.8]] * 4)
    p = tmp_path / "rate.csv"
    rows = "\n".join(",".join(f"{v:g}" for v in (t[k], *g[k], *a[k])) for k in range(4))
    p.write_text("sow,gx,gy,gz,ax,ay,az\n" + rows + "\n")
    imu = read_imu(p, time_offset=-0.125)
    dt = np.array([0.01, 0.01, 0.02, 0.01])  # first Δt is the median step
    np.testing.assert_allclose(imu.t, t - 0.125)
    np.testing.assert_allclose(imu.dtheta, g * dt[:, None])
    np.testing.assert_allclose(imu.dv, a * dt[:, None])
    gyro, acc = imu.rates()
    np.testing.assert_allclose(gyro, g)
    np.testing.assert_allclose(acc, a)
    assert imu.kind == "increments" and imu.frame == "FRD"


def _write_lines(p, rows):
    p.write_text("\n".join(" ".join(f"{v:.6f}" for v in r) for r in rows) + "\n")
    return p


def test_imu_time_checks(tmp_path):
    rows = np.column_stack([np.arange(20) * 0.01, np.zeros((20, 6))])
    bad = rows.copy()
    bad[7, 0] = 0.0
    with pytest.raises(DataError, match="line 8.*backwards"):
        read_imu(_write_lines(tmp_path / "b.txt", bad))
    dup = rows.copy()
    dup[8, 0] = dup[7, 0]
    dup[9, 0] = dup[7, 0]
    with pytest.warns(DataWarning, match="dropped 2 rows"):
        imu = read_imu(_write_lines(tmp_path / "d.txt", dup))
    assert len(imu) == 18 and np.all(np.diff(imu.t) > 0)
    gap = rows.copy()
    gap[10:, 0] += 0.5
    with pytest.warns(DataWarning, match=r"1 time gaps.*largest is 0\.51"):
        read_imu(_write_lines(tmp_path / "g.txt", gap))
    nan = rows.copy()
    nan[4, 3] = np.nan
    p = tmp_path / "n.txt"
    _write_lines(p, nan)
    p.write_text("# comment line\n" + p.read_text())
    with pytest.raises(DataError, match="line 6"):
        read_imu(p)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_imu(_write_lines(tmp_path / "ok.txt", rows))


def test_bad_columns_and_files(tmp_path):
    p = tmp_path / "x.txt"
    p.write_text("0 1 2 3 4 5\n0.01 1 2 3 4 5\n")
    with pytest.raises(DataError, match="7"):
        read_imu(p)
    p.write_text("0 1 2 3 4 5 6 7\n0.01 1 2 3 4 5 6 7\n")
    with pytest.warns(DataWarning, match="first 7"):
        assert read_imu(p).dv[1, 2] == 6.0
    p.write_text("0 1 2 3 4 5 6\n0.01 1 2 3 4 5\n")
    with pytest.raises(DataError, match="line 2"):
        read_imu(p)
    p.write_text("0 1 2 3 4 5 6\n0.01 1 2 abc 4 5 6\n")
    with pytest.raises(DataError, match="line 2"):
        read_imu(p)
    p.write_text("# nothing\n")
    with pytest.raises(DataError, match="no data"):
        read_gnss(p)
    p.write_text("time,foo\n1,2\n")
    with pytest.raises(DataError, match="sow,gx"):
        read_imu(p)
    with pytest.raises(FileNotFoundError):
        read_imu(tmp_path / "missing.txt")


def test_gnss_sigma_handling(tmp_path):
    p = tmp_path / "g.txt"
    p.write_text("1 40 -105 1600\n2 40 -105 1601\n")
    with pytest.warns(DataWarning, match="default"):
        g = read_gnss(p, default_sigma=(2.0, 3.0, 4.0))
    np.testing.assert_allclose(g.sigma_ned, [[2, 3, 4]] * 2)
    np.testing.assert_allclose(g.llh[0], [np.radians(40), np.radians(-105), 1600])
    p.write_text("1 40 -105 1600 0 0.01 0.02\n2 40 -105 1601 0.01 0.01 0.02\n")
    with pytest.warns(DataWarning, match="raised to"):
        g = read_gnss(p)
    assert (g.sigma_ned > 0).all()
    p.write_text("1 40 -105 1600 -1 0.01 0.02\n")
    with pytest.raises(DataError, match="negative"):
        read_gnss(p)
    p.write_text("1 40 -105 1600 nan 0.01 0.02\n")
    with pytest.raises(DataError, match="line 1"):
        read_gnss(p)


def test_gnss_without_and_slices():
    g = _gnss(50)
    t0 = g.t[0]
    h = g.without([(t0 + 10, 5), (t0 + 30, 1)])
    assert len(h) == 50 - 6
    assert not np.isin(t0 + np.array([10, 14, 30]), h.t).any()
    assert np.isin(t0 + np.array([9, 15, 31]), h.t).all()
    assert len(g.slice(t0 + 1, t0 + 3)) == 3
    imu = _imu(100)
    s = imu.slice(imu.t[10], imu.t[19])
    assert len(s) == 10 and np.array_equal(s.dtheta, imu.dtheta[10:20])
    assert len(_ref().slice(t0, t0 + 4)) == 5


def test_reference_nan_only_in_attitude(tmp_path):
    p = tmp_path / "r.nav"
    p.write_text("0 1 40 -105 1600 0 0 0 nan nan nan\n0 2 40 -105 1600 nan 0 0 0 0 0\n")
    with pytest.raises(DataError, match="line 2"):
        read_reference(p)


def test_real_drive_counts(shared_data):
    conv = ("rtklibexplorer_drive0708", "converted")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the real files are clean: no duplicates, no gaps
        imu = read_imu(shared_data(*conv, "imu_body_inc.txt.gz"))
        gnss = read_gnss(shared_data(*conv, "gnss_rtk.txt"))
        ref = read_reference(shared_data(*conv, "ref_rtk.nav.gz"))
    assert len(imu) == 54858 and len(gnss) == 2197 and len(ref) == 2197
    assert imu.t[0] == pytest.approx(243261.729) and 99 < imu.rate_hz < 101
    np.testing.assert_allclose(np.degrees(gnss.llh[0, :2]), [40.0966268, -105.1474483], atol=1e-9)
    assert np.isnan(ref.euler).all() and (ref.week == 0).all()
    # the rate CSV holds the same samples (its stamps are rounded to 1 ms, hence the loose tolerance)
    rate = read_imu(shared_data(*conv, "imu_body_rate.csv.gz"))
    assert len(rate) == len(imu)
    np.testing.assert_allclose(rate.rates()[1].mean(0), imu.rates()[1].mean(0), atol=2e-3)
    wins = read_outages(shared_data(*conv, "outages_60s.txt"))
    assert wins[0] == (243310.0, 60.0) and len(wins) == 5
    assert len(gnss.without(wins)) == 2197 - 5 * 240
