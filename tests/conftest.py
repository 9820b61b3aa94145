"""Shared fixtures: the path to ../shared/data (tests that need it skip with a clear reason)."""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path
from types import ModuleType

import matplotlib
import pytest

matplotlib.use("Agg")

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("IMUNOISE_SHARED_DATA", REPO.parent / "shared" / "data"))


def load_script(name: str) -> ModuleType:
    """The module of ``scripts/NAME.py`` (the scripts are not a package; their tests import them by path)."""
    spec = importlib.util.spec_from_file_location(name, REPO / "scripts" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def shared_path(*parts: str) -> Path:
    """Path inside ../shared/data, or skip the calling test with the reason it is missing."""
    path = SHARED_DATA.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"shared data not available: {path} (clone with ../shared beside the repo)")
    return path


@pytest.fixture
def shared_data():
    """Callable fixture: ``shared_data("simts_reference", "reference.json")`` -> Path or skip."""
    return shared_path


def one_line_error(code: int, err: str, *names: str) -> str:
    """Exit 2, exactly one 'error:' line naming every string in ``names``, no traceback (the bad-input batteries)."""
    assert code == 2, err
    assert "Traceback" not in err
    lines = [ln for ln in err.splitlines() if ": error: " in ln]
    assert len(lines) == 1, err
    for name in names:
        assert str(name) in lines[0], (name, lines[0])
    return lines[0]


def pytest_collection_modifyitems(config, items):
    """Files with the most tests marked slow first, each file's tests in their own order.

    ``make test`` hands whole files to two workers (``--dist loadfile --no-loadscope-reorder``) in collection
    order. xdist's own order (most tests first) left the long end-to-end files of one or two tests (the demo,
    the docs build) for last, with one worker busy and the other idle at the end; starting them first lets the
    many short files fill in behind them. Only the order of files changes, never which tests run.
    """
    slow: dict[str, int] = {}
    first: dict[str, int] = {}
    for i, item in enumerate(items):
        f = item.nodeid.split("::", 1)[0]
        first.setdefault(f, i)
        slow[f] = slow.get(f, 0) + (item.get_closest_marker("slow") is not None)
    items.sort(key=lambda it: (-slow[it.nodeid.split("::", 1)[0]], first[it.nodeid.split("::", 1)[0]]))


@pytest.fixture(autouse=True)
def _default_sigint_handling():
    """Every test starts with SIGINT handled as in a fresh process (Python's default handler) and gives back what
    it found. A test run earlier in the same worker may leave SIGINT ignored (a preload or a library that sets it
    and does not restore it), and the interrupt tests send a real SIGINT: they must not depend on the order of
    files (``make test`` gives each worker whole files in an order set by their slow tests)."""
    import signal

    before = signal.getsignal(signal.SIGINT)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)
