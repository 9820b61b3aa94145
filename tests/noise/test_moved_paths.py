"""The modelling core moved into imunoise.noise; its old import paths still give the same module objects, with a
DeprecationWarning naming the new path, for one release."""

from __future__ import annotations

import importlib
import sys
import warnings

import pytest

from imunoise.noise.moved import MOVED, new_name


@pytest.mark.parametrize("name", sorted(MOVED))
def test_old_path_is_the_new_module_with_a_warning(name):
    sys.modules.pop(f"imunoise.{name}", None)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        old = importlib.import_module(f"imunoise.{name}")
    assert old is importlib.import_module(f"imunoise.noise.{name}")
    assert any(issubclass(w.category, DeprecationWarning) and f"imunoise.noise.{name}" in str(w.message)
               for w in caught)


def test_a_submodule_by_its_old_path_is_not_loaded_twice():
    from imunoise.noise.fitting.result import GMWMFit

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        from imunoise.fitting.result import GMWMFit as old  # noqa: PLC0415 - the old path on purpose

    assert old is GMWMFit and old.__module__ == "imunoise.noise.fitting.result"


def test_names_outside_the_core_are_left_alone():
    assert new_name("imunoise.nav.ekf") is None and new_name("imunoise.io") is None
    assert new_name("imunoise.wv.kernels") == "imunoise.noise.wv.kernels"
