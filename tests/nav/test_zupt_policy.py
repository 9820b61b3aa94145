"""The one ZUPT rule: the batch mask (``nav --zupt``) and the online engine's per-sample test agree, the phase
belongs to the stop, and a record cut anywhere gives the same updates."""

from __future__ import annotations

import numpy as np

from imunoise.nav.zupt_policy import static_runs, zupt_due, zupt_due_at


def _static(seed: int, n: int = 3000) -> np.ndarray:
    rng = np.random.default_rng(seed)
    lengths = rng.integers(1, 400, size=60)
    return np.repeat(np.arange(lengths.size) % 2 == 1, lengths)[:n]


def test_the_mask_is_the_per_sample_rule():
    for seed in (4600, 4601, 4602):
        static = _static(seed)
        gate = np.random.default_rng(seed + 1).random(static.size) < 0.1
        run, want = 0, []
        for s, g in zip(static, gate, strict=True):
            run = run + 1 if s else 0
            want.append(bool(s) and zupt_due_at(run, 10, 50, bool(g)))
        assert np.array_equal(zupt_due(static, every=10, after=50, gate=gate), np.array(want))


def test_updates_start_after_the_delay_and_follow_the_stop():
    static = np.r_[np.zeros(7, bool), np.ones(100, bool), np.zeros(3, bool), np.ones(60, bool)]
    due = np.flatnonzero(zupt_due(static, every=10, after=50))
    # run length 50, 60, ... of the first stop (starting at sample 7), then 50, 60 of the second (at 110)
    assert due.tolist() == [7 + 49, 7 + 59, 7 + 69, 7 + 79, 7 + 89, 7 + 99, 110 + 49, 110 + 59]


def test_a_record_cut_anywhere_gives_the_same_updates():
    static = _static(4603)
    whole = zupt_due(static, every=10, after=50)
    for cut in (1, 57, 1234, 2999):
        first = zupt_due(static[:cut], every=10, after=50)
        run0 = int(static_runs(static[:cut])[-1])
        second = zupt_due(static[cut:], every=10, after=50, run0=run0)
        assert np.array_equal(np.r_[first, second], whole)
