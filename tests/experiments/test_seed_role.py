"""``--seed-role dev|report`` (issue 21 §4): recorded in results.json and named in the report."""

from __future__ import annotations

import json

import pytest

from imunoise.cli import main


@pytest.mark.slow
def test_seed_role_is_recorded_and_named(tmp_path):
    out = tmp_path / "exp"
    rc = main(["experiment", "online", "--sim", "--seeds", "1", "--seed0", "1000007", "--duration", "240", "--stops",
               "2", "--outages", "1", "--methods", "plain", "--workers", "1", "--seed-role", "report",
               "--out", str(out)])
    assert rc == 0
    assert json.loads((out / "results.json").read_text())["seed_role"] == "report"
    text = (out / "report.md").read_text()
    assert "Seeds: report — report seeds 1000007 (fresh seeds, run once for this method version)." in text
    # the per-window table has as many header cells as each row (method, one per window, mean)
    table = [line for line in text.splitlines() if line.startswith("| method |") and "mean" in line]
    assert table, text
    start = text.splitlines().index(table[-1])
    rows = [line for line in text.splitlines()[start:] if line.startswith("|")]
    assert len(rows) >= 3 and len({line.count("|") for line in rows}) == 1, rows


def test_seed_role_defaults_to_dev_and_rejects_others(tmp_path, capsys):
    from imunoise.experiments.report import seed_role_text

    assert seed_role_text({}).startswith("Seeds: dev — development seeds")
    with pytest.raises(SystemExit) as exc:
        main(["experiment", "online", "--sim", "--seed-role", "final", "--out", str(tmp_path / "x")])
    assert exc.value.code == 2 and "--seed-role" in capsys.readouterr().err


def test_report_is_refused_where_the_seeds_are_not_fresh(tmp_path, capsys):
    """A report label must be true: development seeds (below 1 000 000) and the recorded drive are refused in one
    line naming --seed-role, before any output is made."""
    out = tmp_path / "dev_seeds"
    rc = main(["experiment", "online", "--sim", "--seeds", "2", "--seed0", "7", "--seed-role", "report", "--out",
               str(out)])
    err = capsys.readouterr().err
    assert rc == 2 and "--seed-role report" in err and "7–8 are development seeds" in err and not out.exists()
    out = tmp_path / "real"
    rc = main(["experiment", "online", "--seed-role", "report", "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2 and "recorded drive has no seeds" in err and not out.exists()
    # on the recorded drive only the GNSS noise seeds can be fresh: development ones are refused
    rc = main(["experiment", "online", "--outages", "dense:60:20", "--gnss-regime", "noise:1.5,3,1",
               "--noise-seed0", "3", "--seed-role", "report", "--out", str(tmp_path / "noise")])
    assert rc == 2 and "3–7 are development seeds" in capsys.readouterr().err
    # on the simulator a fresh drive seed makes fresh GNSS noise whatever the noise seed (seeded by both)
    from imunoise.experiments.report_tables import seed_role_problem

    assert seed_role_problem(sim=True, seeds=[4_001_000], noise_seeds=[1, 2]) is None


def test_the_label_follows_the_seeds_and_the_data():
    from imunoise.experiments.report import seed_role_text
    from imunoise.experiments.report_tables import seed_role_problem

    assert seed_role_text({"data": "sim", "seeds": [1_000_000, 1_000_001], "seed_role": "report"}) == (
        "Seeds: report — report seeds 1000000–1000001 (fresh seeds, run once for this method version).")
    # a results.json written with the old rule: report asked on development seeds is not called fresh
    text = seed_role_text({"data": "sim", "seeds": [0, 1, 2], "seed_role": "report"})
    assert "fresh seeds" not in text and "0–2 seeds are development seeds" in text and "not evidence" in text
    assert seed_role_text({"data": "sim", "seeds": [5], "seed_role": "dev"}).startswith(
        "Seeds: dev — development seeds 5 (")
    # the recorded drive is development data, whatever the role; only its GNSS noise seeds can be fresh
    for role in ("dev", "report"):
        text = seed_role_text({"data": "data/drive_0708", "seed_role": role})
        assert text.startswith("Data: the recorded drive data/drive_0708 — development data")
        assert "fresh seeds" not in text
    text = seed_role_text({"data": "data/drive_0708", "seed_role": "report", "noise_seeds": [1_000_000, 1_000_001]})
    assert "development data" in text and "GNSS noise seeds: report — report seeds 1000000–1000001" in text
    demo = seed_role_text({"data": "/x/data/drive_0708", "noise_seeds": [1, 2, 3]})  # the demo: role dev
    assert "development data" in demo and "GNSS noise seeds: dev — development seeds 1–3" in demo
    assert seed_role_problem(sim=True, seeds=range(1_000_000, 1_000_030)) is None
    assert seed_role_problem(sim=False, noise_seeds=[1_000_000]) is None
    assert "development seeds" in seed_role_problem(sim=True, seeds=[999_999])


def test_the_per_window_table_has_a_header_cell_for_every_row_cell():
    from imunoise.experiments.report_tables import outage_rows

    # a Monte Carlo: no named windows, window k averaged over seeds
    heads, rows = outage_rows({"methods": {"plain": {"outage_end_horizontal_m": [3.0, 4.0],
                                                     "mean_outage_end_horizontal_m": 3.5},
                                           "gmwm": {"outage_end_horizontal_m": [2.0],
                                                    "mean_outage_end_horizontal_m": 2.0}}})
    assert heads == ["method", "window 1", "window 2", "mean"]
    assert rows == [["plain", 3.0, 4.0, 3.5], ["gmwm", 2.0, None, 2.0]]
    # real data: the windows named by their start, KF-GINS' own row as wide
    heads, rows = outage_rows({"windows": [[100.0, 60.0], [300.0, 60.0]],
                               "methods": {"plain": {"outage_end_horizontal_m": [1.0, 2.0],
                                                     "mean_outage_end_horizontal_m": 1.5}},
                               "kfgins_outage_end_horizontal_m": [1.0, 3.0]})
    assert heads == ["method", "#1 @ 100", "#2 @ 300", "mean"]
    assert all(len(r) == len(heads) for r in rows) and rows[-1][-1] == 2.0
