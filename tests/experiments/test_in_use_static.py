"""``in_use``'s static part is the online engine's identification at the stops (the ``gmwm`` row's), not a fit
of its own: the filter pairs it carries equal, to the bit, what a :class:`StopModeller` identifies and refits from
the stop segments the engine kept on the learning drive."""

from __future__ import annotations

from collections import defaultdict

import numpy as np
import pytest

from imunoise.errors import ModelError
from imunoise.experiments.common import filter_models, simulate_scenario
from imunoise.experiments.dense_methods import method_setup
from imunoise.experiments.dense_warm import gmwm_on_drives
from imunoise.experiments.in_use_method import learn_in_use
from imunoise.online import OnlineConfig
from imunoise.online.modeller import StopModeller

BASE = OnlineConfig(latency=0.5)


def _modeller_on_kept_stops(sc, full) -> StopModeller:
    """A fresh modeller fed the raw samples of the stops the run kept, one ``stop_done`` per completed stop (the
    ``stop_end`` events of one time belong to one detected stop), as the navigator feeds its own."""
    cfg, _, _ = method_setup("gmwm", sc, BASE, {})
    gyro, accel = sc.imu.rates()
    rows = np.column_stack([gyro, accel])
    done_at = [e["t"] for e in full.events if e["event"] == "stop_end"]
    assert len(done_at) == len(full.segments)
    by_stop: dict[float, list] = defaultdict(list)
    for t, seg in zip(done_at, full.segments, strict=True):
        by_stop[t].append(seg)
    m = StopModeller(cfg, sc.rate, [])
    for t in sorted(by_stop):
        for seg in by_stop[t]:
            m.add_stop(seg, rows[seg.i0:seg.i1], t)
        m.stop_done(t)
    return m


@pytest.mark.slow
def test_in_use_static_models_are_the_online_modellers_on_the_same_stops():
    sc = simulate_scenario(4960, n_outages=0, duration_s=200.0, n_stops=1, motion_noise="none")
    full = gmwm_on_drives([(sc, sc.gnss)], BASE)
    m = _modeller_on_kept_stops(sc, full)
    assert any(u.kind == "identify" for u in m.updates) and any(u.kind == "refit" for u in m.updates)
    for a in range(6):  # the engine's run and the modeller alone identify the same fits, bit for bit
        assert str(full.fits[a].model) == str(m.fits[a].model)
        assert np.array_equal(full.fits[a].model.vector, m.fits[a].model.vector)
    model = learn_in_use([(sc, sc.gnss)], full.fits, BASE)
    expected = filter_models(m.fits, sc.rate, BASE.with_(ekf=sc.ekf_config()))
    assert len(model.models) == 6
    for got, want in zip(model.models, expected, strict=True):  # models, each with its rate
        assert got.freq == want.freq == sc.rate and str(got) == str(want)
        assert np.array_equal(got.vector, want.vector)


def test_in_use_without_the_six_fits_is_refused():
    sc = simulate_scenario(4960, n_outages=0, duration_s=200.0, n_stops=1, motion_noise="none")
    with pytest.raises(ModelError, match="six per-axis fits"):
        learn_in_use([(sc, sc.gnss)], [], BASE)
