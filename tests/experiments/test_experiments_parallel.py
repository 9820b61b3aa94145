"""The evidence runs give the same numbers whoever runs the drives: inline, forked processes or Dask."""

from __future__ import annotations

import pytest

from imunoise.experiments import dense
from imunoise.experiments.gnss_regimes import parse_gnss
from imunoise.experiments.runner import run_jobs, tick
from imunoise.online import OnlineConfig

# two short drives, one stop each, 20 s windows: a few seconds per drive
TINY = dict(spec=dense.DenseSpec(20.0, 20.0, 30.0), regimes=[parse_gnss("noise:1.5,3,1")], noise_seeds=[1],
            methods=("plain", "static_var"), base=OnlineConfig(latency=1.0), n_boot=200, duration_s=180.0,
            n_stops=1, motion_noise=None)
SEEDS = [3, 4]


@pytest.fixture(scope="module")
def inline():
    ticks: list[int] = []
    res = dense.run_sim(SEEDS, workers=1, progress=ticks.append, **TINY)
    return res, ticks


def test_two_workers_give_the_inline_per_window_values_to_the_bit(inline):
    ref, ticks = inline
    ticks2: list[int] = []
    res = dense.run_sim(SEEDS, workers=2, progress=ticks2.append, **TINY)
    assert ref["n_windows"] > 4
    assert res["per_window"] == ref["per_window"]  # exact float equality, window by window
    assert res["summary"] == ref["summary"] and res["paired"] == ref["paired"] and res["seeds"] == SEEDS
    # one progress unit per method and drive, from the workers as from the inline loop
    assert sum(ticks) == sum(ticks2) == len(SEEDS) * 2


def test_dask_scheduler_gives_the_inline_per_window_values(inline):
    ref, _ = inline
    units: list[int] = []
    res = dense.run_sim(SEEDS[::-1], workers=2, scheduler="threads", progress=units.append, **TINY)
    assert res["seeds"] == SEEDS and res["per_window"] == ref["per_window"]
    assert units == [2, 2]  # whole drives: a Dask worker's ticks stay on the worker


def _square(x: int) -> dict:
    tick(x)
    return {"x": x * x}


def test_run_jobs_keeps_the_order_of_the_jobs_and_counts_ticks():
    got: list[int] = []
    out = run_jobs(_square, [3, 1, 2], workers=2, progress=got.append)
    assert [o["x"] for o in out] == [9, 1, 4] and sorted(got) == [1, 2, 3]
    with pytest.raises(Exception, match="--workers must be a whole number"):
        run_jobs(_square, [1], workers=0)


def test_cli_scheduler_outside_the_simulated_evidence_is_refused(tmp_path, capsys):
    from imunoise.cli import main

    out = tmp_path / "never"
    assert main(["experiment", "online", "--sim", "--seeds", "1", "--scheduler", "local", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "--scheduler runs the dense-window evidence on the simulator" in err and not out.exists()
