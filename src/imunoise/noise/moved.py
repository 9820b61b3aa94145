"""The old import paths of the modelling core (``imunoise.model``, ``imunoise.fitting.result``, ...) and the old
names of renamed module attributes (:func:`renamed`), for one release.

The modules moved into :mod:`imunoise.noise`; code that still imports them by the old name gets the very same
module object (so ``isinstance`` checks and module state are shared, not duplicated) and one
``DeprecationWarning`` naming the new path. :func:`install` puts the finder on ``sys.meta_path``; the package
``__init__`` calls it, so the old names work from any import.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import warnings
from collections.abc import Callable, Mapping
from types import ModuleType
from typing import Any

MOVED = frozenset({
    "processes", "process_base", "process_white", "process_bias", "process_ar1", "process_ma1", "ar1_math", "model",
    "state_space", "estimator", "selection", "em", "em_kalman", "wv_stream", "wv_log", "imu_model",
    "equivalent_noise", "plots", "fitting", "allan", "wv",
})


def new_name(fullname: str) -> str | None:
    """``imunoise.noise.X...`` for an old ``imunoise.X...`` of a moved module, else None."""
    parts = fullname.split(".")
    if len(parts) >= 2 and parts[0] == "imunoise" and parts[1] in MOVED:
        return ".".join(["imunoise", "noise", *parts[1:]])
    return None


class MovedFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Resolves an old module path to the module at its new path (the same object)."""

    def find_spec(self, fullname, path=None, target=None):
        new = new_name(fullname)
        if new is None:
            return None
        return importlib.machinery.ModuleSpec(fullname, self, is_package=False)

    def create_module(self, spec) -> ModuleType:
        new = new_name(spec.name)
        warnings.warn(f"{spec.name} moved to {new}; import it from there (the old path goes in the next release)",
                      DeprecationWarning, stacklevel=3)
        return importlib.import_module(new)

    def exec_module(self, module: ModuleType) -> None:
        """Nothing to run: the module was executed once, under its new name."""


def install() -> None:
    """Put the finder on ``sys.meta_path`` once."""
    if not any(isinstance(f, MovedFinder) for f in sys.meta_path):
        sys.meta_path.insert(0, MovedFinder())  # before the path finder, which would load a second copy


def renamed(module: str, old: Mapping[str, tuple[Callable[[], Any], str]]) -> Callable[[str], Any]:
    """A module ``__getattr__`` that answers each renamed attribute of ``module`` (``old``: old name → (getter of the
    object under its new name, the warning's text)) with one ``DeprecationWarning`` and the object itself."""

    def __getattr__(name: str) -> Any:
        if name in old:
            get, message = old[name]
            warnings.warn(message, DeprecationWarning, stacklevel=2)
            return get()
        raise AttributeError(f"module {module!r} has no attribute {name!r}")

    return __getattr__
