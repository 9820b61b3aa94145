"""The filter engine against the code before it was made one step sequence, in the same run (CPU time).

The older tree is ``git archive`` of :data:`BEFORE` (the last commit with the three loops); both trees run the
batch filter on data/drive_0708 (548 s, NHC on) and the online engine without modelling, a fresh process per
tree and round, rounds alternating (``scripts/engine_speed.py``, which also counts instructions under
callgrind: ``--clock instructions``).
"""

from __future__ import annotations

import importlib.util
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
BEFORE = "a9880b7"
"""The commit before the one step sequence (its three loops: run_batch, run_span, propagate)."""
ROUNDS = 4


def _speed_script():
    spec = importlib.util.spec_from_file_location("engine_speed", REPO / "scripts" / "engine_speed.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["engine_speed"] = module
    spec.loader.exec_module(module)
    return module


def main() -> str:
    sp = _speed_script()
    with tempfile.TemporaryDirectory() as tmp:
        archive = subprocess.run(["git", "-C", str(REPO), "archive", BEFORE, "src"], check=True,
                                 capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", tmp], input=archive, check=True)
        trees = {"old": str(Path(tmp) / "src"), "new": str(REPO / "src")}
        res: dict[str, list[dict]] = {"old": [], "new": []}
        for r in range(ROUNDS):
            for name in (("old", "new") if r % 2 == 0 else ("new", "old")):
                res[name].append(sp.one(trees[name]))
    lines = ["## Filter engine against the code before it (same run)\n",
             f"Old: `git archive {BEFORE} src` (three step loops); new: this tree (one step sequence, "
             "`imunoise.nav.filter_loop.run_steps`). CPU seconds of one run on data/drive_0708 (548 s): the batch "
             "filter with NHC (best of 3 per process) and the online engine without modelling (best of 2), a fresh "
             f"process per tree and round, {ROUNDS} rounds alternating; median over rounds, and new/old with a "
             "95 % bootstrap interval over the rounds (`scripts/engine_speed.py`).\n",
             "| run | old [s CPU] | new [s CPU] | new / old (95 % CI) |", "|---|---|---|---|"]
    for key in ("batch", "online"):
        o = [x[key] for x in res["old"]]
        n = [x[key] for x in res["new"]]
        q, lo, hi = sp.ratio_ci(o, n)
        lines.append(f"| {key} | {statistics.median(o):.3f} | {statistics.median(n):.3f} | "
                     f"{q:.3f} ({lo:.3f}–{hi:.3f}) |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(main())
