"""CLI start-up and whole-process time (architecture issue, acceptance 3; issue "Performance where users wait",
acceptance 4).

`imunoise --help` is timed beside `python -c "import numpy"` and `python -c pass` in the same run (median of
5 fresh processes each; target ≤ 0.3 s on a quiet machine). `imunoise nav` on the bundled drive
(data/drive_0708, 548 s) is timed as a whole process, with and without the PNG figures, beside the
filter-only time the run reports itself (``elapsed_s`` of its metrics.json, docs/guide/theory.rst, 'Navigation filter'),
and the difference is
broken down: imports (``python -X importtime``) and the CPU of each phase of a run (:data:`PHASES`).

The C++ reference: when the environment variable ``IMUNOISE_KFGINS`` names a KF-GINS executable
(i2Nav-WHU/KF-GINS, GPL-3, built from its own repository: imunoise does not ship it), it runs in the same
interleaved rounds as `imunoise nav`, on the same drive, the same GNSS fixes (the manifest's outage windows
removed, as `nav` removes them) and the same initial state (position, velocity, attitude and gyro bias of
`nav`'s coarse alignment, its initial σ, the KF-GINS noise settings of the shared drive's reference run),
from a configuration written by :mod:`imunoise.io.kfgins_config`; one more run with every fix checks its
accuracy. Without the variable the KF-GINS row is the historical figure, labelled as such.
"""

from __future__ import annotations

import atexit
import json
import math
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DRIVE = REPO / "data" / "drive_0708"
REPS = 5
NAV_REPS = 5
KFGINS_ENV = "IMUNOISE_KFGINS"
IMPORT_GROUPS = ("numpy", "numba", "llvmlite", "scipy", "imunoise")


_PYCACHE: list[str] = []


def _env() -> dict[str, str]:
    """The checkout's code, whatever is installed, with Python's bytecode cache on as in an installed package
    (pip compiles every module at install): PYTHONDONTWRITEBYTECODE removed and the .pyc files kept in a
    temporary PYTHONPYCACHEPREFIX, outside the repository, filled by the first process of this run. Without
    it every imunoise module would be compiled from source in every process (~0.05 s CPU of a `nav`)."""
    if not _PYCACHE:
        _PYCACHE.append(tempfile.mkdtemp(prefix="imunoise-bench-pyc-"))
        atexit.register(shutil.rmtree, _PYCACHE[0], True)
    env = dict(os.environ, PYTHONPATH=str(REPO / "src") + os.pathsep + os.environ.get("PYTHONPATH", ""),
               PYTHONPYCACHEPREFIX=_PYCACHE[0])
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def _wall(argv: list[str]) -> float:
    return _wall_cpu(argv)[0]


def _wall_cpu(argv: list[str]) -> tuple[float, float]:
    """Wall time and CPU time (user + system) [s] of one process; CPU time suffers less from the other
    processes of a shared machine."""
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(argv, env=_env(), check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)


def _median_wall(argv: list[str], reps: int = REPS) -> tuple[float, float, float]:
    ts = [_wall(argv) for _ in range(reps)]
    return statistics.median(ts), min(ts), max(ts)


def _startup() -> list[str]:
    py = sys.executable
    cases = [
        ("`imunoise --help`", [py, "-m", "imunoise", "--help"]),
        ('`python -c "import numpy"`', [py, "-c", "import numpy"]),
        ("`python -c pass`", [py, "-c", "pass"]),
    ]
    for _, argv in cases:  # warm the file cache and write the .pyc files (_env)
        _wall(argv)
    # interleaved rounds, so that a burst of load on this shared machine hits every case alike
    times: dict[str, list[float]] = {label: [] for label, _ in cases}
    for _ in range(REPS):
        for label, argv in cases:
            times[label].append(_wall(argv))
    heavy = subprocess.run(
        [py, "-c", "import sys, imunoise.cli; imunoise.cli.build_parser(); "
         "print(sorted({m.split('.')[0] for m in sys.modules} & "
         "{'numpy', 'scipy', 'numba', 'matplotlib', 'dask', 'rosbags'}))"],
        env=_env(), capture_output=True, text=True, check=True,
    ).stdout.strip()  # fmt: skip
    help_s = statistics.median(times[cases[0][0]])
    lines = [
        "### Start-up",
        "",
        f"Median of {REPS} fresh processes (interleaved); target `imunoise --help` ≤ 0.3 s on a quiet machine.",
        "",
        "| command | median wall [s] | min wall [s] | max wall [s] |",
        "|---|---|---|---|",
    ]
    for label, _ in cases:
        ts = times[label]
        lines.append(f"| {label} | {statistics.median(ts):.3f} | {min(ts):.3f} | {max(ts):.3f} |")
    lines += [
        "",
        f"`imunoise --help` {'meets' if help_s <= 0.3 else 'misses'} the 0.3 s target ({help_s:.3f} s, "
        f"{help_s / statistics.median(times[cases[1][0]]):.2f}× the numpy import); numerical modules imported "
        f"by building the parser: {heavy} (tests/cli/test_cli_startup.py asserts none).",
    ]
    return lines


def _import_s(argv: list[str]) -> tuple[float, dict[str, float]]:
    """Total import time [s] of a process (``-X importtime``) and its split by top-level package (each
    module's own time, so nothing is counted twice)."""
    err = subprocess.run(
        [sys.executable, "-X", "importtime", *argv],
        env=_env(), check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    ).stderr  # fmt: skip
    by_pkg: dict[str, float] = {}
    for line in err.splitlines():
        if not line.startswith("import time:") or line.count("|") != 2:
            continue
        own, _, name = line.removeprefix("import time:").split("|")
        if not own.strip().isdigit():
            continue  # the header
        root = name.strip().split(".")[0]
        by_pkg[root] = by_pkg.get(root, 0.0) + int(own) / 1e6
    return sum(by_pkg.values()), by_pkg


# whole-process figures of KF-GINS (C++) on this drive, NOT measured by this script: issue "Performance where
# users wait" measured them on the same 2-core machine kind, same drive and same initial state
KFGINS_HISTORICAL = {"cpu_s": 1.19, "rss_mib": 4.7}

# phases of a `nav` process: each function's CPU (time.process_time) summed over its calls, in a fresh process
# run as from the command line (main() reading sys.argv); nothing is sampled or traced, so the figures add up
PHASES = [
    ("read IMU/GNSS/reference files", "imunoise.cli.nav", "read_nav_inputs"),
    ("coarse alignment (the first kernel call: numba's CPU target starts here)", "imunoise.nav.align", "coarse_align"),
    ("run_ekf (checks, kernel loads, filter, output arrays)", "imunoise.nav.ekf", "run_ekf"),
    ("write trajectory.nav", "imunoise.cli.nav", "write_trajectory"),
    ("errors against the reference (metrics)", "imunoise.cli.nav", "run_metrics"),
]
NUMBA_LABEL = "numba: CPU target set-up and cached machine code of every kernel (inside the rows above)"

_PHASE_RUN = """
import gc, importlib, json, sys, time
gc.disable()  # the timed modules are imported here, before main(): with the collector off as main() does
T = time.process_time
record = sys.argv[1]
spent, depth = {}, [0]
def wrap(owner, name, label):
    f = getattr(owner, name)
    def timed(*a, **k):
        nested = label == "numba" and depth[0] > 0  # a kernel load inside another: counted once
        depth[0] += label == "numba"
        t0 = T()
        try:
            return f(*a, **k)
        finally:
            depth[0] -= label == "numba"
            if not nested:
                spent[label] = spent.get(label, 0.0) + T() - t0
    setattr(owner, name, timed)
import imunoise.cli
for label, module, name in json.loads(sys.argv[2]):
    wrap(importlib.import_module(module), name, label)
from numba.core.dispatcher import Dispatcher
wrap(Dispatcher, "_compile_for_args", "numba")
gc.freeze()
gc.enable()
start = T()
def report():
    with open(record, "w") as f:
        json.dump({"start": start, "end": T(), **spent}, f)
sys.argv = ["imunoise", *sys.argv[3:]]
code = imunoise.cli.main()
report()
sys.exit(code)
"""


def _phases(nav_args: list[str], reps: int = 3) -> list[tuple[str, float]]:
    """Median CPU [s] per phase of ``reps`` fresh `nav` processes (:data:`PHASES`), with the interpreter start
    and imports before the command, the rest of the command, and the interpreter's exit (the process's CPU
    from wait4 minus its CPU when the command returned)."""
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        rec = Path(tmp) / "phases.json"
        for _ in range(reps):
            proc = subprocess.Popen([sys.executable, "-c", _PHASE_RUN, str(rec), json.dumps(PHASES), *nav_args],
                                    env=_env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            _, status, ru = os.wait4(proc.pid, 0)
            if os.waitstatus_to_exitcode(status) != 0:
                raise RuntimeError(f"imunoise {' '.join(nav_args)} failed under the phase timer")
            r = json.loads(rec.read_text())
            r["total"] = ru.ru_utime + ru.ru_stime
            runs.append(r)

    def med(f) -> float:
        return statistics.median(f(r) for r in runs)

    rows = [("interpreter start and imports of `imunoise.cli` and the timed modules (numpy, numba)",
             med(lambda r: r["start"]))]
    rows += [(label, med(lambda r, k=label: r.get(k, 0.0))) for label, _, _ in PHASES]
    rows.append(("rest of the command (parser, notice, checks, metrics.json, output staging)",
                 med(lambda r: r["end"] - r["start"] - sum(r.get(k, 0.0) for k, _, _ in PHASES))))
    rows.append(("interpreter exit", med(lambda r: r["total"] - r["end"])))
    rows.append(("whole process (wait4)", med(lambda r: r["total"])))
    rows.append((NUMBA_LABEL, med(lambda r: r.get("numba", 0.0))))
    return rows


def _wall_cpu_rss(args: list[str]) -> tuple[float, float, float]:
    """Wall, CPU (user + system) [s] and peak RSS [MiB] of one `python -m imunoise ARGS` process (its own
    VmHWM: see bench_first_run.HWM_WRAPPER)."""
    from bench_first_run import HWM_WRAPPER

    with tempfile.TemporaryDirectory() as tmp:
        hwm = Path(tmp) / "hwm"
        t0 = time.perf_counter()
        proc = subprocess.Popen([sys.executable, "-c", HWM_WRAPPER, *args], env=dict(_env(), IMUNOISE_HWM=str(hwm)),
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        _, status, ru = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        if os.waitstatus_to_exitcode(status) != 0:
            raise RuntimeError(f"imunoise {' '.join(args)} failed")
        return wall, ru.ru_utime + ru.ru_stime, int(hwm.read_text()) / 1024


def _kfgins_binary() -> Path | None:
    """The KF-GINS executable named by $IMUNOISE_KFGINS, or None when the variable is unset."""
    name = os.environ.get(KFGINS_ENV, "").strip()
    if not name:
        return None
    path = Path(name).expanduser()
    if not (path.is_file() and os.access(path, os.X_OK)):
        raise RuntimeError(f"{KFGINS_ENV}={name} is not an executable file; build KF-GINS from its own "
                           "repository (i2Nav-WHU/KF-GINS) and point the variable at bin/KF-GINS, or unset it")
    return path


def _kfgins_setup(tmp: Path) -> dict:
    """KF-GINS configurations for the drive with the initial state of `imunoise nav` (the same parser, the same
    functions and options as its handler), in ``tmp``: ``timed`` (the manifest's outage windows removed from
    the fixes, as `nav` does) and ``full`` (every fix, for the accuracy check); ``init`` and the inputs."""
    import gzip
    import logging
    import shutil

    from imunoise.cli import build_parser
    from imunoise.cli.navrun import nav_start, read_nav_inputs
    from imunoise.io.kfgins_config import kfgins_config, write_kfgins_config
    from imunoise.nav.align import coarse_align
    from imunoise.nav.defaults import EkfConfig

    args = build_parser().parse_args(["nav", "--data", str(DRIVE), "--out", str(tmp / "unused"), "--no-plots"])
    inp = read_nav_inputs(args, logging.getLogger("bench_cli"))
    t0, _ = nav_start(args, inp)
    init = coarse_align(inp.imu, inp.gnss, t0, static_duration=args.static_duration, yaw=None,
                        lever_arm=inp.lever, check_still=True)
    imu_txt = tmp / "imu.txt"  # KF-GINS reads plain text only
    with gzip.open(inp.imu_path, "rb") as src, open(imu_txt, "wb") as dst:
        shutil.copyfileobj(src, dst)
    lines = Path(inp.gnss_path).read_text().splitlines(keepends=True)

    def inside(line: str) -> bool:
        t = float(line.split()[0])
        return any(s <= t < s + d for s, d in inp.windows)  # GnssData.without's rule

    gnss_timed = tmp / "gnss_timed.txt"
    gnss_timed.write_text("".join(x for x in lines if not x.strip() or x.lstrip().startswith("#") or not inside(x)))
    ekf = EkfConfig(lever_arm=tuple(inp.lever))
    out = {"init": init, "inputs": inp, "ekf": ekf}
    for name, gnss in (("timed", gnss_timed), ("full", Path(inp.gnss_path))):
        (tmp / f"kf_{name}").mkdir()
        cfg = kfgins_config(
            imu_path=imu_txt, gnss_path=gnss, output_dir=tmp / f"kf_{name}", start_s=init.t,
            imu_rate_hz=inp.imu.rate_hz, llh=init.llh, vel_ned=init.vel_ned, euler=init.euler, lever_arm=inp.lever,
            gyro_bias=init.gyro_bias, accel_bias=init.accel_bias, sigma_pos0=ekf.sigma_pos0,
            sigma_vel0=ekf.sigma_vel0, sigma_att0=ekf.sigma_att0,
        )  # fmt: skip
        out[name] = write_kfgins_config(tmp / f"kf_{name}.yaml", cfg)
    return out


def _kfgins_run(binary: Path, config: Path) -> tuple[float, float, float]:
    """Wall, CPU (user + system of the child, wait4) [s] and peak RSS [MiB] of one KF-GINS process; the RSS is
    /usr/bin/time's %M of its own child (a wait4 here would carry this Python process's peak over the fork)."""
    timer = Path("/usr/bin/time")
    argv = [str(timer), "-f", "%M", str(binary), str(config)] if timer.exists() else [str(binary), str(config)]
    with tempfile.TemporaryFile() as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=err)
        _, status, ru = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        err.seek(0)
        text = err.read().decode(errors="replace").strip()
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(f"KF-GINS {config} failed: {text[-300:]}")
    last = text.splitlines()[-1] if text else ""
    rss = int(last) / 1024 if timer.exists() and last.isdigit() else float("nan")
    return wall, ru.ru_utime + ru.ru_stime, rss


def _kfgins_accuracy(kf: dict, full_dir: Path) -> tuple[dict, dict]:
    """H RMS / p95 / max [m] of the GNSS antenna against the reference with every fix: KF-GINS' run, and
    imunoise's filter (run_ekf, what `nav` runs) from the same initial state."""
    from imunoise.io.kfgins import read_reference
    from imunoise.nav.ekf import run_ekf
    from imunoise.nav.metrics import nav_errors, summarize
    from imunoise.nav.solution import antenna_llh

    inp = kf["inputs"]
    r = read_reference(full_dir / "KF_GINS_Navresult.nav")
    m_kf = summarize(nav_errors(r.t, antenna_llh(r.llh, r.euler, inp.lever), r.vel_ned, r.euler, inp.ref))
    res = run_ekf(inp.imu, inp.gnss, kf["init"], kf["ekf"], None)
    m_im = summarize(nav_errors(res.t, res.antenna_llh(inp.lever), res.vel_ned, res.euler, inp.ref))
    return m_kf, m_im


def _nav() -> list[str]:
    lines = ["### `imunoise nav` on the drive: whole process vs filter, and the C++ reference", ""]
    if not (DRIVE / "dataset.json").exists():
        return lines + [f"({DRIVE} not found: skipped)"]
    binary = _kfgins_binary()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "nav"
        args = ["nav", "--data", str(DRIVE), "--out", str(out)]
        nav = [sys.executable, "-m", "imunoise", *args]
        _wall(nav)  # first run: numba may compile and cache its kernels
        cases: list[tuple[str, object]] = [("with figures (default)", []), ("`--no-plots`", ["--no-plots"])]
        kf = None
        if binary is not None:
            kf = _kfgins_setup(Path(tmp))
            _kfgins_run(binary, kf["full"])  # the accuracy run, also the file cache's warm-up
            cases.append(("KF-GINS (C++), measured in this run", kf["timed"]))
        samples: dict[str, list[tuple[float, float, float, float]]] = {label: [] for label, _ in cases}
        for _ in range(NAV_REPS):  # interleaved rounds: a burst of load on this shared machine hits every case
            for label, extra in cases:
                if isinstance(extra, Path):
                    wall, cpu, mib = _kfgins_run(binary, extra)  # type: ignore[arg-type]
                    samples[label].append((wall, cpu, mib, float("nan")))
                else:
                    wall, cpu, mib = _wall_cpu_rss([*args, *extra])  # type: ignore[list-item]
                    samples[label].append((wall, cpu, mib, json.loads((out / "metrics.json").read_text())["elapsed_s"]))
        rows = [(label, *(statistics.median(s[i] for s in samples[label]) for i in range(4))) for label, _ in cases]
        acc = _kfgins_accuracy(kf, Path(tmp) / "kf_full") if kf is not None else None
        imp_s, by_pkg = _import_s(["-m", "imunoise", *args, "--no-plots"])
        phases = _phases([*args, "--no-plots"])
    cpu_np = rows[1][2]
    lines += [
        f"548 s drive, default model; median of {NAV_REPS} fresh processes per row, the rows interleaved round by "
        "round, after one warm-up run (numba cache filled; Python's bytecode cached as in an installed package: "
        "`bench_cli._env`). CPU = user + system time of the process (and its children); filter = the run's own "
        "`elapsed_s` (metrics.json, wall): the numba kernel over all samples, after loading.",
        "",
        "| run | whole process CPU [s] | whole process wall [s] | peak RSS [MiB] | filter wall [s] |",
        "|---|---:|---:|---:|---:|",
    ]
    for label, wall, cpu, mib, f in rows:
        filt = "–" if math.isnan(f) else f"{f:.3f}"
        rss = "–" if math.isnan(mib) else (f"{mib:.1f}" if mib < 20 else f"{mib:.0f}")
        lines.append(f"| {label} | {cpu:.2f} | {wall:.2f} | {rss} | {filt} |")
    if kf is None:
        lines.append(
            f"| KF-GINS (C++), historical: not run here (issue \"Performance where users wait\": same drive, same "
            f"initial state, same machine kind) | {KFGINS_HISTORICAL['cpu_s']:.2f} | – | "
            f"{KFGINS_HISTORICAL['rss_mib']:.1f} | – |"
        )
        lines += [
            "",
            "`nav --no-plots` whole-process CPU ÷ the historical KF-GINS figure: "
            f"**{cpu_np / KFGINS_HISTORICAL['cpu_s']:.2f}×** "
            "(target ≤ 1.0×; the ratio mixes this run with a figure from another run). To measure KF-GINS in the "
            f"same run, build it from its own repository (i2Nav-WHU/KF-GINS, CMake Release) and set {KFGINS_ENV} "
            "to its `bin/KF-GINS` (docs/guide/benchmarks.rst).",
        ]
    else:
        cpu_kf, rss_kf = rows[2][2], rows[2][3]
        (m_kf, m_im) = acc  # type: ignore[misc]

        def hm(m: dict) -> str:
            return f"{m['horizontal_rms_m']:.4f} / {m['horizontal_p95_m']:.4f} / {m['horizontal_max_m']:.3f}"

        lines += [
            "",
            f"`nav --no-plots` whole-process CPU ÷ KF-GINS' whole-process CPU, both measured in this run: "
            f"**{cpu_np / cpu_kf:.2f}×** (target ≤ 1.0×); peak RSS {rows[1][3] / rss_kf:.0f}× KF-GINS'. "
            f"KF-GINS: `{KFGINS_ENV}` = `{binary.name}`, reading the plain-text IMU file (decompressed once before "
            "the rounds; `nav` reads the .gz), writing its three result files every IMU sample.",
            "",
            f"Accuracy with every fix, same initial state (GNSS antenna vs the RTK reference, H RMS / p95 / max "
            f"[m]): KF-GINS {hm(m_kf)}, imunoise `run_ekf` {hm(m_im)}. The KF-GINS build is right if its figures "
            "match the historical 0.0253 / 0.0487 / 0.114 m of the same set-up.",
        ]
    lines += [
        "",
        f"Imports of a `--no-plots` run (`python -X importtime`, each module's own time, wall): {imp_s:.2f} s "
        "in all; " + ", ".join(f"{n} {by_pkg.get(n, 0.0):.2f} s" for n in IMPORT_GROUPS)
        + f", everything else {imp_s - sum(by_pkg.get(n, 0.0) for n in IMPORT_GROUPS):.2f} s. scipy is "
        "its top-level package (numba imports it) and the `scipy.linalg.cython_blas` extension numba's CPU target "
        "loads for its BLAS bindings; the rest of scipy.linalg is deferred until something uses it "
        "(imunoise.cli.scipy_defer; tests/cli/test_scipy_defer.py); matplotlib is not imported "
        "(tests/cli/test_cli_startup.py).",
        "",
        "CPU of the phases of a `--no-plots` run (median of 3 fresh processes run as from the command line; each "
        "function's `time.process_time` over its calls, no profiler; the numba row overlaps the rows above it: "
        "numba's CPU target starts at the first kernel call and each kernel's machine code is loaded from the "
        "cache at its first call):",
        "",
        "| phase | CPU [s] |",
        "|---|---:|",
    ]
    lines += [f"| {label} | {t:.3f} |" for label, t in phases]
    return lines


def main() -> str:
    out = ["## CLI start-up and whole-process time", ""]
    out += _startup()
    out.append("")
    out += _nav()
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    print(main())
