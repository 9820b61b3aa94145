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


class ImunoiseWarning(UserWarning):
    """Base class of the warnings imunoise gives about a problem it handled (``warnings.warn`` with one of the
    classes below; the CLI shows each as one line). Filter them all with
    ``warnings.simplefilter("ignore", ImunoiseWarning)``."""


class DataWarning(ImunoiseWarning):
    """A data problem that was handled (duplicates dropped, gaps found, default σ used)."""


class TimingWarning(ImunoiseWarning):
    """A time-stamp problem that was handled: unsorted stamps sorted, duplicates dropped, gaps found."""


class UnitWarning(ImunoiseWarning):
    """The units of the data are doubtful: no unit given and the values cannot be SI, or the file and
    the command line disagree."""


class CutLineWarning(ImunoiseWarning):
    """A cut first or last line of a table (a logger started or stopped mid-write) was skipped."""
