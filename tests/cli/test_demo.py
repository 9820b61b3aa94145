"""`imunoise demo`: the powered dense-window comparison is the headline (with its CI column) and the paper's
five-window view follows it (issue "Evidence with power", acceptance 5)."""

from __future__ import annotations

import csv
import json

import pytest

from imunoise.experiments.common import repo_data_dir

DRIVE = repo_data_dir()
pytestmark = pytest.mark.skipif(not (DRIVE / "imu_body_inc.txt.gz").exists(), reason="data/drive_0708 not shipped")


@pytest.mark.slow
def test_online_demo_headline_is_the_paired_comparison(tmp_path, capsys):
    from imunoise.cli.demo import run_online_demo

    # a cut-down run of the same path: three methods, one meter-level noise seed, independent 60 s windows
    ev = {"methods": ("plain", "static_var", "gmwm"), "gnss": ("noise:1.5,3,1",), "noise_seeds": (1,),
          "outages": "dense:60:60"}
    assert run_online_demo(tmp_path, workers=1, evidence=ev, methods=("plain", "gmwm")) == 0
    printed = capsys.readouterr().out
    # the headline comes first, the five-window table after it
    assert printed.index("headline: paired end-drift ratios") < printed.index("paper-style view")
    rows = list(csv.DictReader((tmp_path / "paired_headline.csv").open()))
    assert [(r["GNSS"], r["method"]) for r in rows] == [("noise:1.5,3,1", "static_var"), ("noise:1.5,3,1", "gmwm")]
    ev_json = json.loads((tmp_path / "evidence.json").read_text())
    by = {(e["method"], e["baseline"]): e for e in ev_json["paired"] if e["metric"] == "drift"}
    for r in rows:
        e = by[(r["method"], "plain")]
        lo, hi = e["ci"]
        assert lo < e["ratio"] < hi  # a real interval around the geometric-mean ratio
        assert float(r["drift vs plain"]) == pytest.approx(e["ratio"], rel=1e-3)
        assert r["verdict vs plain"] == ("significant" if (hi < 1 or lo > 1) else "not significant")
        assert int(r["n_windows"]) == ev_json["n_windows"] >= 5
    # static_var has no pair against itself; gmwm has one against static_var
    assert rows[0]["drift vs static_var"] == "–" and float(rows[1]["drift vs static_var"]) > 0
    html = (tmp_path / "report.html").read_text()
    assert html.index("Headline: paired drift ratios") < html.index("Paper-style view")
    assert "% CI</th>" in html  # the CI column of the headline
    assert (tmp_path / "paired.png").stat().st_size > 10_000  # the forest plot of the same ratios
