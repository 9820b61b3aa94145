"""Fleets of static logs on Dask (docs/guide/theory.rst, 'Interfaces'): one model per file and axis, one table, one
model JSON per file.

Each file is one task (read -> fit every axis -> write ``<name>.model.json``); tasks run on a
``dask.distributed`` cluster — a :class:`~dask.distributed.LocalCluster` of worker *processes* by default
(the fits are numba/NumPy code that holds the GIL between kernels), or any scheduler address. A file
that fails becomes a row with ``status = "error"`` and the one-line reason; the others go on.

The table has one row per file and axis: the model, the continuous-time white-noise density N
(``noise_density``) and bias random walk K (``random_walk_eq``) exactly as :mod:`imunoise.export` writes
them (the one model → (N, K) mapping of :mod:`imunoise.noise.equivalent_noise`, docs/guide/theory.rst, 'Interfaces'),
the fitted RW term
alone (``random_walk``), their units, the longest averaging time matched on and the worst AV ratio of the
pair against the model there, the GOF, the fit time and the handled data problems and export notes
(``notes``: sorted or duplicated stamps, gaps, unidentified white noise). With a remote
scheduler the workers must see the input files and the output folder at the same paths. The table is
written as CSV, and also as Parquet when ``pyarrow`` is installed (optional).

The outputs of a run appear in the output folder together when it completes (:func:`imunoise.io.atomic.staged_run`):
the workers write into a hidden staging folder inside it, so an interrupted or failed run (Ctrl-C reaching the
workers too) leaves the folder as it was, and the tables and models an earlier batch left there are replaced.
"""

from __future__ import annotations

import csv
import glob
import hashlib
import time
import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from imunoise.errors import DataError, ModelError

__all__ = ["BatchResult", "BATCH_OUTPUTS", "TABLE_FIELDS",
           "expand_paths", "process_file", "run_batch", "run_sequential", "write_table"]

TABLE_FIELDS = [
    "file",
    "axis",
    "status",
    "error",
    "model",
    "n_samples",
    "freq_hz",
    "unit",
    "noise_density",
    "noise_density_unit",
    "random_walk_eq",
    "random_walk",
    "random_walk_unit",
    "match_tau_max_s",
    "worst_av_ratio",
    "objective",
    "converged",
    "fit_s",
    "notes",
    "model_json",
]


BATCH_OUTPUTS = ("batch.csv", "batch.parquet", "*.model.json")
"""Every file a batch run writes into its output folder (a rerun removes the ones it did not write again)."""


@dataclass
class BatchResult:
    """Rows of the table (dicts with :data:`TABLE_FIELDS`), files written, wall time [s]."""

    rows: list[dict[str, Any]]
    wall_s: float
    tables: list[Path] = field(default_factory=list)
    scheduler: str = "sequential"

    @property
    def failed(self) -> list[str]:
        return sorted({r["file"] for r in self.rows if r["status"] != "ok"})

    @property
    def n_files(self) -> int:
        return len({r["file"] for r in self.rows})


def expand_paths(patterns: str | Sequence[str]) -> list[str]:
    """Files matching the glob pattern(s) (``**`` recursive), sorted, without duplicates."""
    pats = [patterns] if isinstance(patterns, str) else list(patterns)
    out: list[str] = []
    for p in pats:
        hits = sorted(glob.glob(p, recursive=True)) or ([p] if Path(p).exists() else [])
        out += [h for h in hits if h not in out]
    if not out:
        raise DataError(f"no files match {', '.join(pats)}")
    return out


def _names(paths: Sequence[str]) -> list[str]:
    """Output names: the file stem, with a short hash of the full path where stems collide."""
    stems = [Path(p).name.split(".")[0] for p in paths]
    out = []
    for p, s in zip(paths, stems):
        if stems.count(s) > 1:
            s = f"{s}_{hashlib.sha1(str(Path(p).resolve()).encode()).hexdigest()[:6]}"
        out.append(s)
    return out


def process_file(path: str, cfg: dict[str, Any], out_dir: str, name: str) -> list[dict[str, Any]]:
    """Fit every axis of one file; never raises — a failure becomes one ``status = "error"`` row.

    ``cfg`` keys: ``freq`` (Hz, or None to take it from the stamps), ``model`` or ``auto``, ``criterion``,
    ``columns``, ``units``, ``time_column``, ``time_unit``, ``topic``, ``weights``, ``robust``, ``seed``,
    ``decimate``.
    """
    from imunoise.export import axis_noise, density_units
    from imunoise.io.imu_input import read_imu_source, sensor_of
    from imunoise.io.imu_source import SOURCE_FIELDS, ImuSource
    from imunoise.noise.imu_model import ImuModel, fit_axis

    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            # the reader settings cfg gives (None or missing: the ImuSource default)
            source = ImuSource(path, **{k: cfg[k] for k in SOURCE_FIELDS if cfg.get(k) is not None})
            series = read_imu_source(source, decimate_by=int(cfg.get("decimate") or 1))
        notes = " | ".join(str(w.message) for w in caught)
        fits = {}
        rows = []
        for axis, values in series.data.items():
            t0 = time.perf_counter()
            fit, _ = fit_axis(
                values,
                freq=series.freq,
                model=cfg.get("model"),
                auto=bool(cfg.get("auto")),
                criterion=cfg.get("criterion", "wvic"),
                weights=cfg.get("weights", "efficient"),
                robust=bool(cfg.get("robust")),
                unit=series.unit[axis],
                seed=int(cfg.get("seed", 0)),
            )
            fit.extra.update({"source": path, "column": axis, "source_unit": series.source_unit[axis]})
            fits[axis] = fit
            try:
                an = axis_noise(fit, axis)
            except ModelError as exc:  # no exportable pair (e.g. no white-noise-like process): say why
                an = None
                why = str(exc)
            n_unit, k_unit = density_units(sensor_of(axis, fit.unit) or "gyro")
            if fit.unit not in ("rad/s", "m/s²"):
                n_unit, k_unit = f"{fit.unit}/sqrt(Hz)", f"{fit.unit}/s/sqrt(Hz)"
            rows.append(
                {
                    "file": path,
                    "axis": axis,
                    "status": "ok",
                    "error": "",
                    "model": str(fit.model),
                    "n_samples": int(values.size),
                    "freq_hz": series.freq,
                    "unit": fit.unit,
                    "noise_density": an.N if an else "",
                    "noise_density_unit": n_unit,
                    "random_walk_eq": an.K if an else "",
                    "random_walk": an.K_rw if an else "",
                    "random_walk_unit": k_unit,
                    "match_tau_max_s": an.tau_range_s[1] if an and an.tau_range_s else "",
                    "worst_av_ratio": an.worst_ratio if an else "",
                    "objective": fit.objective,
                    "converged": bool(fit.converged),
                    "fit_s": time.perf_counter() - t0,
                    "notes": " | ".join(x for x in (notes, *(an.notes if an else (why,))) if x),
                }
            )
        source = {"file": path, **{k: v for k, v in series.meta.items() if isinstance(v, (str, int, float))}}
        out = Path(out_dir) / f"{name}.model.json"
        ImuModel.from_fits(fits, source=source).save(out)
        for r in rows:
            r["model_json"] = str(out)
        return rows
    except Exception as exc:  # noqa: BLE001 - a broken file must not stop the fleet
        reason = f"{type(exc).__name__}: {exc}".splitlines()[0]
        return [{**{k: "" for k in TABLE_FIELDS}, "file": path, "status": "error", "error": reason}]


def write_table(rows: Iterable[dict[str, Any]], out_dir: str | Path, stem: str = "batch") -> list[Path]:
    """``<stem>.csv`` always; ``<stem>.parquet`` too when pyarrow is importable."""
    rows = list(rows)
    out_dir = Path(out_dir)
    paths = [out_dir / f"{stem}.csv"]
    with open(paths[0], "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=TABLE_FIELDS)
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k, "") for k in TABLE_FIELDS})
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return paths
    cols = {k: [None if r.get(k, "") == "" else r.get(k) for r in rows] for k in TABLE_FIELDS}
    pq.write_table(pa.table(cols), out_dir / f"{stem}.parquet")
    paths.append(out_dir / f"{stem}.parquet")
    return paths


def _sort_rows(rows: list[dict[str, Any]], paths: Sequence[str]) -> list[dict[str, Any]]:
    order = {p: i for i, p in enumerate(paths)}
    return sorted(rows, key=lambda r: order.get(r["file"], len(order)))


def run_sequential(
    paths: Sequence[str], cfg: dict[str, Any], out_dir: str | Path, *, progress: bool = False
) -> BatchResult:
    """The plain loop (the baseline of the benchmark), same outputs as :func:`run_batch`."""
    from tqdm import tqdm

    from imunoise.io.atomic import staged_run
    from imunoise.io.interrupt import interrupt_point

    out_dir = Path(out_dir)
    t0 = time.perf_counter()
    rows = []
    with staged_run(out_dir, BATCH_OUTPUTS) as stage:
        for p, n in tqdm(list(zip(paths, _names(paths))), desc="files", disable=not progress, unit="file"):
            rows += process_file(p, cfg, str(stage), n)
            interrupt_point("batch-progress")
        res = _finish(rows, paths, stage, out_dir, time.perf_counter() - t0, "sequential")
    return res


def _finish(rows: list[dict[str, Any]], paths: Sequence[str], stage: Path, out_dir: Path, wall: float,
            scheduler: str) -> BatchResult:
    """The rows in the order of ``paths``, naming the models where they will be once published, and the
    tables written into the staging folder (their published paths in the result)."""
    rows = _sort_rows(rows, paths)
    for r in rows:
        if r.get("model_json"):
            r["model_json"] = str(out_dir / Path(r["model_json"]).name)
    tables = [out_dir / p.name for p in write_table(rows, stage)]
    return BatchResult(rows, wall, tables, scheduler)


def run_batch(
    paths: Sequence[str],
    cfg: dict[str, Any],
    out_dir: str | Path,
    *,
    scheduler: str = "local",
    n_workers: int | None = None,
    progress: bool = True,
) -> BatchResult:
    """Run :func:`process_file` for every path on Dask and write the table.

    ``scheduler``: ``"local"`` (a LocalCluster of ``n_workers`` single-threaded processes, default one per
    core), ``"threads"`` (in-process, for debugging) or a ``dask.distributed`` scheduler address
    (``tcp://host:8786``). ``wall_s`` includes the cluster start-up.
    """
    from dask.distributed import as_completed
    from tqdm import tqdm

    from imunoise.io.atomic import staged_run
    from imunoise.io.dask_client import dask_client
    from imunoise.io.interrupt import interrupt_point

    out_dir = Path(out_dir)
    t0 = time.perf_counter()
    rows: list[dict[str, Any]] = []
    with staged_run(out_dir, BATCH_OUTPUTS) as stage:
        # the client and the cluster close before the staging folder is kept or removed (an interrupt included):
        # no worker writes into it afterwards
        with dask_client(scheduler, n_workers) as client:
            names = _names(paths)
            where = str(stage.resolve())  # remote workers see the folder at the same path
            futures = {client.submit(process_file, p, cfg, where, n, pure=False): p for p, n in zip(paths, names)}
            bar = tqdm(total=len(futures), desc="files", disable=not progress, unit="file")
            for fut in as_completed(list(futures)):
                try:
                    rows += fut.result()
                except Exception as exc:  # noqa: BLE001 - a worker crash on one file is reported, not fatal
                    blank = {k: "" for k in TABLE_FIELDS}
                    rows.append({**blank, "file": futures[fut], "status": "error", "error": f"worker: {exc}"})
                bar.update(1)
                interrupt_point("batch-progress")
            bar.close()
        res = _finish(rows, paths, stage, out_dir, time.perf_counter() - t0, scheduler)
    return res
