"""The candidate models of the selection: every non-empty sub-model of the complete model
(docs/guide/theory.rst, 'Model selection').

A :class:`Candidate` is a structure only (how many AR1s, which of the other processes); its immediate
sub-models (:meth:`Candidate.parents`) are where :mod:`imunoise.noise.fitting.candidate_fit` starts it from.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

from imunoise.noise.model import Model, ModelLike, as_model, default_complete
from imunoise.noise.processes import AR1, PROCESS_TYPES

__all__ = ["Candidate", "candidates", "candidate_of", "SINGLE", "SINGLE_ORDER"]

# the processes a model holds at most once, in canonical order (the registry); AR1 is the repeated one
SINGLE = {k: cls for k, cls in PROCESS_TYPES.items() if cls.singleton}
SINGLE_ORDER = tuple(SINGLE)
_MODELS: dict = {}  # Candidate -> its structure (Model is immutable)


@dataclass(frozen=True)
class Candidate:
    """One sub-model of the complete model: number of AR1s and the set of other processes."""

    n_ar1: int
    others: tuple[str, ...]  # canonical order of the registry (WN, QN, RW, DR, ...)

    @property
    def model(self) -> Model:
        """The structure (parameters unknown); one shared, immutable Model per candidate."""
        model = _MODELS.get(self)
        if model is None:
            model = _MODELS[self] = Model([AR1() for _ in range(self.n_ar1)] + [SINGLE[k]() for k in self.others])
        return model

    @property
    def n_params(self) -> int:
        return len(AR1.param_names) * self.n_ar1 + sum(len(SINGLE[k].param_names) for k in self.others)

    @property
    def size(self) -> int:
        return self.n_ar1 + len(self.others)

    def parents(self) -> list[tuple[Candidate, str]]:
        """Immediate sub-models (one process removed) with the kind of the removed process."""
        out = []
        if self.n_ar1 >= 1 and self.size > 1:
            out.append((Candidate(self.n_ar1 - 1, self.others), "AR1"))
        if self.size > 1:
            for k in self.others:
                out.append((Candidate(self.n_ar1, tuple(o for o in self.others if o != k)), k))
        return out

    def __str__(self) -> str:
        return str(self.model)


def candidates(complete: ModelLike | None = None) -> list[Candidate]:
    """Every non-empty sub-model of ``complete`` (default 4*AR1+DR+WN+QN+RW: 5·16 − 1 = 79), small first.

    Parameters
    ----------
    complete
        A process, a Model or a model string; default :func:`imunoise.noise.model.default_complete`.

    Returns
    -------
    list of Candidate
        Ordered by size, then number of parameters (the order :func:`select_model` fits them in).
    """
    complete = default_complete() if complete is None else as_model(complete)
    counts = complete.counts
    n_ar_max = counts.get("AR1", 0)
    singles = [k for k in SINGLE_ORDER if counts.get(k, 0)]
    out = []
    for a in range(n_ar_max + 1):
        for r in range(len(singles) + 1):
            for subset in itertools.combinations(singles, r):
                if a + r > 0:
                    out.append(Candidate(a, tuple(subset)))
    out.sort(key=lambda c: (c.size, c.n_params, -c.n_ar1, [SINGLE_ORDER.index(k) for k in c.others]))
    return out



def candidate_of(model: Model) -> Candidate:
    """The candidate (structure) of a model.

    Parameters
    ----------
    model
        A model, parameters known or not.

    Returns
    -------
    Candidate
    """
    n_ar1 = 0
    kinds = set()
    for c in model.components:
        if c.kind == "AR1":
            n_ar1 += 1
        else:
            kinds.add(c.kind)
    return Candidate(n_ar1, tuple(k for k in SINGLE_ORDER if k in kinds))
