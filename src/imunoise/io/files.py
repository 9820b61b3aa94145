"""Reading a text or JSON input file with one clear error naming the file (issue "Trustworthy outputs" §3).

Binary junk, a truncated or corrupt ``.gz``, a folder or an unreadable path given where a text file is
expected become :class:`~imunoise.errors.DataError` (or the ``error`` type asked for) with the file name
and what to do, instead of ``UnicodeDecodeError``/``EOFError``/``zlib.error`` tracebacks.
"""

from __future__ import annotations

import gzip
import json
import zlib
from pathlib import Path
from typing import Any

from imunoise.errors import DataError, ImunoiseError

__all__ = ["read_text", "read_json", "looks_binary", "is_number"]

_BINARY_SNIFF = 8192


def looks_binary(raw: bytes) -> bool:
    """True when the first bytes hold a NUL or mostly control bytes (not a text table in any encoding)."""
    head = raw[:_BINARY_SNIFF]
    if b"\x00" in head:
        return True
    if not head:
        return False
    ctrl = sum(1 for b in head if b < 32 and b not in (9, 10, 12, 13))
    return ctrl > 0.05 * len(head)


def read_text(
    path: str | Path,
    what: str = "input",
    error: type[ImunoiseError] = DataError,
    expected: str = "a CSV/TXT table (or .npy/.npz for NumPy arrays)",
) -> str:
    """The text of ``path`` (gunzipped when the name ends in ``.gz``), UTF-8 or else Latin-1.

    Parameters
    ----------
    path : str or Path
        A text file, optionally gzip-compressed (``.gz``).
    what : str
        What the file is, for the message (``"IMU file"``, ``"--init"``).
    error : type
        The :class:`~imunoise.errors.ImunoiseError` subclass to raise.
    expected : str
        What the user should give instead, for the message about a binary file.

    Returns
    -------
    str
        The decoded text.
    """
    path = Path(path)
    if not path.exists():
        raise error(f"{what} {path}: no such file")
    if path.is_dir():
        raise error(f"{what} {path} is a folder; give a file")
    try:
        # the head first: a binary (or sparse, all-NUL) file of any size is refused before it is read whole
        with (gzip.open(path, "rb") if path.suffix == ".gz" else open(path, "rb")) as fh:
            raw = fh.read(_BINARY_SNIFF)
            if looks_binary(raw):
                raise error(f"{what} {path} is not a text file (binary content near the start); give {expected}")
            raw += fh.read()
    except EOFError as exc:
        raise error(
            f"{what} {path}: the gzip stream ends early (truncated download or copy?); get the file again"
        ) from exc
    except (gzip.BadGzipFile, zlib.error) as exc:
        raise error(f"{what} {path}: not a valid gzip file ({exc}); decompress it or fix the name") from exc
    except PermissionError as exc:
        raise error(f"{what} {path}: permission denied; check the file's read permission") from exc
    except OSError as exc:
        raise error(f"{what} {path}: cannot read ({exc.strerror or exc})") from exc
    if looks_binary(raw):
        raise error(
            f"{what} {path} is not a text file (binary content near the start); give {expected}"
        )
    try:
        return raw.decode("utf-8-sig")  # a byte-order mark (Excel's "CSV UTF-8") is not part of the text
    except UnicodeDecodeError:
        # no NUL and few control bytes: a legacy 8-bit text (e.g. a '°' in a Latin-1 header)
        return raw.decode("latin-1")


def read_json(path: str | Path, what: str = "JSON file", error: type[ImunoiseError] = DataError) -> Any:
    """Parse the JSON file ``path``; any unreadable, binary or malformed file raises ``error`` naming it."""
    text = read_text(path, what, error, expected="a JSON file")
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise error(f"{what} {path}: not valid JSON ({exc})") from exc


def is_number(tok: str) -> bool:
    """True when ``tok`` parses as a float (a data token, not a header word)."""
    try:
        float(tok)
    except ValueError:
        return False
    return True
