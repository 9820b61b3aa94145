"""Assembly and paired statistics of the dense-window evidence: per-window values over drives × GNSS
realisations × windows, per-regime summaries, and every method paired against the baselines with a block
bootstrap CI (:func:`imunoise.experiments.stats.paired_entry`); the ``--pairs`` grammar."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from imunoise.errors import ModelError
from imunoise.experiments.dense_spec import DenseSpec
from imunoise.experiments.gnss_regimes import GnssRegime
from imunoise.experiments.nees import nees_summary
from imunoise.experiments.stats import default_block, n_independent, paired_entry

__all__ = ["METRICS", "assemble", "paired_list", "significance_text", "parse_pairs"]

METRICS = ("drift", "rms", "aided_rms")


def assemble(drives: list[dict], methods: Sequence[str], regimes: Sequence[GnssRegime], spec: DenseSpec,
             pairs: Sequence[tuple[str, str]], *, n_paper: int = 0, n_boot: int = 2000, boot_seed: int = 0) -> dict:
    """Per-window values (drives × realisations × windows), per-regime summaries and the ``paired`` list."""
    block = default_block(spec.length_s, spec.step_s)
    n_ind = sum(n_independent([w[0] for w in d["windows"]], spec.length_s) for d in drives)
    per: dict[str, dict] = {}
    summary: dict[str, dict] = {}
    for ri, rg in enumerate(regimes):
        vals = {met: {m: [] for m in methods} for met in METRICS}
        paper: dict[str, list] = {m: [] for m in methods}
        scal: dict[str, dict[str, list]] = {m: {"horizontal_rms_m": [], "vertical_rms_m": []} for m in methods}
        for d in drives:
            nd = len(d["windows"])
            runs = sorted([r for r in d["runs"] if r[1] == ri], key=lambda r: r[2])
            for m in methods:
                rr = [r[3] for r in runs if r[0] == m]
                for met in METRICS:
                    vals[met][m].append([[w[met] for w in r["windows"][:nd]] for r in rr])
                paper[m].extend([[w["drift"] for w in r["windows"][nd:nd + n_paper]] for r in rr])
                for key in scal[m]:
                    scal[m][key].extend(r[key] for r in rr)
        s: dict[str, Any] = {}
        for m in methods:
            def _mean(x):
                a = np.array([np.nan if v is None else v for v in np.ravel(np.array(x, dtype=object))], dtype=float)
                return float(np.nanmean(a)) if np.any(np.isfinite(a)) else None

            s[m] = {"horizontal_rms_m": _mean(scal[m]["horizontal_rms_m"]),
                    "vertical_rms_m": _mean(scal[m]["vertical_rms_m"]),
                    "mean_end_drift_m": _mean([v for dd in vals["drift"][m] for v in dd]),
                    "mean_window_rms_m": _mean([v for dd in vals["rms"][m] for v in dd]),
                    "mean_aided_rms_m": _mean([v for dd in vals["aided_rms"][m] for v in dd])}
            if n_paper:
                arr = np.array([[np.nan if v is None else v for v in row] for row in paper[m]], dtype=float)
                s[m]["paper_windows_drift_m"] = np.nanmean(arr, axis=0).tolist()
                s[m]["paper_mean_drift_m"] = float(np.nanmean(arr))
        per[rg.label] = vals
        summary[rg.label] = s
    paired = paired_list(per, methods, pairs, block=block, n_indep=n_ind, n_boot=n_boot, boot_seed=boot_seed)
    nees = {rg.label: {m: nees_summary([_drive_nees(d, ri, m) for d in drives], n_boot=n_boot, seed=boot_seed)
                       for m in methods} for ri, rg in enumerate(regimes)}
    return {"experiment": "online", "protocol": {"outages": spec.label, "length_s": spec.length_s,
                                                  "step_s": spec.step_s, "lead_s": spec.lead_s, "block": block,
                                                  "n_boot": n_boot, "boot_seed": boot_seed},
            "methods": list(methods), "gnss": [rg.label for rg in regimes],
            "windows": {d["name"]: [list(w) for w in d["windows"]] for d in drives},
            "n_windows": sum(len(d["windows"]) for d in drives), "n_independent": n_ind, "n_drives": len(drives),
            "summary": summary, "per_window": per, "paired": paired, "nees": nees}


def _drive_nees(d: dict, ri: int, m: str) -> dict | None:
    """One drive's NEES counts of method ``m`` in regime ``ri``, summed over its GNSS noise seeds (realisations
    of one drive, not more drives); None when the runs measured none."""
    got = [r[3]["nees"] for r in d["runs"] if r[0] == m and r[1] == ri and r[3].get("nees")]
    if not got:
        return None
    return {k: sum(g[k] for g in got) for k in ("n", "inside", "sum")}


def paired_list(per: dict, methods: Sequence[str], pairs: Sequence[tuple[str, str]], *, block: int, n_indep: int,
                n_boot: int = 2000, boot_seed: int = 0) -> list[dict]:
    """Every method against ``plain`` and ``static_var`` (when run; plain/static_var only as static_var/plain)
    and every pair of ``pairs``, for each GNSS regime and metric (``drift``, ``rms``, ``aided_rms``)."""
    want: list[tuple[str, str]] = []
    for b in ("plain", "static_var"):
        if b in methods:
            # plain vs static_var is the inverse of static_var vs plain: listed once
            want += [(m, b) for m in methods if m != b and (m, b) != ("plain", "static_var")]
    for a, b in pairs:
        if a not in methods or b not in methods:
            raise ModelError(f"--pairs {a}/{b}: both methods must be among the methods run ({', '.join(methods)})")
        if (a, b) not in want:
            want.append((a, b))
    out = []
    for label, vals in per.items():
        for met in METRICS:
            for a, b in want:
                e = paired_entry(a, b, met, vals[met], block, n_independent_total=n_indep, n_boot=n_boot,
                                 seed=boot_seed)
                e["gnss"] = label
                out.append(e)
    return out


def significance_text(e: dict) -> str:
    """"significant" when the CI excludes 1, else "not significant"."""
    return "significant" if e.get("significant") else "not significant"


def parse_pairs(text: str | None) -> list[tuple[str, str]]:
    """``"a/b,c/d"`` → [(a, b), (c, d)]."""
    if not text:
        return []
    out = []
    for p in text.split(","):
        p = p.strip()
        if not p:
            continue
        if p.count("/") != 1:
            raise ModelError(f"--pairs: {p!r} is not method/baseline (e.g. gmwm/av)")
        a, b = (x.strip() for x in p.split("/"))
        out.append((a, b))
    return out
