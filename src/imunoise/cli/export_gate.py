"""The fit-quality gate of ``--export`` (``calibrate``, ``fit``): a fit that leaves its WV band over a range of
scales (:class:`imunoise.noise.fitting.quality.BandCheck`) is not exported, unless ``--force``, and then with the
warning written into the file (comment lines at the top of the YAML formats, a ``warnings`` key in JSON).

Built around :func:`imunoise.export.export_text`: the text is formed, the warnings put in, and the file
written atomically (:func:`imunoise.io.atomic.atomic_write_text`).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from imunoise.errors import FitError

__all__ = ["add_force", "add_update_interval", "band_checks", "band_diagnostics", "data_lines", "force_readings",
           "pair_gates", "refusal", "with_warnings", "write_exports"]


def add_force(p: argparse.ArgumentParser) -> None:
    """``--force``: export past the pair gate (the data's own Allan reading is written), the warning in the file."""
    p.add_argument("--force", action="store_true",
                   help="--export even where the exported (N, K) pair misses the data's Allan variance by more than "
                   "2x outside its band: the data's own Allan reading is written instead, with the warning in the file")


def add_update_interval(p: argparse.ArgumentParser) -> None:
    """``--update-interval``: the consumer's filter interval, the shortest averaging time the gate checks."""
    p.add_argument("--update-interval", type=float, metavar="S",
                   help="--export: the consumer's update interval [s], the shortest averaging time the exported pair "
                   "is checked on against the data (default 4 IMU periods)")


def pair_gates(fits: Mapping[str, Any], *, horizon_s: float | None = None,
               update_interval_s: float | None = None) -> dict[str, Any]:
    """Per axis (model text, :class:`imunoise.export.gate.PairGate`) of the pair :func:`imunoise.export.axis_noise`
    exports against the fit's data WV; the gate goes into ``fit.extra["export_gate"]`` (the model file and the
    export notes). Lines found but kept in the data name the cause of a refusal."""
    from imunoise.errors import ModelError
    from imunoise.export import axis_noise
    from imunoise.export.gate import pair_gate

    if update_interval_s is not None and not update_interval_s > 0:
        raise ModelError(f"--update-interval must be a positive time in seconds, got {update_interval_s}")
    out = {}
    for axis, fit in fits.items():
        a = axis_noise(fit, axis, horizon_s=horizon_s)
        rec = fit.extra.get("lines") or {}
        kept = [] if rec.get("removed", True) else list(rec.get("found", ()))
        g = pair_gate(fit.wv, a.N, a.K, horizon_s=horizon_s or (a.tau_range_s or (None, None))[1],
                      update_interval_s=update_interval_s, lines=kept)
        fit.extra["export_gate"] = g.to_dict()
        out[axis] = (str(fit.model), g)
    return out


def force_readings(fits: Mapping[str, Any], gates: Mapping[str, Any]) -> None:
    """``--force`` past a refusal: each refused axis exports the data's Allan reading (``extra["forced_pair"]``)."""
    for axis, (_, g) in gates.items():
        if g.refused:
            fits[axis].extra["forced_pair"] = {"N": g.reading[0], "K": g.reading[1]}


def band_checks(fits: Mapping[str, Any]) -> dict[str, Any]:
    """Per axis the :class:`~imunoise.noise.fitting.quality.BandCheck` of a fit (a GMWMFit or its dict)."""
    from imunoise.noise.fitting.quality import band_check
    from imunoise.noise.fitting.result import GMWMFit

    out = {}
    for axis, fit in fits.items():
        f = fit if isinstance(fit, GMWMFit) else GMWMFit.from_dict(dict(fit))
        out[axis] = (str(f.model), band_check(f.wv, f.theoretical_wv))
    return out


def refusal(checks: Mapping[str, Any], force: bool, *, where: str = "") -> list[str]:
    """The warning lines of the refused axes; raises :class:`FitError` (one line: the axes, the cause,
    ``--force``) when there are some and ``force`` is not set.

    Parameters
    ----------
    checks : mapping
        Per axis (model text, check with ``refused`` and ``text()``): the pair gate of :func:`pair_gates`, or a
        BandCheck of :func:`band_checks`.
    force : bool
        ``--force`` given.
    where : str
        Where the user sees the fits (e.g. ``"out/report.html"``), for the message.

    Returns
    -------
    list of str
        One warning per refused axis (empty when every fit is inside its band).
    """
    bad = [(ax, m, b) for ax, (m, b) in checks.items() if b.refused]
    lines = [f"{ax}: the {m} fit: {b.text()}" for ax, m, b in bad]
    if bad and not force:
        what = "; ".join(f"{ax} ({m}) {b.text()}" for ax, m, b in bad)
        see = f" (see {where})" if where else ""
        raise FitError(f"export refused: {what}{see}; --force writes the export with this warning in the file")
    return lines


def band_diagnostics(checks: Mapping[str, Any]) -> list[str]:
    """The WV band check per axis as a diagnostic (the gate is on the pair, :func:`pair_gates`)."""
    return [f"{ax}: {m} fit {b.text()} (diagnostic)" for ax, (m, b) in checks.items() if b.refused]


def data_lines(fits: Mapping[str, Any], horizon_s: float | None = None) -> list[str]:
    """Per axis: the axis's exported (N, K) pair against the **data's** Allan variance and band
    (:func:`imunoise.noise.fitting.quality.pair_check`), beside the worst ratio against the fitted model that the
    export notes print (a file writes the largest pair of a sensor's axes)."""
    from imunoise.export import axis_noise
    from imunoise.noise.fitting.quality import pair_check
    from imunoise.noise.fitting.result import GMWMFit

    lines = []
    for axis, fit in fits.items():
        f = fit if isinstance(fit, GMWMFit) else GMWMFit.from_dict(dict(fit))
        a = axis_noise(f, axis, horizon_s=horizon_s)
        lines.append(f"{axis}: {pair_check(f.wv, a.N, a.K, a.tau_range_s).text()}; pair/model AV: worst "
                     f"{a.worst_ratio:.3g}×")
    return lines


def with_warnings(text: str, fmt: str, warnings: Sequence[str]) -> str:
    """The export text with the warnings put in: comment lines at the top of a YAML format (after a
    ``%YAML`` directive, which must stay first), a ``warnings`` key in JSON."""
    if not warnings:
        return text
    if fmt == "json":
        d = json.loads(text)
        kind = {"kind": d.pop("kind")} if "kind" in d else {}
        return json.dumps({**kind, "warnings": list(warnings), **d}, indent=1)
    lines = text.splitlines(keepends=True)
    head = 1 if lines and lines[0].startswith("%YAML") else 0
    block = [f"# WARNING (exported with --force): {w}\n" for w in warnings]
    return "".join(lines[:head] + block + lines[head:])


def write_exports(model: Any, fmts: Sequence[str], out: Path, warnings: Sequence[str], *,
                  fits: Mapping[str, Any] | None = None, **kwargs: Any) -> list[Path]:
    """Each format's file in ``out`` (:data:`imunoise.export.DEFAULT_FILENAMES`), with the warnings in it,
    written atomically; the warnings also go to stderr.

    Parameters
    ----------
    model : ImuModel or GMWMFit
        What is exported.
    fmts : sequence of str
        Formats (``--export``).
    out : Path
        Output folder.
    warnings : sequence of str
        From :func:`refusal` (empty: the files as :func:`imunoise.export.export_text` writes them).
    fits : mapping, optional
        Per axis the fit: its pair against the data is printed (:func:`data_lines`).
    **kwargs
        Passed to :func:`imunoise.export.export_text` (``sensor``, ``source``, ``horizon_s``, ``topic``).

    Returns
    -------
    list of Path
        The files written.
    """
    from imunoise.export import DEFAULT_FILENAMES, export_text
    from imunoise.io.atomic import atomic_write_text

    if fits:
        for line in data_lines(fits, kwargs.get("horizon_s")):
            print(f"data check: {line}", file=sys.stderr)
    for w in warnings:
        print(f"warning: exported with --force: {w}", file=sys.stderr)
    written = []
    for fmt in fmts:
        path = Path(out) / DEFAULT_FILENAMES[fmt]
        written.append(atomic_write_text(path, with_warnings(export_text(model, fmt, **kwargs), fmt, warnings)))
    return written
