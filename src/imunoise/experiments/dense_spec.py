"""Dense outage windows (docs/guide/theory.rst, 'Experiments'): the ``--outages`` grammar (``dense:L:S[:LEAD]``, a
window count or an
outage file) and where the windows of length L open, every S s after LEAD s of aided driving with no GNSS gap
over :data:`MAX_GAP_S` (:mod:`imunoise.experiments.dense` runs the evidence on them)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from imunoise.errors import DataError, ModelError
from imunoise.experiments.common import Scenario

__all__ = ["DenseSpec", "parse_outages", "dense_windows", "MAX_GAP_S", "BRANCH_MARGIN_S"]

MAX_GAP_S = 2.0
BRANCH_MARGIN_S = 1.0


@dataclass(frozen=True)
class DenseSpec:
    """Dense windows: ``length_s`` long, opened every ``step_s`` after ``lead_s`` of aided driving."""

    length_s: float = 60.0
    step_s: float = 20.0
    lead_s: float = 60.0

    @property
    def label(self) -> str:
        return f"dense:{self.length_s:g}:{self.step_s:g}:{self.lead_s:g}"


def parse_outages(text: str | int | None) -> tuple[str, Any]:
    """``--outages``: ``"dense:L:S[:LEAD]"`` → ("dense", DenseSpec); an integer → ("count", n) (simulator:
    windows per drive); anything else → ("file", Path) (an outage file, docs/guide/theory.rst, 'Navigation filter')."""
    if text is None:
        return "none", None
    if isinstance(text, int):
        return "count", text
    s = str(text).strip()
    if s.lower().startswith("dense"):
        parts = s.split(":")[1:]
        try:
            vals = [float(p) for p in parts if p.strip()]
        except ValueError as exc:
            raise ModelError(f"--outages {text!r}: dense:L:S[:LEAD] takes numbers (s)") from exc
        if len(vals) > 3:
            raise ModelError(f"--outages {text!r}: dense:L:S[:LEAD], at most three numbers (s)")
        spec = DenseSpec(*vals)
        if not (spec.length_s > 0 and spec.step_s > 0 and spec.lead_s >= 0):
            raise ModelError(f"--outages {text!r}: L and S must be > 0 s and LEAD ≥ 0 s")
        return "dense", spec
    try:
        return "count", int(s)
    except ValueError:
        pass
    p = Path(s)
    if not p.exists():
        raise ModelError(f"--outages {text!r}: not dense:L:S[:LEAD], a number of windows or an existing "
                            "outage file")
    return "file", p


def dense_windows(sc: Scenario, spec: DenseSpec) -> list[tuple[float, float]]:
    """Window (start, L) every ``step_s`` from ``init.t + lead_s`` while the window ends before the IMU
    and the reference do, kept where the recorded fixes cover the preceding ``lead_s`` with no gap over
    :data:`MAX_GAP_S`."""
    gt = np.asarray(sc.gnss.t, dtype=float)
    gt = gt[gt > sc.init.t]
    t_end = min(float(sc.imu.t[-1]), float(sc.ref.t[-1])) - BRANCH_MARGIN_S
    out = []
    s = sc.init.t + spec.lead_s
    while s + spec.length_s <= t_end + 1e-9:
        a = s - spec.lead_s
        inside = gt[(gt >= a) & (gt < s)]
        if inside.size:
            edges = np.concatenate([[a], inside, [s]])
            if float(np.max(np.diff(edges))) <= MAX_GAP_S:
                out.append((float(s), float(spec.length_s)))
        s += spec.step_s
    if not out:
        raise DataError(f"no dense window fits ({spec.label}): the drive is shorter than lead + L or GNSS has gaps")
    return out
