"""``static.npz``: the static IMU pieces an online run pooled, handed to the next drive of the same IMU.

``imunoise online`` writes the pieces its model was fitted on (:attr:`OnlineResult.static_pieces`: the earlier
drives' it was given, then its own stops; bias removed, (N, 6) each, gyro x, y, z rad/s, accel x, y, z m/s²)
as ``piece_000``, ``piece_001``, … with the IMU rate ``rate_hz``; ``imunoise online --earlier-static`` reads
one or more of them (:func:`load_static_pieces`). A chain of drives therefore needs only the last file, and a
piece given twice (the same bytes in two files of one chain) is pooled once.
"""

from __future__ import annotations

import hashlib
import io
import zipfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from imunoise.errors import DataError
from imunoise.io.atomic import atomic_write_bytes

__all__ = ["save_static_pieces", "load_static_pieces"]


def save_static_pieces(path: str | Path, pieces: Sequence[np.ndarray], rate_hz: float) -> Path:
    """Write ``pieces`` ((N, 6) arrays) and ``rate_hz`` to ``path`` atomically; returns ``path``."""
    buf = io.BytesIO()
    arrays = {f"piece_{k:03d}": np.asarray(p, dtype=float) for k, p in enumerate(pieces)}
    np.savez_compressed(buf, rate_hz=np.array(float(rate_hz)), **arrays)
    return atomic_write_bytes(path, buf.getvalue())


def load_static_pieces(paths: Sequence[str | Path], rate_hz: float) -> list[np.ndarray]:
    """The pieces of the ``static.npz`` files ``paths``, each piece once, in file order.

    Raises
    ------
    DataError
        A file that is missing, not a ``static.npz`` of ``imunoise online``, holds a piece that is not (N, 6)
        and finite, or was recorded at another IMU rate than ``rate_hz`` (±0.5 %).
    """
    out: list[np.ndarray] = []
    seen: set[str] = set()
    for path in paths:
        path = Path(path)
        if not path.is_file():
            raise DataError(f"{path}: no such file; give the static.npz an earlier `imunoise online` run wrote")
        try:
            with np.load(path, allow_pickle=False) as z:
                files = dict(z.items())
        except (OSError, ValueError, zipfile.BadZipFile) as exc:
            raise DataError(f"{path}: not a static.npz of `imunoise online` ({exc})") from exc
        if "rate_hz" not in files or not any(k.startswith("piece_") for k in files):
            raise DataError(f"{path}: not a static.npz of `imunoise online` (needs rate_hz and piece_NNN arrays)")
        rate = float(files["rate_hz"])
        if not abs(rate - rate_hz) <= 0.005 * rate_hz:
            raise DataError(f"{path}: recorded at {rate:g} Hz, this IMU runs at {rate_hz:g} Hz; the static data of "
                            "another IMU or rate cannot be pooled")
        for name in sorted(k for k in files if k.startswith("piece_")):
            p = files[name]
            if p.ndim != 2 or p.shape[1] != 6 or not np.all(np.isfinite(p)):
                raise DataError(f"{path}: {name} is not a finite (N, 6) array of static samples")
            key = hashlib.sha1(np.ascontiguousarray(p).tobytes()).hexdigest()
            if key not in seen:
                seen.add(key)
                out.append(p)
    return out
