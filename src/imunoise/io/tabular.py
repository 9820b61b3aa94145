"""Generic tabular readers: CSV/TXT (with or without a header) and NumPy ``.npy``/``.npz``
(docs/guide/theory.rst, 'Interfaces').

The reader picks the delimiter (comma, semicolon, tab or white space), skips ``#`` comments, finds a
header line if there is one, and returns float columns. Bad cells, NaN and Inf are reported with the
file line they are on, so the user can find them.

:func:`read_columns` maps several columns (by name or 0-based index) to output names with a unit per
column (docs/guide/theory.rst, 'Conventions': converted to SI at the boundary) and an optional time column in
s/ms/µs/ns;
:func:`clean_time` sorts the stamps, drops and counts duplicates, reports gaps and the sampling jitter and
infers (or checks) the sample rate. The same report is used by the ROS bag reader.

Modules: :mod:`imunoise.io.table` (tables and single series), :mod:`imunoise.io.time_stamps` (time stamps)
and :mod:`imunoise.io.columns` (several columns with units); every name below is importable from here.
"""

from __future__ import annotations

from imunoise.io.columns import (
    Columns,
    UnitWarning,
    column_pairs,
    parse_column_map,
    read_columns,
    stamp_step,
    time_index,
    unit_for,
)
from imunoise.io.table import CutLineWarning, Series, Table, parse_rows, read_series, read_table
from imunoise.io.time_stamps import GAP_FACTOR, RATE_TOLERANCE, TimeReport, TimingWarning, clean_time

__all__ = [
    "Table",
    "read_table",
    "read_series",
    "Series",
    "TimeReport",
    "TimingWarning",
    "CutLineWarning",
    "parse_rows",
    "UnitWarning",
    "clean_time",
    "Columns",
    "read_columns",
    "unit_for",
    "parse_column_map",
    "column_pairs",
    "time_index",
    "stamp_step",
    "GAP_FACTOR",
    "RATE_TOLERANCE",
]
