"""The KF-GINS text I/O fast paths. The readers' one (numpy's C parser for plain numeric tables) gives the same
doubles as the line-by-line path and leaves every file with a header, a comment, a blank line or a bad line
to that path, which names the file line; the writer's text is np.savetxt's."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from imunoise.errors import DataError
from imunoise.io import kfgins
from imunoise.io.kfgins import read_imu, read_reference

ROWS = [
    "243263.009999999776 1.2345678901234567e-05 -3.3e-310 0.1 -0.0 5e-324 9.80665",
    "243263.019999999553 0.30000000000000004 1e+308 -1.7976931348623157e308 2.5E-3 7 -8",
]


def _line_path(monkeypatch, path, what):
    with monkeypatch.context() as m:
        m.setattr(kfgins, "_plain_table", lambda text: None)
        return kfgins._read_table(path, what)


def test_fast_path_gives_the_same_doubles_as_the_line_path(tmp_path, monkeypatch):
    p = tmp_path / "imu.txt"
    p.write_text("\n".join(ROWS) + "\n")
    header, data, lines = kfgins._read_table(p, "IMU")
    _, slow, slow_lines = _line_path(monkeypatch, p, "IMU")
    assert header is None and data.tobytes() == slow.tobytes() and lines.tolist() == slow_lines.tolist() == [1, 2]
    assert kfgins._plain_table(p.read_text()) is not None  # this file took the fast path


def test_nan_attitude_reference_reads_the_same(tmp_path, monkeypatch):
    p = tmp_path / "ref.nav"
    p.write_text("2374 243263.0 40.1 -105.1 1601.5 0.1 0.2 0.3 nan nan nan\n"
                 "2374 243263.25 40.1 -105.1 1601.6 0.1 0.2 0.3 NaN -1.5 2.5\n")
    fast = kfgins._read_table(p, "reference")[1]
    assert fast.tobytes() == _line_path(monkeypatch, p, "reference")[1].tobytes()
    assert np.isnan(read_reference(p).euler[0]).all()


@pytest.mark.parametrize(
    "text",
    [
        "# comment\n" + "\n".join(ROWS) + "\n",  # comment
        ROWS[0] + "\n\n" + ROWS[1] + "\n",  # blank line
        "t dtx dty dtz dvx dvy dvz\n" + "\n".join(ROWS) + "\n",  # header
        ROWS[0].replace(" ", ",") + "\n" + ROWS[1].replace(" ", ",") + "\n",  # commas
    ],
)
def test_other_layouts_take_the_line_path(text):
    assert kfgins._plain_table(text) is None


def test_bad_line_is_named_by_the_line_path(tmp_path):
    p = tmp_path / "imu.txt"
    p.write_text(ROWS[0] + "\n" + ROWS[1] + "\n" + ROWS[1].rsplit(" ", 1)[0] + "\n")
    with pytest.raises(DataError) as exc, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        read_imu(p)
    assert str(exc.value) == (f"IMU file {p}, line 3: 6 columns where the first row has 7; "
                              "fix or remove the malformed line")


def test_writer_text_is_numpy_savetxt_text(tmp_path):
    import io

    from imunoise.io.kfgins_write import write_reference

    rng = np.random.default_rng(7)
    n = 50
    euler = rng.normal(0, 1, (n, 3))
    euler[::7] = np.nan
    ref = kfgins.Reference(t=243263.0 + np.arange(n) / 100, llh=np.column_stack([rng.normal(0.7, 1e-4, n),
                           rng.normal(-1.8, 1e-4, n), rng.normal(1600, 5, n)]), vel_ned=rng.normal(0, 9, (n, 3)),
                           euler=euler, week=np.full(n, 2374))
    write_reference(tmp_path / "r.nav", ref)
    data = np.column_stack([ref.week, ref.t, np.degrees(ref.llh[:, :2]), ref.llh[:, 2], ref.vel_ned,
                            np.degrees(ref.euler)])
    buf = io.StringIO()
    np.savetxt(buf, data, fmt=["%d", "%.9f", "%.12f", "%.12f", "%.6f"] + ["%.9f"] * 6, delimiter=" ")
    assert (tmp_path / "r.nav").read_text() == buf.getvalue()
