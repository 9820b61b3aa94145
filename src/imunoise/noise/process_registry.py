"""The registry of latent processes, the one kind vocabulary (:data:`PROCESS_TYPES`): canonical order (a model
lists its components in it) and, by position, the compiled kind codes (``cls.code``).

It sits below :mod:`imunoise.noise.model` (which needs the registry) and below :mod:`imunoise.noise.processes`
(the public face, which also loads the model so that ``WN() + RW()`` works from any import). A new process is one
class in its own module (all its math: WV in numpy and numba, parameter transforms and bounds, starting values,
simulation, filter states, EM form or refusal, export route), its entry here, and its branch in the kernels'
dispatch (:mod:`imunoise.noise.fitting.kernels`). It is a selection candidate only when a complete model names it.
"""

from __future__ import annotations

from imunoise.noise.process_ar1 import AR1
from imunoise.noise.process_base import Process
from imunoise.noise.process_bias import DR, RW
from imunoise.noise.process_ma1 import MA1
from imunoise.noise.process_sin import SIN
from imunoise.noise.process_white import QN, WN

__all__ = ["PROCESS_TYPES", "ORDER", "N_PARAMS"]

PROCESS_TYPES: dict[str, type[Process]] = {cls.kind: cls for cls in (AR1, WN, QN, RW, DR, MA1, SIN)}
"""Kind → class, in canonical order; a class' position is its compiled kind code."""
for _code, _cls in enumerate(PROCESS_TYPES.values()):
    _cls.code = _code
ORDER: tuple[str, ...] = tuple(PROCESS_TYPES)
N_PARAMS: tuple[int, ...] = tuple(len(c.param_names) for c in PROCESS_TYPES.values())
