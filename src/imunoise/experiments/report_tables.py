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
    "seed_role_problem",
    "REPORT_SEED_MIN",
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
    kf = results.get("kfgins_outage_end_horizontal_m")
    ends = {name: list(r.get("outage_end_horizontal_m") or []) for name, r in results["methods"].items()}
    # one column per window: on real data the windows are named by their start; a Monte Carlo has none (each seed
    # draws its own), so its columns are the window index k, averaged over seeds
    n = max([len(wins), len(kf or []), *(len(e) for e in ends.values())])
    heads = (["method"] + [f"#{i + 1} @ {wins[i][0]:.0f}" if i < len(wins) else f"window {i + 1}" for i in range(n)]
             + ["mean"])
    rows = []
    for name, r in results["methods"].items():
        rows.append([name] + ends[name] + [None] * (n - len(ends[name])) + [r.get("mean_outage_end_horizontal_m")])
    if kf:
        rows.append(["KF-GINS (C++, README)"] + list(kf) + [None] * (n - len(kf)) + [float(np.mean(kf))])
    return heads, rows



DEMO_HEADS = ["GNSS", "method", "drift vs plain", "95 % CI", "drift vs static_var", "95 % CI ", "n_windows",
              "n_independent", "verdict vs plain"]


SEED_ROLES = {
    "dev": "development seeds (the methods were designed or tuned on runs like this one; not evidence)",
    "report": "report seeds (fresh seeds, run once for this method version)",
}
#: Seeds below this are development seeds (CONTRIBUTING, "Seeds: development and report").
REPORT_SEED_MIN = 1_000_000


def _span(seeds) -> str:
    s = sorted(set(int(x) for x in seeds))
    if not s:
        return ""
    if len(s) == 1:
        return f"{s[0]}"
    return f"{s[0]}–{s[-1]}" if s[-1] - s[0] + 1 == len(s) else f"{s[0]}–{s[-1]} ({len(s)} seeds)"


def seed_role_problem(*, sim: bool, seeds=(), noise_seeds=()) -> str | None:
    """Why ``--seed-role report`` would be false for this run, or None when every seed it draws is fresh.

    A recorded drive is development data (the methods were developed on it) and has no seed of its own; only the
    GNSS noise seeds of a noise regime can be fresh there. On the simulator the drive seeds decide: the GNSS noise
    of a drive is seeded by the drive seed and the noise seed together (:mod:`imunoise.experiments.dense`), so a
    fresh drive gets fresh noise. Seeds below :data:`REPORT_SEED_MIN` are development seeds.
    """
    drawn = list(seeds) if sim else list(noise_seeds)
    if not sim and not noise_seeds:
        return ("a recorded drive has no seeds and the methods were developed on it, so nothing in this run is "
                "fresh; use --seed-role dev (the default)")
    dev = [s for s in drawn if s < REPORT_SEED_MIN]
    if dev:
        return (f"seeds {_span(dev)} are development seeds (below {REPORT_SEED_MIN:,}); give fresh ones (e.g. "
                f"--seed0 {REPORT_SEED_MIN} and --noise-seed0 {REPORT_SEED_MIN}) or use --seed-role dev")
    return None


def _role_label(role: str, seeds: list) -> str:
    span = f" {_span(seeds)}" if seeds else ""
    if role == "report" and seeds and min(seeds) >= REPORT_SEED_MIN:
        return f"report — report seeds{span} (fresh seeds, run once for this method version)"
    if role == "report":
        dev = [s for s in seeds if s < REPORT_SEED_MIN]
        return (f"report requested, but {_span(dev) or 'no'} seeds are development seeds (below "
                f"{REPORT_SEED_MIN:,}): not fresh, not evidence")
    return f"dev — development seeds{span} (the methods were designed or tuned on runs like this one; not evidence)"


def seed_role_text(results: dict) -> str:
    """The sentence naming what the run's data and seeds are (``results["seed_role"]``, ``--seed-role``).

    The label follows the seeds actually drawn, not only the role asked for: development seeds (below
    :data:`REPORT_SEED_MIN`) are never called fresh, and a recorded drive is development data whatever the role
    (only the GNSS noise seeds of a noise regime can be fresh on it).
    """
    role = results.get("seed_role") or "dev"
    data = results.get("data")
    noise = [int(s) for s in results.get("noise_seeds") or []]
    if data not in (None, "sim"):
        text = (f"Data: the recorded drive {data} — development data (the methods were developed on it; no seed "
                "makes it fresh).")
        return text + (f" GNSS noise seeds: {_role_label(role, noise)}." if noise else "")
    seeds = [int(s) for s in results.get("seeds") or []]  # on the simulator they seed the GNSS noise too
    return f"Seeds: {_role_label(role, seeds)}."

