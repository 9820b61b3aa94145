"""Cold start (issue "Evidence with power" §3): in a fresh process the online engine compiles or loads its
modelling kernels at construction (:func:`imunoise.warm_up`), so the first identification compiles nothing.

The behaviour is checked, not the time (speed targets live in benchmarks/bench_cold_start.py): a fresh
interpreter runs the online engine on the first 30 s of data/drive_0708 (up to the first identification)
and records every numba dispatcher's signatures right before and right after the identification job.
A signature added in between is a compilation (or a cache load) the first stop waited for. The same
run without the warm-up must show such additions, which proves the probe can see them.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
DRIVE = REPO / "data" / "drive_0708"

PROBE = textwrap.dedent(
    """
    import json, sys
    import numpy as np
    from numba.core.dispatcher import Dispatcher
    import imunoise.online as online
    from imunoise.io.dataset import read_dataset
    from imunoise.io.kfgins import read_gnss, read_imu
    from imunoise.nav.align import coarse_align

    def signatures():
        out = {}
        for name, mod in list(sys.modules.items()):
            if name.startswith("imunoise") and mod is not None:
                for attr, obj in vars(mod).items():
                    if isinstance(obj, Dispatcher):
                        out[f"{obj.__module__}.{obj.__name__}"] = {str(s) for s in obj.signatures}
        return out

    added = []
    import imunoise.online.modeller as home  # where the online engine calls the modelling job
    name = "model_job"
    job = getattr(home, name)

    def probed(kind, *args, **kw):
        before = signatures()
        out = job(kind, *args, **kw)
        after = signatures()
        if kind == "identify" and not added:
            added.append(sorted(k for k, v in after.items() if v - before.get(k, set())))
        return out

    setattr(home, name, probed)
    ds = read_dataset(sys.argv[1])
    imu = read_imu(ds.imu, time_offset=ds.imu_time_offset_s)
    gnss = read_gnss(ds.gnss)
    t0 = float(ds.extra["start_sow"])
    init = coarse_align(imu, gnss, t0, static_duration=30.0, lever_arm=np.asarray(ds.lever_arm_m, dtype=float))
    imu, gnss = imu.slice(imu.t[0], t0 + 30.0), gnss.slice(gnss.t[0], t0 + 30.0)
    cfg = online.OnlineConfig(warm_up=sys.argv[2] == "1", store=False)
    nav = online.OnlineNavigator(cfg, init, imu_rate_hz=float(imu.rate_hz))
    res = nav.run(imu, gnss)
    ev = [e for e in res.events if e["event"] in ("warm_up", "identified")]
    print(json.dumps({"added": added[0] if added else None, "events": ev}))
    """
)


def _probe(warm: bool) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(REPO / "src") + os.pathsep + env.get("PYTHONPATH", "")
    out = subprocess.run([sys.executable, "-c", PROBE, str(DRIVE), "1" if warm else "0"], capture_output=True,
                         text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not (DRIVE / "dataset.json").exists(), reason="data/drive_0708 not in this checkout")
def test_first_identification_compiles_nothing_after_the_warm_up():
    warm = _probe(True)
    kinds = [e["event"] for e in warm["events"]]
    assert kinds == ["warm_up", "identified"], kinds  # warm-up logged at construction, before the first stop
    info = warm["events"][0]
    assert "error" not in info and info["worker"] == "inline" and info["time_s"] > 0
    assert info["compiled"] + info["loaded"] >= 4  # the fitting kernels were compiled or loaded here
    assert len(warm["events"][1]["axes"]) == 6
    assert warm["added"] == [], f"compiled during the first identification: {warm['added']}"

    cold = _probe(False)
    assert [e["event"] for e in cold["events"]] == ["identified"]
    # without the warm-up the solver kernels get their first signature inside the identification
    assert "imunoise.noise.fitting.kernels.levenberg_marquardt" in cold["added"], cold["added"]
    assert "imunoise.noise.fitting.kernels.objectives" in cold["added"], cold["added"]
