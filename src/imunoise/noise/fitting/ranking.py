"""The result of a model selection: :class:`ModelRanking`, every candidate fit best first
(docs/guide/theory.rst, 'Model selection')."""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from typing import Any

from imunoise.errors import ModelError
from imunoise.noise.fitting.problem import GMWMProblem
from imunoise.noise.fitting.result import GMWMFit
from imunoise.noise.model import Model

__all__ = ["ModelRanking"]


@dataclass
class ModelRanking:
    """All candidate fits of :func:`select_model`, sorted best first by ``criterion``."""

    fits: list[GMWMFit]
    criterion: str
    skipped: list[tuple[str, str]] = field(default_factory=list)  # (structure, reason)
    top: int = 3
    elapsed_s: float = 0.0
    problem: GMWMProblem | None = None

    @property
    def best(self) -> GMWMFit:
        return self.fits[0]

    @property
    def top_fits(self) -> list[GMWMFit]:
        return self.fits[: self.top]

    def __len__(self) -> int:
        return len(self.fits)

    def by_structure(self, structure: str | Model) -> GMWMFit:
        """The fit of one structure, e.g. ``ranking.by_structure("2*AR1+WN+RW")``.

        Parameters
        ----------
        structure
            A model string or Model (parameters ignored).

        Returns
        -------
        GMWMFit
            Its fit (``ModelError`` if it was not fitted).
        """
        target = (Model.parse(structure) if isinstance(structure, str) else structure).unknown()
        for fit in self.fits:
            if fit.model.unknown() == target:
                return fit
        raise ModelError(f"{target} is not among the fitted candidates of this ranking")

    def rows(self) -> list[dict[str, Any]]:
        rows = []
        for rank, fit in enumerate(self.fits, start=1):
            rows.append(
                {
                    "rank": rank,
                    "model": str(fit.model),
                    "n_params": fit.n_params,
                    "gof": fit.objective,
                    "wvic": fit.extra["wvic"],
                    "penalty": fit.extra["wvic_penalty"],
                    "time_ms": 1e3 * fit.elapsed_s,
                    "skipped": "",
                }
            )
        for structure, reason in self.skipped:
            rows.append(
                {
                    "rank": "",
                    "model": structure,
                    "n_params": Model.parse(structure).n_params,
                    "gof": math.nan,
                    "wvic": math.nan,
                    "penalty": math.nan,
                    "time_ms": math.nan,
                    "skipped": reason,
                }
            )
        return rows

    def table(self, limit: int | None = None) -> str:
        """Plain-text ranking: model, #params, GOF (Eq. 8), WVIC, fit time; skipped candidates last.

        Parameters
        ----------
        limit
            Show only the best ``limit`` fits (None: all).

        Returns
        -------
        str
        """
        if limit is not None and (isinstance(limit, bool) or not isinstance(limit, int) or limit < 0):
            raise ModelError(f"limit must be a whole number ≥ 0 (0 = none, None = all), got {limit!r}")
        shown = self.fits if limit is None else self.fits[:limit]
        w = max([len(str(f.model)) for f in shown] + [len(s) for s, _ in self.skipped] + [5])
        head = f"{'rank':>4}  {'model':<{w}}  {'#par':>4}  {'GOF (Eq. 8)':>12}  {'WVIC':>12}  {'time ms':>8}"
        lines = [
            f"{len(self.fits)} candidates ranked by {self.criterion.upper()} "
            f"(all on one WV and Ω; total {1e3 * self.elapsed_s:.0f} ms)",
            head,
            "-" * len(head),
        ]
        for rank, fit in enumerate(shown, start=1):
            lines.append(
                f"{rank:>4}  {str(fit.model):<{w}}  {fit.n_params:>4}  {fit.objective:>12.6g}  "
                f"{fit.extra['wvic']:>12.6g}  {1e3 * fit.elapsed_s:>8.2f}"
            )
        if limit is not None and len(self.fits) > limit:
            lines.append(f"  ... {len(self.fits) - limit} more (ranking.table() shows all)")
        for structure, reason in self.skipped:
            lines.append(f"   -  {structure:<{w}}  skipped: {reason}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.table(limit=10)

    def to_csv(self, path: str) -> None:
        """One row per candidate (skipped ones with their reason), GOF and WVIC both present.

        Parameters
        ----------
        path
            Output CSV file.
        """
        rows = self.rows()
        with open(path, "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=list(rows[0]) if rows else ["model"])
            writer.writeheader()
            for row in rows:
                writer.writerow({k: (f"{v:.10g}" if isinstance(v, float) else v) for k, v in row.items()})
