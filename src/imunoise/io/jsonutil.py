"""The one ``default=`` helper for :func:`json.dumps` (truth.json, events.jsonl, metrics.json, model files)."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["json_default"]


def json_default(o: Any) -> Any:
    """``default=`` of :func:`json.dumps`: NumPy arrays → lists, NumPy scalars → Python numbers/bools,
    anything else (a path, a model, an enum) → its ``str``.

    Parameters
    ----------
    o : Any
        An object the JSON encoder does not know.

    Returns
    -------
    Any
        A JSON-serialisable replacement.
    """
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    return str(o)
