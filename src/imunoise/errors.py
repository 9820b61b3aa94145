"""Exception types of imunoise.

Every error raised on bad input is one of these, with a message that says what was wrong and how to
fix it. The CLI turns them into a one-line message and exit code 2.
"""

from __future__ import annotations


class ImunoiseError(Exception):
    """Base class of all errors raised by imunoise on bad input or impossible requests."""


class DataError(ImunoiseError, ValueError):
    """The data cannot be used: NaN/Inf, too short, constant, unsorted time, missing column, ..."""


class ModelError(ImunoiseError, ValueError):
    """A model, configuration or option value is malformed: unparseable string, missing parameters,
    impossible, unknown or conflicting values (e.g. ``--top 0``, ``OnlineConfig(dr='x')``)."""


class UnitError(ImunoiseError, ValueError):
    """An unknown or inconsistent physical unit."""


class FitError(ImunoiseError, RuntimeError):
    """An estimator could not produce a usable result (the message says why)."""
