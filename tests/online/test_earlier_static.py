"""Static data of earlier drives pooled with a drive's stops (``OnlineNavigator(earlier_static=...)``)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from imunoise.errors import DataError
from imunoise.experiments import dense
from imunoise.experiments.common import simulate_scenario
from imunoise.online import OnlineConfig, OnlineNavigator

RATE = 100.0
SIGMA = np.array([2e-3, 3e-3, 4e-3, 0.02, 0.03, 0.04])  # white noise per sample: rad/s, m/s²


def _pieces(seed: int, n: int = 30, seconds: float = 40.0) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    bias = rng.normal(0.0, 0.05, (n, 6))  # each piece its own bias (removed when pooled)
    return [b + rng.normal(0.0, 1.0, (int(seconds * RATE), 6)) * SIGMA for b in bias]


@pytest.fixture(scope="module")
def drive():
    return simulate_scenario(3, duration_s=240.0, n_stops=2, n_outages=0, motion_noise="none")


SCALES = np.array([2.0, 4.0, 8.0, 16.0, 64.0])  # samples


def _wv_white(sigma2: float) -> np.ndarray:
    from imunoise.noise.model import Model
    from imunoise.noise.processes import WN

    return Model([WN(sigma2=sigma2)]).wv(SCALES)


def test_earlier_static_identifies_the_model_before_the_first_sample(drive):
    """1200 s of white noise of known σ from earlier drives: the model is identified at construction, in
    effect from the drive's start, and its WV is the white noise's (within 8 % from 0.02 to 0.64 s, ~2.5 σ of the
    estimate at 0.64 s; the structure may split the white noise among processes)."""
    cfg = OnlineConfig(ekf=drive.ekf_config(), criterion="gof", warm_up=False)
    nav = OnlineNavigator(cfg, drive.init, imu_rate_hz=RATE, earlier_static=_pieces(1))
    assert nav.static_s == pytest.approx(1200.0)
    assert [u.kind for u in nav.updates] == ["identify"] and nav.updates[0].t_effect == drive.init.t
    for a in range(6):
        np.testing.assert_allclose(nav.fits[a].model.wv(SCALES), _wv_white(SIGMA[a] ** 2), rtol=0.08)
    ev = [e for e in nav.events if e["event"] == "earlier_static"]
    assert ev and ev[0]["pieces"] == 30 and ev[0]["static_s"] == pytest.approx(1200.0)
    dth, dv = drive.imu.increments()
    i = int(np.searchsorted(drive.imu.t, drive.init.t, side="right"))
    for k in range(i, i + int(15 * RATE)):  # past the 10 s the detector learns λ0 on, held before the filter
        nav.push_imu(drive.imu.t[k], dth[k], dv[k])
    swaps = [e for e in nav.events if e["event"] == "swap"]  # at the filter's first sample
    assert len(swaps) == 1 and swaps[0]["job"] == "identify" and swaps[0]["t"] == drive.imu.t[i]
    assert nav.current_models == nav.filter_models()
    given = _pieces(1)
    assert len(nav.static_pieces()) == 30  # handed on as given (the next drive recognises them by their bytes)
    assert all(np.array_equal(a, b) for a, b in zip(nav.static_pieces(), given, strict=True))


def test_pooled_drive_refits_on_earlier_and_own_stops_and_a_shared_cache_changes_nothing(drive):
    """The drive's own stops refit on the pool; the modelling-job cache shared with a run without earlier
    data (as the experiments share it between methods) gives the same result as a private one."""
    cfg = dense.method_setup("gmwm", drive)[0].with_(latency=0.5)  # swap times independent of the machine
    earlier = _pieces(2, n=10)
    shared: dict = {}
    plain_run = OnlineNavigator(cfg, drive.init, imu_rate_hz=RATE, job_cache=shared).run(drive.imu, drive.gnss)
    with_shared = OnlineNavigator(cfg, drive.init, imu_rate_hz=RATE, job_cache=shared,
                                  earlier_static=earlier).run(drive.imu, drive.gnss)
    with_own = OnlineNavigator(cfg, drive.init, imu_rate_hz=RATE, job_cache={},
                               earlier_static=earlier).run(drive.imu, drive.gnss)
    assert len(with_own.segments) >= 1 and [u.kind for u in with_own.updates][0] == "identify"
    assert all(u.kind == "refit" for u in with_own.updates[1:]) and len(with_own.updates) > 1
    assert with_own.updates[-1].static_s == pytest.approx(400.0 + sum(s.duration for s in with_own.segments))
    assert len(with_own.static_pieces) == 10 + len(with_own.segments)
    np.testing.assert_array_equal(with_shared.llh, with_own.llh)
    assert not np.array_equal(with_own.llh, plain_run.llh)


@pytest.mark.parametrize("bad, msg", [([np.zeros((100, 5))], "expected an \\(N, 6\\) array"),
                                      ([np.full((100, 6), np.nan)], "non-finite")])
def test_bad_earlier_static_is_refused_with_a_one_line_reason(drive, bad, msg):
    with pytest.raises(DataError, match=msg):
        OnlineNavigator(OnlineConfig(ekf=drive.ekf_config()), drive.init, imu_rate_hz=RATE, earlier_static=bad)


# ------------------------------------------------------------------------------------------------------
# imunoise online: static.npz out, --earlier-static in
# ------------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def short_files(tmp_path_factory):
    """60 s and 150 s of the shipped drive (34.5 s still, then driving) as plain files, and the same from 1 s
    later (a stand-in for another drive of the IMU: other samples)."""
    import gzip
    from pathlib import Path

    drive_dir = Path(__file__).resolve().parents[2] / "data" / "drive_0708"
    if not (drive_dir / "imu_body_inc.txt.gz").is_file():
        pytest.skip("data/drive_0708 is not in this checkout")
    d = tmp_path_factory.mktemp("short")
    with gzip.open(drive_dir / "imu_body_inc.txt.gz", "rt") as fh:
        lines = [next(fh) for _ in range(15000)]
    (d / "imu.txt").write_text("".join(lines[:6000]))
    (d / "imu_b.txt").write_text("".join(lines[100:6000]))
    (d / "imu_long.txt").write_text("".join(lines))  # 150 s: two minutes of driving for the learner's rounds
    (d / "imu_long_b.txt").write_text("".join(lines[100:]))
    gnss = (drive_dir / "gnss_rtk.txt").read_text().splitlines(keepends=True)
    (d / "gnss.txt").write_text("".join(gnss[:400]))
    return d


def _online(files, out, *extra, imu="imu.txt") -> dict:
    from imunoise.cli import main

    argv = ["online", "--imu", files / imu, "--gnss", files / "gnss.txt", *extra, "--out", out]
    assert main([str(a) for a in argv]) == 0
    return json.loads((out / "metrics.json").read_text())


def test_cli_chains_static_data_across_drives(short_files, tmp_path):
    """static.npz holds what the model was fitted on; the next run pools it from its first sample; a chain
    needs only its last file, and a piece given twice is pooled once."""
    from imunoise.io.static_npz import load_static_pieces

    m1 = _online(short_files, tmp_path / "a")
    p1 = load_static_pieces([tmp_path / "a" / "static.npz"], 100.0)
    assert m1["earlier_static_s"] == 0.0 and p1
    assert sum(p.shape[0] for p in p1) / 100.0 == pytest.approx(m1["static_s"], abs=0.1)  # ≤ 1 sample a piece
    m2 = _online(short_files, tmp_path / "b", "--earlier-static", tmp_path / "a" / "static.npz", imu="imu_b.txt")
    assert m2["earlier_static_s"] == pytest.approx(m1["static_s"], abs=0.1)
    p2 = load_static_pieces([tmp_path / "b" / "static.npz"], 100.0)
    own = m2["static_s"]
    assert len(p2) > len(p1)  # the earlier drive's pieces, then its own
    for a, b in zip(p1, p2[: len(p1)], strict=True):
        np.testing.assert_array_equal(a, b)
    m3 = _online(short_files, tmp_path / "c", "--earlier-static", tmp_path / "a" / "static.npz",
                 tmp_path / "b" / "static.npz")
    assert m3["earlier_static_s"] == pytest.approx(m1["static_s"] + own, abs=0.2)  # a's pieces once, not twice
    events = [json.loads(x) for x in (tmp_path / "b" / "events.jsonl").read_text().splitlines()]
    first = [e["event"] for e in events if e["event"] in ("earlier_static", "identified", "swap")][:3]
    assert first == ["earlier_static", "identified", "swap"]


def test_cli_refuses_a_static_file_of_another_rate_before_writing(short_files, tmp_path, capsys):
    from imunoise.cli import main
    from imunoise.io.static_npz import save_static_pieces

    bad = save_static_pieces(tmp_path / "s200.npz", [np.zeros((100, 6))], 200.0)
    out = tmp_path / "never"
    argv = ["online", "--imu", short_files / "imu.txt", "--gnss", short_files / "gnss.txt", "--earlier-static", bad,
            "--out", out]
    assert main([str(a) for a in argv]) == 2
    err = capsys.readouterr().err
    assert "200 Hz" in err and "Traceback" not in err
    assert not out.exists() or not any(out.rglob("*"))  # nothing written


@pytest.mark.slow  # the warm methods' evidence path on two simulated drives
def test_experiment_methods_pool_the_earlier_drives_stops():
    """gmwm_warm / gmwm_warm3 get the stops of their earlier drives, and only they; two earlier drives pool
    more than one (chained as a user would)."""
    from imunoise.errors import ModelError
    from imunoise.experiments.gnss_regimes import GnssRegime

    kw = {"duration_s": 200.0, "n_stops": 1, "motion_noise": "none"}
    one = dense.earlier_stops(11, GnssRegime(), 0, n_drives=1, **kw)
    two = dense.earlier_stops(11, GnssRegime(), 0, n_drives=2, **kw)
    assert one and sum(p.shape[0] for p in two) > sum(p.shape[0] for p in one)
    sc = simulate_scenario(11, n_outages=0, **kw)
    for name, pooled in (("gmwm_warm", None), ("gmwm", one)):
        with pytest.raises(ModelError, match="earlier drives' stops"):
            dense.evaluate_method(sc, name, sc.gnss, [], earlier_static=pooled)
    cfg, _, _ = dense.method_setup("gmwm_warm3", sc)
    assert cfg == dense.method_setup("gmwm", sc)[0]


def test_static_npz_round_trip_and_refusals(tmp_path):
    from imunoise.io.static_npz import load_static_pieces, save_static_pieces

    pieces = _pieces(3, n=3, seconds=1.0)
    save_static_pieces(tmp_path / "s.npz", pieces, RATE)
    back = load_static_pieces([tmp_path / "s.npz", tmp_path / "s.npz"], RATE)  # the second file adds nothing
    assert len(back) == 3 and all(np.array_equal(a, b) for a, b in zip(back, pieces, strict=True))
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    save_static_pieces(tmp_path / "five.npz", [np.zeros((10, 5))], RATE)
    for name, msg in (("missing.npz", "no such file"), ("junk.npz", "not a static.npz"),
                      ("other.npz", "needs rate_hz and piece_NNN"), ("five.npz", "not a finite \\(N, 6\\) array")):
        with pytest.raises(DataError, match=msg):
            load_static_pieces([tmp_path / name], RATE)


def test_cli_carries_the_motion_noise_evidence_to_the_next_drive(short_files, tmp_path):
    """`--learn-motion-noise` writes its evidence into metrics.json; `--motion-noise-prior` of that file starts the
    next run with it (the two-command chain of the README, on 150 s of the shipped drive)."""
    m1 = _online(short_files, tmp_path / "a", "--learn-motion-noise", imu="imu_long.txt")
    ev = m1["motion_noise"]["evidence"]
    assert m1["config"]["learn_motion_noise"] and m1["motion_noise"]["carried_rounds"] == 0
    assert ev["rounds"] == m1["motion_noise"]["rehearsal_rounds"] >= 3, m1["motion_noise"]["rehearsal_rounds"]
    m2 = _online(short_files, tmp_path / "b", "--motion-noise-prior", tmp_path / "a" / "metrics.json",
                 imu="imu_long_b.txt")
    assert m2["config"]["motion_noise_prior"] == str(tmp_path / "a" / "metrics.json")
    assert m2["motion_noise"]["carried_rounds"] == ev["rounds"]
    ev2 = m2["motion_noise"]["evidence"]
    assert ev2["rounds"] == ev["rounds"] + m2["motion_noise"]["rehearsal_rounds"]
