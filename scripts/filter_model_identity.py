"""The paths from a fitted model into the filter, saved and compared exactly: a change of how models reach the
filter (e.g. a model carrying its sample rate instead of (model, freq) pairs) must leave them identical to the bit.

    PYTHONPATH=OLD/src python scripts/filter_model_identity.py run before.pkl    # with the code before
    PYTHONPATH=NEW/src python scripts/filter_model_identity.py run after.pkl     # with the code after
    python scripts/filter_model_identity.py compare before.pkl after.pkl

Runs (from the repository root, which holds ``data/drive_0708``): six GMWM fits (AR1 + WN + RW of 2^15 simulated
samples per axis at 200 Hz, seeds 100-105) saved as one model file; ``nav`` and ``online`` (``--latency 1``) on the
shipped drive with that file (the trajectory files' bytes); on simulated drive 1000 (300 s, two stops, the default
motion law, the ``dense:60:20`` windows) ``run_windows_law`` with the law, the oracle's and the plain models, and
``evaluate_method`` for ``oracle_law``, ``adaptive``, ``av`` and ``gmwm_dyn`` (latency 1 s: with ``latency=None`` a
model takes effect after its measured compute time, which differs from run to run). Compared: everything exactly.
About 5 minutes per ``run`` on one core.
"""

from __future__ import annotations

import hashlib
import sys
import tempfile
from pathlib import Path

from identity_harness import run_or_compare, same_exactly

AXES = ("gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")


def model_file(path: Path) -> dict:
    from imunoise.noise.estimator import gmwm
    from imunoise.noise.imu_model import ImuModel
    from imunoise.noise.processes import AR1, RW, WN

    fits = {}
    for k, a in enumerate(AXES):
        s = 1e-5 if a.startswith("gyro") else 1e-3
        truth = AR1(phi=0.9995, sigma2=(0.05 * s) ** 2) + WN(sigma2=s * s) + RW(gamma2=(1e-4 * s) ** 2)
        fits[a] = gmwm(AR1() + WN() + RW(), truth.simulate(2**15, seed=100 + k), freq=200.0,
                       unit="rad/s" if a.startswith("gyro") else "m/s^2")
    ImuModel.from_fits(fits).save(path)
    return {a: (str(f.model), f.model.vector.tolist(), f.objective) for a, f in fits.items()}


def md5(path: Path) -> str:
    return hashlib.md5(path.read_bytes()).hexdigest()


def run() -> dict:
    from imunoise.cli import main as cli_main
    from imunoise.experiments import dense
    from imunoise.experiments.common import simulate_scenario
    from imunoise.experiments.online_exp import method_config
    from imunoise.experiments.oracle_law import run_windows_law
    from imunoise.nav.defaults import default_axis_models
    from imunoise.online import OnlineConfig

    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "model.json"
        out["fits"] = model_file(p)
        assert cli_main(["nav", "--data", "data/drive_0708", "--imu-model", str(p), "--no-plots",
                         "--out", f"{tmp}/nav"]) == 0
        out["nav"] = md5(Path(tmp) / "nav" / "trajectory.nav")
        assert cli_main(["online", "--data", "data/drive_0708", "--imu-model", str(p), "--latency", "1",
                         "--out", f"{tmp}/online"]) == 0
        out["online"] = [md5(Path(tmp) / "online" / f) for f in ("trajectory.nav", "static.npz")]
    print("files", flush=True)
    sc = simulate_scenario(1000, duration_s=300.0, n_stops=2, n_outages=0)
    windows = dense.dense_windows(sc, dense.parse_outages("dense:60:20")[1])
    cfg, oracle_models = method_config("oracle", sc)
    for name, models in (("law", None), ("law_oracle", oracle_models),
                         ("law_plain", default_axis_models(sc.rate, cfg.ekf.fallback))):
        out[name] = [w["drift"] for w in run_windows_law(sc, sc.gnss, windows, models=models)["windows"]]
    for m in ("oracle_law", "adaptive", "av", "gmwm_dyn"):
        r = dense.evaluate_method(sc, m, sc.gnss, windows, base=OnlineConfig(latency=1.0))
        out[m] = [(w["drift"], w.get("rms"), w.get("aided_rms")) for w in r["windows"]]
        print(m, flush=True)
    return out


def main(argv: list[str]) -> int:
    return run_or_compare(argv, run, same_exactly, __doc__)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
