"""Atomic output: a file appears at its final path complete, or not at all (issue "Trustworthy outputs" §3).

Every writer goes through a temporary file in the destination folder and :func:`os.replace` — atomic on
POSIX and Windows for a rename inside one file system — so an interrupted or failing run never leaves a
complete-looking truncated file: at worst a hidden ``.NAME.XXXX.partial`` temporary, removed on any
Python exception. :func:`staged_dir` does the same for a set of files that only make sense together
(a simulated drive: IMU, GNSS, reference and truth); :func:`staged_run` publishes the outputs of a whole
command run at its end and removes the files an earlier run of the same command left beside them.
"""

from __future__ import annotations

import os
import secrets
import shutil
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from imunoise.io.interrupt import interrupt_point, raise_if_interrupted

__all__ = ["atomic_path", "atomic_write_text", "atomic_write_bytes", "atomic_savefig", "staged_dir", "staged_run"]


def _temp_beside(path: Path) -> Path:
    """A new empty file next to ``path`` whose name keeps ``path``'s last suffix (``.gz``, ``.png``):
    writers that choose the format from the suffix then write the same bytes. Created with mode 0o666
    minus the umask, like a plain ``open(path, "w")`` would (``mkstemp`` would give 0o600)."""
    for _ in range(100):
        tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}.partial{path.suffix}")
        try:
            fd = os.open(tmp, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o666)
        except FileExistsError:
            continue
        os.close(fd)
        return tmp
    raise FileExistsError(f"cannot create a temporary file beside {path}")  # pragma: no cover


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on normal exit it replaces ``path``, on an exception
    (including KeyboardInterrupt) it is deleted and ``path`` is left as it was.

    Parameters
    ----------
    path : str or Path
        Final file path; its folder must exist.

    Returns
    -------
    Iterator[Path]
        The temporary path to write to (same folder, same last suffix).
    """
    path = Path(path)
    tmp = _temp_beside(path)
    try:
        yield tmp
        interrupt_point(path.name)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (temporary file + rename); returns ``path``."""
    path = Path(path)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)
    return path


def atomic_write_text(path: str | Path, text: str, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically (temporary file + rename); returns ``path``."""
    return atomic_write_bytes(path, text.encode(encoding))


def atomic_savefig(fig: Any, path: str | Path, **kwargs: Any) -> Path:
    """``fig.savefig(path, **kwargs)`` through a temporary file (the format from ``path``'s suffix)."""
    path = Path(path)
    kwargs.setdefault("format", path.suffix.lstrip(".") or None)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, **kwargs)
    return path


@contextmanager
def staged_dir(out: str | Path) -> Iterator[Path]:
    """Yield a hidden staging folder beside ``out``; on normal exit every entry in it is moved into
    ``out`` (created if needed, each move an atomic rename), on an exception the staging folder is
    deleted and ``out`` is untouched. For outputs whose files are only meaningful together.

    Parameters
    ----------
    out : str or Path
        Final folder (may exist; entries of the same name in it are replaced).

    Returns
    -------
    Iterator[Path]
        The staging folder to write into.
    """
    out = Path(out)
    parent = out.resolve().parent
    parent.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(dir=parent, prefix=f".{out.name}.", suffix=".partial"))
    try:
        yield stage
        interrupt_point("publish")
        raise_if_interrupted()  # a Ctrl-C swallowed on the way (imunoise.io.interrupt): nothing is published
        out.mkdir(parents=True, exist_ok=True)
        for entry in sorted(stage.iterdir()):
            dest = out / entry.name
            if dest.is_dir() and not dest.is_symlink():
                shutil.rmtree(dest)
            os.replace(entry, dest)
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def _merge_into(src: Path, dest: Path, moved: set[Path], root: Path) -> None:
    """Move every file under ``src`` to the same place under ``dest`` (each an atomic rename), creating
    folders; an existing folder of the same name is kept with whatever else it holds."""
    dest.mkdir(parents=True, exist_ok=True)
    for entry in sorted(src.iterdir()):
        target = dest / entry.name
        if entry.is_dir() and not entry.is_symlink():
            _merge_into(entry, target, moved, root)
        else:
            if target.is_dir() and not target.is_symlink():
                raise IsADirectoryError(21, "a folder is in the way of an output file", str(target))
            os.replace(entry, target)
            moved.add(target.relative_to(root))


@contextmanager
def staged_run(out: str | Path, owned: Sequence[str]) -> Iterator[Path]:
    """The outputs of one run of a command: written into a hidden staging folder in ``out``, published
    into ``out`` only when the run completes, and the files an earlier run of the same command left there
    removed (issue 22 "Interrupted or repeated runs").

    On an exception (also KeyboardInterrupt) the staging folder is deleted and ``out`` is left exactly as it
    was: nothing of the interrupted run appears complete. On success every staged file is moved into ``out``
    (each an atomic rename; folders merged, never replaced), then every file of ``out`` matching one of the
    ``owned`` glob patterns (the names this command writes, e.g. ``outage_*/metrics.json``) that this run did
    not write is deleted, and folders left empty by that are removed. Nothing else in ``out`` is touched.

    Parameters
    ----------
    out : str or Path
        The output folder (created if needed).
    owned : sequence of str
        Glob patterns, relative to ``out``, of every file the command can write.

    Returns
    -------
    Iterator[Path]
        The staging folder to write into (the same layout as ``out``).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    # staged inside ``out`` (writable, same file system; a hidden name no output pattern matches)
    stage = Path(tempfile.mkdtemp(dir=out, prefix=".run.", suffix=".partial"))
    try:
        yield stage
        interrupt_point("publish")
        raise_if_interrupted()  # a Ctrl-C swallowed on the way (imunoise.io.interrupt): nothing is published
        moved: set[Path] = set()
        _merge_into(stage, out, moved, out)
        for pattern in owned:
            for old in sorted(out.glob(pattern)):
                rel = old.relative_to(out)
                if rel in moved or old.is_dir():
                    continue
                old.unlink()
                parent = old.parent
                while parent != out and parent.is_dir() and not any(parent.iterdir()):
                    parent.rmdir()
                    parent = parent.parent
    finally:
        shutil.rmtree(stage, ignore_errors=True)
