"""The filter engine keeps every trajectory to the bit: the fingerprints (SHA-256 of each output array) of the
batch run on the shipped drive (NHC, ZUPT, RTK velocity), the batch, step-by-step and rehearsal runs on a simulated
drive, the online engine and the law-aware oracle equal those stored from the code before the engine was made
one step sequence (``scripts/engine_reference.py --write``, run on that code).

numba compiles for the host CPU, whose features (FMA, vector width) change the last bits of a float result;
bit identity is therefore checked on a CPU with the features the reference was made on, and the test says so
and skips elsewhere (the batch ≡ step-filter identities of tests/nav/test_nav_filter_step.py hold everywhere).
"""

from __future__ import annotations

import json

import pytest

from conftest import load_script

REF = load_script("engine_reference")


@pytest.fixture(scope="module")
def reference():
    doc = json.loads(REF.OUT.read_text())
    if doc["cpu"] != REF.host_cpu():
        pytest.skip("the reference fingerprints were made on another CPU (numba compiles for the host's features)")
    return doc["cases"]


@pytest.mark.timeout(900)
@pytest.mark.parametrize("case", sorted(REF.CASES))
def test_trajectories_equal_the_reference_to_the_bit(reference, case):
    got = REF.CASES[case]()
    assert got == reference[case]


def test_the_step_sequence_exists_once():
    """The strapdown step is called in one place (predict_step) and the per-sample loop over IMU samples with
    measurement updates in one (run_steps): a second copy of the step sequence would add a call site."""
    import re
    from pathlib import Path

    src = Path(__file__).resolve().parents[2] / "src" / "imunoise"
    calls = [(p.relative_to(src).as_posix(), line.strip()) for p in src.rglob("*.py")
             for line in p.read_text(encoding="utf-8").splitlines()
             if re.search(r"\bnav_step\(", line) and not line.lstrip().startswith("def ")]
    assert calls == [("nav/filter_loop.py", "nav_step(f.nav, f.xm, f.acc, dth, dv, dt, m.hvec, m.axis_of, gate, "
                                            "m.sf_idx)")]
    users = [p.relative_to(src).as_posix() for p in src.rglob("*.py")
             if re.search(r"\bpredict_step\(", p.read_text(encoding="utf-8"))]
    assert sorted(users) == ["nav/filter_loop.py", "nav/step_filter.py"]  # run_steps and propagate
