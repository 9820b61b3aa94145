"""scripts/evidence_tables.py: the markdown tables of docs/acceptance/ from a results.json."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

from imunoise.experiments.stats import paired_entry

_SPEC = importlib.util.spec_from_file_location(
    "evidence_tables", Path(__file__).resolve().parents[1] / "scripts" / "evidence_tables.py")
evidence_tables = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(evidence_tables)


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
