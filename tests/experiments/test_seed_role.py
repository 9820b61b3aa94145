"""``--seed-role dev|report`` (issue 21 §4): recorded in results.json and named in the report."""

from __future__ import annotations

import json

import pytest

from imunoise.cli import main


@pytest.mark.slow
def test_seed_role_is_recorded_and_named(tmp_path):
    out = tmp_path / "exp"
    rc = main(["experiment", "online", "--sim", "--seeds", "1", "--seed0", "7", "--duration", "240", "--stops", "2",
               "--outages", "1", "--methods", "plain", "--workers", "1", "--seed-role", "report", "--out", str(out)])
    assert rc == 0
    assert json.loads((out / "results.json").read_text())["seed_role"] == "report"
    assert "Seeds: report — report seeds (fresh seeds, run once for this method version)." in (
        out / "report.md").read_text()


def test_seed_role_defaults_to_dev_and_rejects_others(tmp_path, capsys):
    from imunoise.experiments.report import seed_role_text

    assert seed_role_text({}).startswith("Seeds: dev — development seeds")
    with pytest.raises(SystemExit) as exc:
        main(["experiment", "online", "--sim", "--seed-role", "final", "--out", str(tmp_path / "x")])
    assert exc.value.code == 2 and "--seed-role" in capsys.readouterr().err
