"""scripts/evidence_tables.py: the markdown tables of docs/evidence/ from a results.json."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import load_script
from imunoise.experiments.stats import paired_entry

evidence_tables = load_script("evidence_tables")


def _results() -> dict:
    # two drives of 6 windows: the oracle has 0.6 × plain's drift everywhere, "half" exactly half its log-gain
    rng = np.random.default_rng(3)
    plain = [[list(rng.uniform(50, 300, 6))] for _ in range(2)]
    drift = {"plain": plain,
             "oracle": [[[0.6 * v for v in d[0]]] for d in plain],
             "half": [[[np.sqrt(0.6) * v for v in d[0]]] for d in plain]}
    paired = [dict(paired_entry(m, "plain", "drift", drift, 3, n_independent_total=4, n_boot=100), gnss="rtk")
              for m in ("oracle", "half")]
    return {"methods": ["plain", "half", "oracle"], "gnss": ["rtk"], "n_drives": 2, "n_windows": 12,
            "n_independent": 4, "seeds": [0, 1], "protocol": {"outages": "dense:60:20:60", "block": 3,
                                                              "n_boot": 200, "boot_seed": 0},
            "paired": paired, "per_window": {"rtk": {"drift": drift}}}


def test_tables_show_ratios_and_the_oracle_share():
    md = evidence_tables.tables(_results())
    assert "| half | **0.775 [0.775, 0.775]** |" in md  # √0.6, the CI degenerate and excluding 1
    assert "| half | 50.0 % [50.0, 50.0] |" in md
    assert "| oracle |" in md and "| oracle | 100" not in md  # the oracle has no share row of its own


def _run(method: str, scale: float, windows: dict) -> dict:
    rng = np.random.default_rng(5)  # the same draws in both runs: the second run's method is scale × the first's
    per = {met: {method: [[list(scale * rng.uniform(50, 300, 6))] for _ in range(2)]}
           for met in ("drift", "rms", "aided_rms")}
    return {"methods": [method], "gnss": ["rtk"], "n_independent": 4, "windows": windows,
            "protocol": {"block": 3, "n_boot": 200, "boot_seed": 0}, "per_window": {"rtk": per}}


def test_across_pairs_two_runs_of_the_same_windows(capsys, tmp_path):
    windows = {"seed 0": [[60.0, 120.0]] * 6, "seed 1": [[60.0, 120.0]] * 6}
    a, b = _run("x", 1.0, windows), _run("y", 0.8, windows)
    entries = evidence_tables.cross_pairs(a, b, [("x", "y")])
    assert {e["metric"] for e in entries} == {"drift", "rms", "aided_rms"}
    for e in entries:
        assert (e["method"], e["baseline"], e["gnss"]) == ("x", "y", "rtk")
        assert abs(e["ratio"] - 1.25) < 1e-12 and e["significant"]  # x / (0.8 x) in every window
    (tmp_path / "a.json").write_text(json.dumps(a))
    (tmp_path / "b.json").write_text(json.dumps(b))
    assert evidence_tables.main([str(tmp_path / "a.json"), "--across", str(tmp_path / "b.json"), "--pairs", "x/y"]) == 0
    assert "| x / y | **1.250 [1.250, 1.250]** |" in capsys.readouterr().out


def test_across_refuses_runs_of_other_windows_and_unknown_methods():
    a = _run("x", 1.0, {"seed 0": [[60.0, 120.0]]})
    b = _run("y", 1.0, {"seed 0": [[80.0, 140.0]]})
    with pytest.raises(ValueError, match="same drives and windows"):
        evidence_tables.cross_pairs(a, b, [("x", "y")])
    with pytest.raises(ValueError, match="method 'z' is not in its run"):
        evidence_tables.cross_pairs(a, _run("y", 1.0, a["windows"]), [("x", "z")])
    with pytest.raises(SystemExit):
        evidence_tables.main(["a.json", "--across", "b.json"])  # no --pairs: usage error


def test_recompute_rebuilds_the_paired_entries_from_the_windows():
    res = _results()
    stale = [dict(e, ci=[0.1, 9.9], interval="block bootstrap") for e in res["paired"]]
    res["paired"] = stale
    got = evidence_tables.recompute(res)
    drift = res["per_window"]["rtk"]["drift"]
    want = paired_entry("half", "plain", "drift", drift, 3, n_independent_total=4, n_boot=200, seed=0)
    half = next(e for e in got if e["method"] == "half")
    assert half["ci"] == pytest.approx(want["ci"], rel=1e-12) and half["gnss"] == "rtk"
    assert half["interval"] == "cluster t" and [e["method"] for e in got] == ["oracle", "half"]
