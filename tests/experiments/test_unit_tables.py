"""scripts/unit_tables.py: units (sensors) as the clusters of the paired ratios, drives nested inside."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from conftest import load_script

unit_tables = load_script("unit_tables")


def _mc(rng, effect):
    # a Monte Carlo results.json of 3 drives × 4 windows: gmwm = plain × exp(effect + noise)
    plain = [list(rng.uniform(50, 300, 4)) for _ in range(3)]
    gm = [[v * math.exp(effect + rng.normal(0, 0.05)) for v in d] for d in plain]
    return {"methods": ["plain", "gmwm"], "data": "sim", "seed_role": "dev",
            "per_seed": {"plain": [{"outage_end_horizontal_m": d} for d in plain],
                         "gmwm": [{"outage_end_horizontal_m": d} for d in gm]}}


def test_units_are_the_clusters():
    rng = np.random.default_rng(0)
    effects = [-0.2, -0.1, 0.0, -0.3, -0.15]
    res = [_mc(rng, e) for e in effects]
    (e,) = unit_tables.pooled(res, [f"u{k}" for k in range(5)], n_boot=100)
    assert e["n_clusters"] == 5 and e["df"] == 4 and e["n_drives"] == 15 and e["n_windows"] == 60
    # equal units: the interval is the t interval of the five unit means of the log-ratios
    unit_means = []
    for r in res:
        lr = [math.log(g / p) for dg, dp in zip(r["per_seed"]["gmwm"], r["per_seed"]["plain"])
              for g, p in zip(dg["outage_end_horizontal_m"], dp["outage_end_horizontal_m"])]
        unit_means.append(np.mean(lr))
    m = np.mean(unit_means)
    half = stats.t.ppf(0.975, 4) * np.std(unit_means, ddof=1) / math.sqrt(5)
    assert math.log(e["ratio"]) == pytest.approx(m, rel=1e-12)
    assert [math.log(x) for x in e["ci"]] == pytest.approx([m - half, m + half], rel=1e-10)
    assert "| sim | drift | gmwm | plain |" in unit_tables.table([e])


def test_extra_pairs_and_the_paper_style_table():
    rng = np.random.default_rng(1)
    res = [_mc(rng, e) for e in (-0.2, -0.1, 0.0)]
    for r in res:  # a third method: av = plain × 1.5 on every window
        r["methods"].append("av")
        r["per_seed"]["av"] = [{"outage_end_horizontal_m": [1.5 * v for v in d["outage_end_horizontal_m"]]}
                               for d in r["per_seed"]["plain"]]
    entries = unit_tables.pooled(res, ["a", "b", "c"], n_boot=100, pairs=[("gmwm", "av"), ("x", "av")])
    (ga,) = [e for e in entries if (e["method"], e["baseline"]) == ("gmwm", "av")]
    (gp,) = [e for e in entries if (e["method"], e["baseline"]) == ("gmwm", "plain")]
    assert ga["ratio"] == pytest.approx(gp["ratio"] / 1.5, rel=1e-12) and ga["n_clusters"] == 3
    text = unit_tables.paper_table(res, ["a", "b", "c"])
    plain = np.mean([v for r in res for d in r["per_seed"]["plain"] for v in d["outage_end_horizontal_m"]])
    assert f"| sim | plain | {plain:.4g} | – |" in text and "| sim | av | " in text and "| +50.0 |" in text
