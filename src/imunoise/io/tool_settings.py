"""Update the IMU keys of an existing ORB-SLAM3 / OpenVINS / Kalibr file in place (docs/guide/theory.rst, 'Interfaces',
issue 22).

Appending an export to a settings file (``>> settings.yaml``) leaves two ``IMU.NoiseGyro`` keys: OpenCV 4.x
reads the first (the file's old value wins) and OpenCV 3.4 refuses the file ("Duplicated key"). Instead,
:func:`update_file` rewrites the IMU keys where they stand:

- every line that is not one of the keys written stays byte for byte (line endings included);
- a key found is rewritten on its own line (its indentation, name and the spacing after the colon kept,
  the value and the comment replaced); a later duplicate of it (an earlier ``>>``) is removed;
- a key absent is appended after the file's last IMU key (ORB-SLAM3 ``IMU.*``, OpenVINS' ``imu0`` block,
  Kalibr's noise keys), or at the end of the file when it has none;
- ``blocks`` (OpenVINS' intrinsic matrices) are added only when absent: a calibrated ``Tw`` is never touched;
- the original is kept as ``FILE.bak`` (``FILE.bak.1``, ``.2``, … when taken) and the new text is written
  atomically; a file that is not of the tool's kind, or that would miss a key the tool requires, is refused
  (:class:`~imunoise.errors.DataError`, one line) before anything is written.

What each tool reads (the reads are reproduced in ``tests/export/test_export_clients.py``):
ORB-SLAM3 v1.0 ``System.cc`` takes ``Settings`` only when ``File.version`` is the *string* "1.0", else the
legacy ``Tracking::ParseIMUParamFile``, which needs ``IMU.Frequency`` as an integer and ``Tbc``; OpenVINS
reads the ``imu0`` map of the chain file with ``cv::FileStorage``; Kalibr's ``ImuParameters`` reads the
top-level keys with PyYAML.
"""

from __future__ import annotations

import os
import re
import stat
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from imunoise.errors import DataError, ModelError
from imunoise.io.atomic import atomic_path, atomic_write_bytes

__all__ = ["SettingsFile", "IntoResult", "inspect_settings", "update_text", "update_file", "backup_path"]

KIND = {
    "orbslam3": "an ORB-SLAM3 settings file (%YAML:1.0 with Camera.* keys)",
    "openvins": "an OpenVINS IMU chain (kalibr_imu_chain.yaml with an imu0 block)",
    "kalibr": "a Kalibr imu.yaml (top-level accelerometer_/gyroscope_ keys, rostopic, update_rate)",
}
_KALIBR_NAMES = ("accelerometer_noise_density", "accelerometer_random_walk", "gyroscope_noise_density",
                 "gyroscope_random_walk", "rostopic", "update_rate")
_KEY = re.compile(r"""^(?P<indent>[ ]*)(?P<key>"[^"\n]*"|'[^'\n]*'|[A-Za-z_][\w.\-]*)[ \t]*:(?=[ \t]|\r?\n|$)""")


@dataclass(frozen=True)
class _Entry:
    """One ``key:`` line at a given indentation and the deeper lines that belong to it."""

    key: str
    start: int
    end: int


@dataclass(frozen=True)
class SettingsFile:
    """A file ``--into`` can update: its lines (line endings kept) and what was read from it.

    ``legacy`` is True for an ORB-SLAM3 file without ``File.version: "1.0"`` (the legacy reader), None for
    the other tools."""

    path: Path
    fmt: str
    lines: tuple[str, ...]
    eol: str
    legacy: bool | None = None


@dataclass(frozen=True)
class IntoResult:
    """What :func:`update_file` did: keys rewritten, appended, duplicates removed, blocks added, backup."""

    path: Path
    backup: Path | None
    updated: tuple[str, ...]
    appended: tuple[str, ...]
    duplicates_removed: tuple[str, ...]
    blocks_added: tuple[str, ...]
    legacy: bool | None
    notes: tuple[str, ...] = field(default_factory=tuple)


def _strip_quotes(key: str) -> str:
    return key[1:-1] if len(key) >= 2 and key[0] == key[-1] and key[0] in "\"'" else key


def _indent(line: str) -> int:
    return len(line) - len(line.lstrip(" "))


def _is_blank(line: str) -> bool:
    s = line.strip()
    return not s or s.startswith("#")


def _entries(lines: Sequence[str], lo: int, hi: int, indent: int) -> list[_Entry]:
    """The ``key:`` lines at exactly ``indent`` spaces in lines[lo:hi]; each owns the deeper lines after it
    (and a block sequence at its own indentation), up to its last such line."""
    out = []
    i = lo
    while i < hi:
        m = _KEY.match(lines[i])
        if m is None or len(m.group("indent")) != indent or lines[i].lstrip().startswith("#"):
            i += 1
            continue
        end = i + 1
        j = i + 1
        while j < hi:
            ln = lines[j]
            if _is_blank(ln):
                j += 1
                continue
            deeper = _indent(ln) > indent or (_indent(ln) == indent and ln.lstrip().startswith("- "))
            if not deeper:
                break
            end = j = j + 1
        out.append(_Entry(_strip_quotes(m.group("key")), i, end))
        i = end
    return out


def _top_value(lines: Sequence[str], e: _Entry) -> str:
    m = _KEY.match(lines[e.start])
    assert m is not None
    return lines[e.start][m.end():].split("#", 1)[0].strip()


def _imu0(lines: Sequence[str], path: Path) -> tuple[_Entry, int]:
    """The ``imu0`` entry of a chain and the indentation of its keys."""
    top = [e for e in _entries(lines, 0, len(lines), 0) if e.key == "imu0"]
    if not top:
        raise DataError(f"--into {path}: no imu0 block, so it is not {KIND['openvins']}; write a new one with "
                        "--out instead")
    e = top[0]
    if _top_value(lines, e):
        raise DataError(f"--into {path}: imu0 is written in flow style ({_top_value(lines, e)[:20]}...); --into "
                        "edits block style only (as OpenVINS' own files): rewrite it as one 'key: value' per line")
    child = next((_indent(ln) for ln in lines[e.start + 1:e.end] if not _is_blank(ln)), 0)
    if child == 0:
        raise DataError(f"--into {path}: the imu0 block is empty; write a new chain with --out instead")
    return e, child


def inspect_settings(path: str | Path, fmt: str) -> SettingsFile:
    """Read ``path`` and check it is a file of ``fmt``'s tool (:data:`KIND`); ORB-SLAM3 legacy detection.

    Parameters
    ----------
    path : str or Path
        The settings file to update.
    fmt : {"orbslam3", "openvins", "kalibr"}
        The tool.

    Returns
    -------
    SettingsFile

    Raises
    ------
    DataError
        Missing or unreadable file, or a file not of that tool's kind (the message says which).
    """
    path = Path(path)
    if fmt not in KIND:
        raise ModelError(f"--into works with --to orbslam3, openvins or kalibr, not {fmt!r}")
    if not path.is_file():
        raise DataError(f"--into {path}: no such file; to write a new file use --out {path}")
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise DataError(f"--into {path}: not a UTF-8 text file ({exc.reason}), so not {KIND[fmt]}") from exc
    if "\t" in "".join(ln[: _indent(ln) + 1] for ln in text.splitlines()):
        raise DataError(f"--into {path}: indented with tabs, which YAML and OpenCV refuse; fix the file first")
    lines = tuple(text.splitlines(keepends=True))
    eol = "\r\n" if "\r\n" in text else "\n"
    keys = {e.key for e in _entries(lines, 0, len(lines), 0)}
    first = next((ln.strip() for ln in lines if ln.strip()), "")
    legacy = None
    if fmt == "orbslam3":
        if not first.startswith("%YAML:1.0") or not any(k.startswith("Camera") for k in keys):
            raise DataError(f"--into {path}: not {KIND[fmt]}" + ("" if first.startswith("%YAML:1.0") else
                            ": it does not start with %YAML:1.0") + "; give the settings file ORB-SLAM3 runs with")
        version = [e for e in _entries(lines, 0, len(lines), 0) if e.key == "File.version"]
        # System.cc takes the v1.0 reader only for the *string* "1.0"; an unquoted 1.0 is a real -> legacy
        legacy = not (version and _top_value(lines, version[0]) in ('"1.0"', "'1.0'"))
    elif fmt == "openvins":
        _imu0(lines, path)
    else:
        if first.startswith("%YAML:"):
            raise DataError(f"--into {path}: starts with {first[:9]}, which Kalibr's PyYAML reader refuses, so it is "
                            f"not {KIND[fmt]}; for an OpenVINS chain use --to openvins")
        if "imu0" in keys:
            raise DataError(f"--into {path}: has an imu0 block (an IMU chain), not {KIND[fmt]}; use --to openvins")
        if not keys & set(_KALIBR_NAMES):
            raise DataError(f"--into {path}: none of {', '.join(_KALIBR_NAMES)} is in it, so it is not {KIND[fmt]}")
    return SettingsFile(path, fmt, lines, eol, legacy)


def _scalar_line(old: str, value: str, comment: str | None, eol: str) -> str:
    """``old`` with its value and comment replaced; its indentation, key and spacing after the colon kept."""
    m = _KEY.match(old)
    assert m is not None
    rest = old[m.end():].rstrip("\r\n")
    gap = rest[: len(rest) - len(rest.lstrip(" \t"))] or " "
    return old[: m.end()] + gap + value + (f"  # {comment}" if comment else "") + eol


def _new_line(indent: int, key: str, value: str, comment: str | None, eol: str) -> str:
    return " " * indent + f"{key}: {value}" + (f"  # {comment}" if comment else "") + eol


def update_text(
    sf: SettingsFile,
    scalars: Mapping[str, tuple[str, str | None]],
    *,
    blocks: Mapping[str, Sequence[str]] | None = None,
    required: Sequence[str] = (),
    anchor: str = "",
    model_keys: Sequence[str] = (),
) -> tuple[str, IntoResult]:
    """The new text of ``sf`` with ``scalars`` (key -> (value text, comment)) set and ``blocks`` (key -> lines
    below it, without indentation) added where absent (module docstring).

    Parameters
    ----------
    sf : SettingsFile
        From :func:`inspect_settings`.
    scalars : mapping
        Keys to set, in the order they are appended when absent.
    blocks : mapping, optional
        Keys with nested lines (OpenVINS' matrices) added only when absent.
    required : sequence of str
        Keys the tool needs; one absent after the update is refused.
    anchor : str
        ORB-SLAM3: prefix of the keys that form the IMU block (``"IMU."``).
    model_keys : sequence of str
        Keys a model can give (the noise keys of both sensors), to say why a required key is missing.

    Returns
    -------
    (str, IntoResult)
        The text and what changed (``backup`` None: nothing written yet).

    Raises
    ------
    DataError
        When a key the tool requires would still be missing (named in the message).
    """
    lines = list(sf.lines)
    if lines and not lines[-1].endswith(("\n", "\r")):
        lines[-1] += sf.eol
    if sf.fmt == "openvins":
        block, indent = _imu0(lines, sf.path)
        lo, hi = block.start + 1, block.end
    else:
        lo, hi, indent = 0, len(lines), 0
    entries = _entries(lines, lo, hi, indent)
    updated, removed, appended, added = [], [], [], []
    drop: set[int] = set()
    first: dict[str, _Entry] = {}
    for e in entries:
        if e.key in scalars or (blocks and e.key in blocks):
            if e.key in first:
                drop.update(range(e.start, e.end))
                removed.append(e.key)
            else:
                first[e.key] = e
    for key, (value, comment) in scalars.items():
        if key in first:
            e = first[key]
            lines[e.start] = _scalar_line(lines[e.start], value, comment, sf.eol)
            drop.update(range(e.start + 1, e.end))
            updated.append(key)
    if sf.fmt == "openvins":  # at the end of the imu0 block
        insert_at: int | None = hi
    else:  # after the last IMU key: ORB-SLAM3's IMU.* lines, Kalibr's noise keys
        ours = [e.end for e in entries if e.start not in drop
                and (e.key.startswith(anchor) if anchor else e.key in _KALIBR_NAMES)]
        insert_at = max(ours, default=None)
    new: list[str] = []
    for key, (value, comment) in scalars.items():
        if key not in first:
            new.append(_new_line(indent, key, value, comment, sf.eol))
            appended.append(key)
    for key, rows in (blocks or {}).items():
        if key not in first:
            new.append(" " * indent + f"{key}:" + sf.eol)
            new += [" " * (indent + 2) + r + sf.eol for r in rows]
            added.append(key)
    if insert_at is None:  # no IMU key in the file yet: a block of its own at the end
        while lines and not lines[-1].strip():
            lines.pop()
        insert_at = len(lines)
        if new:
            new = [sf.eol, "# IMU noise (imunoise export --into)" + sf.eol, *new]
    else:  # after the last IMU line, not after the blank lines that follow it
        while insert_at > lo and not lines[insert_at - 1].strip() and insert_at - 1 not in drop:
            insert_at -= 1
    out = [ln for i, ln in enumerate(lines[:insert_at]) if i not in drop] + new
    out += [ln for i, ln in enumerate(lines[insert_at:], start=insert_at) if i not in drop]
    text = "".join(out)
    check = inspect_settings_text(sf, text)
    missing = [k for k in required if k not in check]
    if missing:
        theirs = [k for k in missing if k not in model_keys]
        why = ("the model has no value for " + ", ".join(k for k in missing if k in model_keys) + "; " if
               len(theirs) < len(missing) else "")
        why += "the file must hold " + ", ".join(theirs) + " itself (e.g. the camera-IMU transform); " if theirs else ""
        raise DataError(f"--into {sf.path}: the result would miss {', '.join(missing)}, which the tool requires "
                        f"({why}nothing written)")
    dup = sorted(k for k, n in check.items() if n > 1 and (k in scalars or (blocks and k in blocks)))
    if dup:  # pragma: no cover - the removal above guarantees it; kept as the last guard before writing
        raise DataError(f"--into {sf.path}: duplicate keys {', '.join(dup)} after the update; nothing written")
    res = IntoResult(sf.path, None, tuple(updated), tuple(appended), tuple(removed), tuple(added), sf.legacy)
    return text, res


def inspect_settings_text(sf: SettingsFile, text: str) -> dict[str, int]:
    """How many times each key appears where the tool reads it (top level; OpenVINS: inside imu0)."""
    lines = text.splitlines(keepends=True)
    if sf.fmt == "openvins":
        block, indent = _imu0(lines, sf.path)
        entries = _entries(lines, block.start + 1, block.end, indent)
    else:
        entries = _entries(lines, 0, len(lines), 0)
    counts: dict[str, int] = {}
    for e in entries:
        counts[e.key] = counts.get(e.key, 0) + 1
    return counts


def backup_path(path: str | Path) -> Path:
    """``FILE.bak``, or ``FILE.bak.N`` with the first N ≥ 1 not taken."""
    path = Path(path)
    cand = path.with_name(path.name + ".bak")
    n = 0
    while cand.exists():
        n += 1
        cand = path.with_name(f"{path.name}.bak.{n}")
    return cand


def update_file(
    sf: SettingsFile,
    scalars: Mapping[str, tuple[str, str | None]],
    *,
    blocks: Mapping[str, Sequence[str]] | None = None,
    required: Sequence[str] = (),
    anchor: str = "",
    model_keys: Sequence[str] = (),
    notes: Sequence[str] = (),
) -> IntoResult:
    """:func:`update_text`, then the backup and the atomic write (module docstring).

    Parameters
    ----------
    sf, scalars, blocks, required, anchor, model_keys
        As for :func:`update_text`.
    notes : sequence of str
        Kept in the result (said on stderr by the CLI).

    Returns
    -------
    IntoResult
        With the backup path.
    """
    text, res = update_text(sf, scalars, blocks=blocks, required=required, anchor=anchor, model_keys=model_keys)
    original = "".join(sf.lines).encode("utf-8")
    target = sf.path.resolve()  # a symlinked settings file stays a link; the file it points to is updated
    if target.read_bytes() != original:
        raise DataError(f"--into {sf.path}: the file changed while it was being updated; run again")
    mode = stat.S_IMODE(target.stat().st_mode)
    bak = backup_path(target)
    atomic_write_bytes(bak, original)
    with atomic_path(target) as tmp:
        tmp.write_bytes(text.encode("utf-8"))
        os.chmod(tmp, mode)  # the tool's file keeps its permissions
    return IntoResult(res.path, bak, res.updated, res.appended, res.duplicates_removed, res.blocks_added,
                      res.legacy, tuple(notes))
