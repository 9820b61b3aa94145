"""Scoring a static mask against the truth: epoch-wise precision/recall/F1 and the truth from a reference
speed (docs/guide/theory.rst, 'Static detection')."""

from __future__ import annotations

import numpy as np

from imunoise.errors import DataError

__all__ = ["static_metrics", "static_truth_from_speed"]


def static_metrics(static_pred: np.ndarray, static_true: np.ndarray) -> dict[str, float]:
    """Epoch-wise precision, recall and F1 of a static mask against the truth (NaN when undefined)."""
    p = np.asarray(static_pred, dtype=bool)
    q = np.asarray(static_true, dtype=bool)
    if p.shape != q.shape:
        raise DataError(f"static_metrics: shapes differ: {p.shape} vs {q.shape}")
    tp = int(np.sum(p & q))
    n_pred, n_true = int(p.sum()), int(q.sum())
    precision = tp / n_pred if n_pred else float("nan")
    recall = tp / n_true if n_true else float("nan")
    if not (n_pred and n_true):
        f1 = float("nan")
    else:
        f1 = 2 * precision * recall / (precision + recall) if tp else 0.0
    return {"precision": precision, "recall": recall, "f1": f1, "n_true": n_true, "n_pred": n_pred}


def static_truth_from_speed(
    t: np.ndarray, t_ref: np.ndarray, vel_ref: np.ndarray, threshold: float = 0.2
) -> np.ndarray:
    """Reference static mask at epochs ``t``: speed ‖v‖ (3-D, from ``vel_ref`` (m, 3) m/s, or a speed
    (m,)) linearly interpolated to ``t``, below ``threshold`` [m/s]. Epochs outside the reference span
    are not static."""
    v = np.asarray(vel_ref, dtype=float)
    speed = np.linalg.norm(v, axis=1) if v.ndim == 2 else v
    s = np.interp(t, t_ref, speed)
    return (s < threshold) & (t >= t_ref[0]) & (t <= t_ref[-1])
