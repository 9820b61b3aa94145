"""The experiments' result files and table rows (docs/guide/theory.rst, 'Experiments'): ``results.json`` without the
in-memory objects, CSV tables, the headline and outage rows, and the seed-role sentence."""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from imunoise.experiments.common import METHOD_LABELS
from imunoise.io.atomic import atomic_write_text
from imunoise.io.jsonutil import json_default
from imunoise.report import fmt

__all__ = [
    "DEMO_HEADS",
    "HEADLINE",
    "SEED_ROLES",
    "clean_json",
    "headline_rows",
    "outage_rows",
    "seed_role_text",
    "short_floats",
    "write_csv",
    "write_results",
]

HEADLINE = ["method", "horizontal RMS [m]", "vertical RMS [m]", "ECEF RMS X/Y/Z [m]", "mean outage-end drift [m]",
            "Δ drift vs plain [%]"]



def clean_json(o: Any) -> Any:
    """JSON-ready copy: keys starting with ``_`` dropped, arrays to lists, non-finite floats to None."""
    if isinstance(o, dict):
        return {str(k): clean_json(v) for k, v in o.items() if not str(k).startswith("_")}
    if isinstance(o, (list, tuple)):
        return [clean_json(v) for v in o]
    if isinstance(o, np.ndarray):
        return clean_json(o.tolist())
    if isinstance(o, (np.floating, float)):
        v = float(o)
        return v if math.isfinite(v) else None
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.bool_,)):
        return bool(o)
    return o


def short_floats(o: Any) -> Any:
    """Floats rounded for reading: times (≥ 10⁴, GPS seconds) to the ms, the rest to 6 significant digits."""
    if isinstance(o, dict):
        return {k: short_floats(v) for k, v in o.items()}
    if isinstance(o, list):
        return [short_floats(v) for v in o]
    if isinstance(o, float):
        return round(o, 3) if abs(o) >= 1e4 else float(f"{o:.6g}")
    return o


def write_results(results: dict, out: Path) -> Path:
    """``results.json`` without the in-memory objects (keys starting with ``_``), written atomically."""
    return atomic_write_text(out / "results.json", json.dumps(clean_json(results), indent=1, default=json_default))


def write_csv(path: Path, headers: Sequence[str], rows: Sequence[Sequence[Any]]) -> Path:
    """A CSV table with a header row, numbers as :func:`imunoise.report.fmt` prints them (written atomically)."""
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow(headers)
    for r in rows:
        w.writerow([fmt(c) if not isinstance(c, str) else c for c in r])
    atomic_write_text(path, buf.getvalue())
    return path


def headline_rows(results: dict) -> list[list[Any]]:
    """Rows of the headline table: method (label), RMS, ECEF RMS, mean drift, % change vs plain."""
    from imunoise.experiments.denial import LABELS as DENIAL

    labels = DENIAL if results.get("experiment") == "denial" else METHOD_LABELS
    m = results["methods"]
    plain = m.get("plain", {}).get("mean_outage_end_horizontal_m")
    rows = []
    for name, r in m.items():
        d = r.get("mean_outage_end_horizontal_m")
        imp = None if (plain is None or d is None or name == "plain") else 100.0 * (d / plain - 1.0)
        ecef = "/".join(fmt(x, 3) for x in (r.get("ecef_rms_m") or []))
        label = labels.get(name, name)
        shown = label if label.startswith(name) else f"{name} ({label})"  # no "plain (plain LC …)"
        rows.append([shown, r.get("horizontal_rms_m"), r.get("vertical_rms_m"),
                     ecef, d, imp])
    return rows


def outage_rows(results: dict) -> tuple[list[str], list[list[Any]]]:
    """Header and rows of the outage-end horizontal drift per method and window (KF-GINS' own if given)."""
    wins = results.get("windows") or []
    heads = ["method"] + [f"#{i + 1} @ {w[0]:.0f}" for i, w in enumerate(wins)] + ["mean"]
    rows = []
    for name, r in results["methods"].items():
        ends = r.get("outage_end_horizontal_m") or []
        rows.append([name] + list(ends) + [r.get("mean_outage_end_horizontal_m")])
    kf = results.get("kfgins_outage_end_horizontal_m")
    if kf:
        rows.append(["KF-GINS (C++, README)"] + list(kf) + [float(np.mean(kf))])
    return heads, rows



DEMO_HEADS = ["GNSS", "method", "drift vs plain", "95 % CI", "drift vs static_var", "95 % CI ", "n_windows",
              "n_independent", "verdict vs plain"]


SEED_ROLES = {
    "dev": "development seeds (the methods were designed or tuned on runs like this one; not evidence)",
    "report": "report seeds (fresh seeds, run once for this method version)",
}


def seed_role_text(results: dict) -> str:
    """The sentence naming the run's seed role (``results["seed_role"]``, ``--seed-role``; issue 21 §4)."""
    role = results.get("seed_role") or "dev"
    return f"Seeds: {role} — {SEED_ROLES.get(role, role)}."

