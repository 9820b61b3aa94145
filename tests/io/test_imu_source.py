"""One IMU source value (ImuSource): one default per reader setting, the same reading through the value as
through the readers' keywords, and the CLI's options carried in it."""

from __future__ import annotations

import argparse
import inspect

import numpy as np
import pytest

from imunoise.calibrate.logs import read_log
from imunoise.calibrate.stream import stream_stops
from imunoise.cli.options import imu_source
from imunoise.errors import DataError
from imunoise.io.imu_input import read_imu_source
from imunoise.io.imu_source import SOURCE_FIELDS, UNSET, ImuSource
from imunoise.io.imu_stream import open_imu_blocks

READERS = (read_imu_source, open_imu_blocks, read_log, stream_stops)


def _csv(path, n=3000, rate=100.0, t_scale=1.0, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate * t_scale
    x = rng.normal(size=(n, 6)) * [1e-3, 1e-3, 1e-3, 1e-2, 1e-2, 1e-2] + [0, 0, 0, 0, 0, -9.8]
    np.savetxt(path, np.column_stack([x, t]), delimiter=",", header="gx,gy,gz,ax,ay,az,ts", comments="",
               fmt="%.17g")
    return path


COLS = {"gyro_x": "gx", "gyro_y": "gy", "gyro_z": "gz", "accel_x": "ax", "accel_y": "ay", "accel_z": "az"}


def test_every_reader_takes_its_defaults_from_imu_source():
    """The reader keywords default to UNSET (the ImuSource field's default), so the defaults are written once;
    before, time_unit defaulted to None in two readers and to "s" in two others."""
    for f in READERS:
        params = inspect.signature(f).parameters
        own = {k: params[k].default for k in SOURCE_FIELDS if k in params}
        assert own and all(v is UNSET for v in own.values()), (f.__name__, own)
        assert list(params)[0] == "path"
    src = ImuSource("x.csv")
    assert (src.topic, src.columns, src.units, src.time_column, src.time_unit, src.freq, src.stamps) == (
        None, None, None, None, "s", None, "header")
    assert ImuSource.of("x.csv", time_unit=UNSET, freq=UNSET) == src
    assert ImuSource.of(src, freq=200.0) == ImuSource("x.csv", freq=200.0)
    assert ImuSource.of(src) is src
    assert set(src.reader_args()) == set(SOURCE_FIELDS)


def test_the_value_reads_as_the_keywords(tmp_path):
    p = _csv(tmp_path / "imu.csv")
    by_kw = read_imu_source(p, columns=COLS, time_column="ts")
    src = ImuSource(p, columns=COLS, time_column="ts")
    by_value = read_imu_source(src)
    assert by_value.source == by_kw.source and by_value.freq == by_kw.freq == pytest.approx(100.0)
    for a in COLS:
        np.testing.assert_array_equal(by_value.data[a], by_kw.data[a])
    # a keyword given with a value replaces that field
    assert read_imu_source(src, freq=100.0).freq == by_kw.freq
    units = {"gyro": "rad/s", "accel": "m/s²"}
    log_kw = read_log(p, columns=COLS, units=units, time_column="ts")
    log_value = read_log(ImuSource.of(src, units=units))
    assert log_kw.name == log_value.name == str(p)
    np.testing.assert_array_equal(log_kw.gyro, log_value.gyro)
    np.testing.assert_array_equal(log_kw.t, log_value.t)
    blocks = open_imu_blocks(src)
    assert blocks.n_estimate > 0


def test_time_unit_default_and_explicit_inference(tmp_path):
    """The one default, seconds, refuses stamps that are not an IMU rate in seconds (naming --time-unit); an
    explicit None infers the unit from the spacing."""
    p = _csv(tmp_path / "ms.csv", t_scale=1000.0)  # stamps in ms in a column whose name says no unit
    with pytest.raises(DataError, match="--time-unit ms"):
        read_imu_source(p, columns=COLS, time_column="ts")
    with pytest.warns(Warning, match="taken as ms"):
        s = read_imu_source(p, columns=COLS, time_column="ts", time_unit=None)
    assert s.freq == pytest.approx(100.0)
    assert read_imu_source(p, columns=COLS, time_column="ts", time_unit="ms").freq == pytest.approx(100.0)


def test_cli_options_become_one_source(tmp_path):
    args = argparse.Namespace(topic="/imu", columns="gyro_x=gx,gyro_y=gy", units="gyro=deg/s,accel=g",
                              time_column="ts", time_unit="ms", freq=200.0, stamps="bag", out="o")
    src = imu_source(args, "a.bag")
    assert src == ImuSource("a.bag", topic="/imu", columns={"gyro_x": "gx", "gyro_y": "gy"},
                            units={"gyro": "deg/s", "accel": "g"}, time_column="ts", time_unit="ms", freq=200.0,
                            stamps="bag")
    # a command without some of the options: their defaults; an override wins
    few = argparse.Namespace(freq=None, units=None, columns=None)
    assert imu_source(few, "b.csv", columns=["gx"]) == ImuSource("b.csv", columns=["gx"])
