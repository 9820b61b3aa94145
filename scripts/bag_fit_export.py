"""Issue 6 acceptance 1: WN+RW IMU (N = 2^22 at 200 Hz) in .bag, .db3, .mcap -> fit --auto -> export kalibr."""

import json
import shutil
import sys
import time
from pathlib import Path

import numpy as np

from imunoise.cli import main
from imunoise.export import read_export
from imunoise.io.rosbag import write_imu_bag
from imunoise.noise.model import Model

F, n = 200.0, 2**22
TRUTH = {"gyro": (1.6968e-4, 1.9393e-5), "accel": (2.0e-3, 3.0e-3)}  # EuRoC-like N [u/√Hz], K [u/s/√Hz]
root = Path(sys.argv[1] if len(sys.argv) > 1 else "/tmp/acc/run")
shutil.rmtree(root, ignore_errors=True)
root.mkdir(parents=True)
cols = []
for i in range(6):
    N, K = TRUTH["gyro" if i < 3 else "accel"]
    # docs/guide/theory.rst, 'Latent processes'
    m = Model.parse("WN+RW").with_params({"WN.sigma2": N * N * F, "RW.gamma2": K * K / F})
    cols.append(m.simulate(n, seed=100 + i))
x = np.column_stack(cols)
stamps = 1_700_000_000_000_000_000 + np.arange(n, dtype=np.int64) * 5_000_000
res = {}
for name in ("imu.bag", "imu2.db3", "imu3.mcap"):
    t0 = time.perf_counter()
    p = write_imu_bag(root / name, stamps, x[:, :3], x[:, 3:], topic="/imu0")
    tw = time.perf_counter() - t0
    out = root / ("fit_" + name.replace(".", "_"))
    t0 = time.perf_counter()
    assert main(["fit", str(p), "--auto", "--export", "kalibr", "--out", str(out)]) == 0
    tf = time.perf_counter() - t0
    model = json.loads((out / "imu_model.json").read_text())
    res[name] = (model, read_export(out / "imu.yaml"), tw, tf)
print("\n\n==== acceptance 1 ====")
print(f"N = 2^22 = {n} samples at {F:g} Hz ({n / F / 3600:.2f} h) per axis; truth {TRUTH}")
ref = None
for name, (model, k, tw, tf) in res.items():
    models = {a: d["model"] for a, d in model["axes"].items()}
    params = {a: d["params"] for a, d in model["axes"].items()}
    same = "reference" if ref is None else ("identical params" if params == ref else "DIFFERENT")
    ref = ref or params
    print(f"{name:10s} write {tw:5.1f} s, fit+export {tf:5.1f} s; models {sorted(set(models.values()))}; {same}")
    for s, key in (("gyro", "gyroscope"), ("accel", "accelerometer")):
        N, K = TRUTH[s]
        en = k[f"{key}_noise_density"] / N - 1
        ek = k[f"{key}_random_walk"] / K - 1
        print(
            f"   {key:13s} noise_density {k[f'{key}_noise_density']:.5e} ({100 * en:+.2f} %)  "
            f"random_walk {k[f'{key}_random_walk']:.5e} ({100 * ek:+.2f} %)  [max over axes]"
        )
    for a, d in model["axes"].items():
        s = "gyro" if a.startswith("gyro") else "accel"
        c = d["continuous"]
        print(
            f"   {a}: {d['model']}: N {100 * (c['WN.noise_density'] / TRUTH[s][0] - 1):+.2f} %, "
            f"K {100 * (c.get('RW.random_walk', 0) / TRUTH[s][1] - 1):+.2f} %"
        )
