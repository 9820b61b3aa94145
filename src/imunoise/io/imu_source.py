"""Where an IMU record comes from and how to read it: one value (:class:`ImuSource`) carried from the command line
through the readers (:func:`imunoise.io.imu_input.read_imu_source`, :func:`imunoise.io.imu_stream.open_imu_blocks`)
and the calibration (:func:`imunoise.calibrate.logs.read_log`, :func:`imunoise.calibrate.stream.stream_stops`),
with one default per field.

The readers keep their keyword arguments (``read_imu_source(path, columns=..., freq=...)``); a keyword not given
takes the field's default here (:data:`UNSET` marks "not given"), so the defaults are written once.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

__all__ = ["ImuSource", "UNSET", "SOURCE_FIELDS"]


class Unset:
    """The type of :data:`UNSET`."""

    def __repr__(self) -> str:
        return "UNSET"


UNSET: Any = Unset()
"""Default of a reader's keyword argument: "not given", i.e. the :class:`ImuSource` field's default."""


@dataclass(frozen=True)
class ImuSource:
    """An IMU record and how to read it.

    Parameters
    ----------
    path : str or Path
        A ROS bag (``.bag``, ``.db3``, ``.mcap``, ROS 2 folder) or a table (CSV/TXT, ``.npy``, ``.npz``); kept
        as given (the outputs name the log so).
    topic : str, optional
        Bag: the ``sensor_msgs/Imu`` topic (default: the only one).
    columns : optional
        Table: which columns are read and as which axes (:func:`imunoise.io.tabular.read_columns`: a name, an
        index, a list, or ``{"gyro_x": "gx", ...}``); bag: a subset of the six axes. Default: all.
    units : optional
        Table: the unit of each column (one for all, or per column/sensor); default: the unit a ``.npz`` states,
        else as is.
    time_column : str or int, optional
        Table: the time stamp column; default: a column named like one (``t``, ``time``, ``stamp``, ...).
    time_unit : str or None
        Unit of ``time_column`` (s, ms, us, ns; default ``"s"``; a column found by its name, or whose name says
        its unit, is read in that unit). None: inferred from the stamp spacing.
    freq : float, optional
        Sample rate [Hz], needed when there are no stamps; checked against them when there are.
    stamps : str
        Bag: ``"header"`` (default) or ``"bag"`` (receive time).
    """

    path: str | Path
    topic: str | None = None
    columns: str | int | Sequence[str | int] | Mapping[str, str | int] | None = None
    units: str | Mapping[str, str] | None = None
    time_column: str | int | None = None
    time_unit: str | None = "s"
    freq: float | None = None
    stamps: str = "header"

    @classmethod
    def of(cls, source: str | Path | ImuSource, **given: Any) -> ImuSource:
        """``source`` as an :class:`ImuSource`: a path with the reader keywords ``given`` (those left
        :data:`UNSET` take the defaults), or an :class:`ImuSource` with the ``given`` fields replaced."""
        given = {k: v for k, v in given.items() if v is not UNSET}
        if isinstance(source, ImuSource):
            return replace(source, **given) if given else source
        return cls(source, **given)

    def reader_args(self) -> dict[str, Any]:
        """Every field but the path, as reader keywords (``read_imu_source(src.path, **src.reader_args())``)."""
        return {f.name: getattr(self, f.name) for f in fields(self) if f.name != "path"}


SOURCE_FIELDS = tuple(f.name for f in fields(ImuSource) if f.name != "path")
"""The reader keywords an :class:`ImuSource` holds: topic, columns, units, time_column, time_unit, freq, stamps."""
