"""`imunoise warm-up`: compile every numba kernel that `nav`, `online`, `fit`, `select`, `calibrate`, `em`,
`allan` and `experiment` use into numba's on-disk cache, so that the first real command compiles nothing.

How: each kernel group runs the commands' own code paths (the CLI handlers, in this process, output
discarded) on tiny inputs written to a temporary folder: a 30 000-sample static series (.npy) and a
simulated 200 s drive (KF-GINS text files, :func:`imunoise.sim.simulate_drive`). The kernels therefore get
exactly the type signatures (float64 C-contiguous arrays, int64/float64 scalars, optional arguments) that
the real runs ask for: a specialisation compiled here is the one a later process loads. The online engine's
own modelling warm-up (:func:`imunoise.warm_up`) runs too. With the cache already warm the command only
loads the kernels (a few seconds).

``--timings`` adds the CPU time each kernel took to compile in this run (zero when it came from the cache).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

__all__ = ["GROUPS", "register", "run", "warm_up_all"]

EPILOG = """examples:
  imunoise warm-up                   # once after an install: later commands compile nothing
  imunoise warm-up --timings         # also the compile CPU time of every kernel (run with an empty cache)
  NUMBA_CACHE_DIR=/opt/cache imunoise warm-up   # a cache outside a read-only install"""

# the simulated drive of the navigation groups: a static start (alignment, first identification of the
# online engine), one stop, one GNSS outage (the `--outage-runs` path)
_DRIVE = {"duration_s": 200.0, "n_stops": 1, "stop_range_s": (25.0, 30.0), "static_s": 40.0,
          "outages": [(100.0, 15.0)], "lever_arm_m": (0.0, -0.05, 0.0), "seed": 0}


def _cli(*argv: object) -> None:
    """One command of the CLI in this process, its output discarded; a failure is an error of the warm-up."""
    from imunoise.cli import main

    args = [str(a) for a in argv]
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(args)
        except SystemExit as exc:  # argparse refused the arguments
            code = exc.code
    if code != 0:
        raise RuntimeError(f"warm-up: `imunoise {' '.join(args)}` exited {code}: {err.getvalue().strip()[-500:]}")


def _static(tmp: Path) -> Path:
    path = tmp / "static.npy"
    if not path.exists():
        import numpy as np

        rng = np.random.default_rng(0)
        n = 30_000
        x = 1e-3 * rng.standard_normal((n, 6)) + 1e-6 * np.cumsum(rng.standard_normal((n, 6)), axis=0)
        np.save(path, x)
    return path


def _drive(tmp: Path) -> Path:
    out = tmp / "drive"
    if not (out / "dataset.json").exists():
        from imunoise.sim import DriveConfig, simulate_drive

        simulate_drive(DriveConfig(**_DRIVE), "mems", seed=0).write(out)
    return out


def _modelling(tmp: Path) -> None:
    import imunoise

    x = _static(tmp)
    imunoise.warm_up()  # the online engine's identification and refit path
    _cli("fit", x, "--freq", 100, "--column", 0, "--model", "2*AR1+WN+RW", "--out", tmp / "fit")
    _cli("fit", x, "--freq", 100, "--column", 0, "--auto", "--robust", "--out", tmp / "fit_auto")
    _cli("fit", x, "--freq", 100, "--column", 0, "--model", "AR1+WN+RW", "--stream", "--out", tmp / "fit_stream")
    _cli("select", x, "--freq", 100, "--column", 0, "--out", tmp / "select")


def _baselines(tmp: Path) -> None:
    x = _static(tmp)
    _cli("allan", x, "--freq", 100, "--column", 0, "--out", tmp / "allan")
    _cli("em", x, "--freq", 100, "--column", 0, "--model", "AR1+WN+RW", "--max-iter", 3, "--out", tmp / "em")


def _navigation(tmp: Path) -> None:
    d = _drive(tmp)
    _cli("nav", "--data", d, "--no-plots", "--out", tmp / "nav")
    _cli("nav", "--data", d, "--zupt", "--outage-runs", "--no-plots", "--out", tmp / "nav_zupt")


def _online(tmp: Path) -> None:
    d = _drive(tmp)
    _cli("online", "--data", d, "--out", tmp / "online")
    # with ZUPT/ZARU at the stops (the demo's gmwm_zupt): the step filter's ZARU kernel, which `nav --zupt`
    # (ZUPT only) does not call; left cold, two demo workers compiled it at once
    _cli("online", "--data", d, "--zupt", "--out", tmp / "online_zupt")


def _calibrate(tmp: Path) -> None:
    _cli("calibrate", _drive(tmp), "--out", tmp / "calibrate")


def _experiment(tmp: Path) -> None:
    _cli("experiment", "online", "--sim", "--seeds", 1, "--duration", 200, "--stops", 1, "--outages", "dense:15:20:60",
         "--workers", 1, "--bootstrap", 10, "--out", tmp / "experiment")


# (name, the commands that use the group, what runs it); later groups reuse the kernels of earlier ones
GROUPS: list[tuple[str, str, Callable[[Path], None]]] = [
    ("modelling", "fit, select, online, calibrate, experiment", _modelling),
    ("baselines", "allan, em, experiment", _baselines),
    ("navigation filter", "nav, simulate, experiment", _navigation),
    ("online engine", "online, experiment, demo", _online),
    ("calibration", "calibrate", _calibrate),
    ("experiments", "experiment, demo", _experiment),
]


def warm_up_all(progress: Callable[[str], None] | None = None, recorder: Any = None) -> list[dict[str, Any]]:
    """Run every group of :data:`GROUPS` once (module docstring); returns one dict per group: ``name``,
    ``commands``, ``wall_s``, ``cpu_s``, ``compiled`` (signatures compiled now) and ``loaded`` (from the cache).

    ``progress`` receives one line per group as it ends; ``recorder`` (a
    :class:`~imunoise.cli.kernel_cache.CompileRecorder`) is entered around the whole run when given.
    """
    import warnings

    rows = []
    with tempfile.TemporaryDirectory(prefix="imunoise-warm-up-") as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the tiny inputs are meant to be tiny
        with recorder if recorder is not None else contextlib.nullcontext():
            for i, (name, commands, fn) in enumerate(GROUPS, 1):
                before = _cache_counts()
                w0, c0 = time.perf_counter(), time.process_time()
                fn(Path(tmp))
                after = _cache_counts()
                row = {"name": name, "commands": commands, "wall_s": time.perf_counter() - w0,
                       "cpu_s": time.process_time() - c0, "compiled": after[1] - before[1],
                       "loaded": after[0] - before[0]}
                rows.append(row)
                if progress is not None:
                    progress(f"[{i}/{len(GROUPS)}] {name} ({commands}): {row['compiled']} compiled, "
                             f"{row['loaded']} loaded from the cache, {row['wall_s']:.1f} s")
    return rows


def _cache_counts() -> tuple[int, int]:
    """(cache hits, compilations) summed over every imunoise kernel imported so far."""
    from numba.core.dispatcher import Dispatcher

    hits = misses = 0
    seen: set[int] = set()
    for name, mod in list(sys.modules.items()):
        if not name.startswith("imunoise") or mod is None:
            continue
        for obj in list(vars(mod).values()):
            if isinstance(obj, Dispatcher) and id(obj) not in seen and obj.__module__ == name:
                seen.add(id(obj))
                hits += sum(obj.stats.cache_hits.values())
                misses += sum(obj.stats.cache_misses.values())
    return hits, misses


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "warm-up",
        help="compile every numba kernel into the on-disk cache (once after an install)",
        description=__doc__,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--timings", action="store_true",
                   help="print the compile CPU time of every kernel compiled in this run")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from imunoise.cli.kernel_cache import CompileRecorder, cache_dir_problem, silence
    from imunoise.errors import DataError

    problem = cache_dir_problem()
    if problem:  # before any work: numba would write elsewhere and the warm-up would look successful
        raise DataError(problem)
    silence()

    print("imunoise warm-up: compiling (or loading) the kernels of every command; with an empty cache "
          "this takes a few minutes once", flush=True)
    w0, c0 = time.perf_counter(), time.process_time()
    recorder = CompileRecorder() if args.timings else None
    rows = warm_up_all(lambda line: print(line, flush=True), recorder)
    compiled = sum(r["compiled"] for r in rows)
    print(f"done in {time.perf_counter() - w0:.1f} s ({time.process_time() - c0:.1f} s CPU): {compiled} "
          f"signatures compiled, {sum(r['loaded'] for r in rows)} loaded from numba's cache", flush=True)
    if recorder is not None:
        rows = recorder.by_kernel()
        print("\n| kernel | module | signatures | compile CPU cold [s] | + numba helpers [s] |\n"
              "|---|---|---:|---:|---:|")
        for mod, fn, n, own, helpers in rows:
            print(f"| `{fn}` | `{mod}` | {n} | {own:.2f} | {helpers:.2f} |")
        print(f"| all | | {sum(r[2] for r in rows)} | {sum(r[3] for r in rows):.2f} | "
              f"{sum(r[4] for r in rows):.2f} |")
    return 0
