"""numba's on-disk cache of the compiled kernels, seen from the command line: the one-line notice of a command
that finds the cache cold, and the per-kernel compile cost that `imunoise warm-up` reports.

Every kernel is ``@njit(cache=True)``: numba compiles it on its first call for a new type signature and writes
the machine code into its cache (``__pycache__/*.nbi``/``*.nbc`` beside the installed module, or under
``NUMBA_CACHE_DIR`` when that is set); a later process loads it from there in milliseconds. A command that
finds the cache cold therefore waits for the compiler once.

Detection: numba fires its ``numba:compile`` event only when a signature is neither in memory nor in the
cache (a cache hit returns before the event), so a listener on that event is exact and free when the cache
is warm: nothing is checked up front, and the notice comes right before the first wait. Not a command (no
``register``); light at import (numba is imported only by :func:`announce_cold_cache` for the commands
that run kernels).
"""

from __future__ import annotations

import os
import sys
import tempfile
import threading
import time
from typing import Any

__all__ = ["COMPILE_ESTIMATE_S", "announce_cold_cache", "silence", "CompileRecorder", "NOTICE", "cache_dir_problem",
           "no_cache_message"]

# CPU seconds a command spends compiling with an empty cache, rounded up from `imunoise warm-up --timings`
# (compile CPU per kernel) and benchmarks/bench_first_run.py (`nav` with an empty cache) on a 2-core machine
COMPILE_ESTIMATE_S = {
    "nav": 20,
    "online": 30,
    "fit": 15,
    "select": 15,
    "calibrate": 20,
    "experiment": 40,
    "demo": 40,
    "em": 5,
    "allan": 5,
    "detect": 5,
    "simulate": 5,
    "batch": 15,
}
_INSTALLED = False  # one listener per process (the warm-up runs commands in-process)
_SILENT = False  # set by `imunoise warm-up`, which says what it compiles itself
NOTICE = "imunoise {command}: compiling kernels (one time, ~{seconds} s; `imunoise warm-up` does it ahead)"


def _is_ours(event: Any) -> bool:
    disp = event.data.get("dispatcher") if isinstance(event.data, dict) else None
    return str(getattr(disp, "__module__", "") or "").startswith("imunoise")


def announce_cold_cache(command: str, stream: Any = None) -> bool:
    """Print :data:`NOTICE` once on ``stream`` (stderr) when the command starts compiling an imunoise kernel.

    Installs a listener on numba's ``numba:compile`` event for the rest of the process; returns whether
    one was installed (False for the commands that run no kernel, which then do not import numba).
    """
    global _INSTALLED
    seconds = COMPILE_ESTIMATE_S.get(command)
    if seconds is None or _INSTALLED or _SILENT:
        return False
    from numba.core import event

    _INSTALLED = True

    lock = threading.Lock()
    said = []

    class _Notice(event.Listener):
        def on_start(self, ev: event.Event) -> None:
            if said or not _is_ours(ev):
                return
            with lock:
                if not said:
                    said.append(True)
                    print(NOTICE.format(command=command, seconds=seconds), file=stream or sys.stderr, flush=True)

        def on_end(self, ev: event.Event) -> None:
            pass

    event.register("numba:compile", _Notice())
    return True


def cache_dir_problem() -> str | None:
    """The one-line problem with ``NUMBA_CACHE_DIR`` when it is set but no cache can be written there, else None.

    numba tries the folder it is given and, when it cannot write there, silently falls back to the next place it
    knows (``__pycache__`` beside the installed modules, then the user's cache): a warm-up would report success
    and leave the folder the later runs read empty. The same test as numba's (create the folder, then a
    temporary file in it).
    """
    path = os.environ.get("NUMBA_CACHE_DIR")
    if not path:
        return None
    try:
        os.makedirs(path, exist_ok=True)
        tempfile.TemporaryFile(dir=path).close()
    except OSError as exc:
        return (f"NUMBA_CACHE_DIR={path}: cannot write the kernel cache there ({exc.strerror or exc}); numba would "
                "put it elsewhere: make the folder writable or point NUMBA_CACHE_DIR to a writable folder")
    return None


def no_cache_message(exc: BaseException) -> str | None:
    """One line for numba's "cannot cache function ...: no locator available" (no writable place for the kernel
    cache at all: a read-only install, no writable home), None for any other exception."""
    if isinstance(exc, RuntimeError) and "cannot cache function" in str(exc) and "no locator" in str(exc):
        where = os.environ.get("NUMBA_CACHE_DIR")
        now = f" (NUMBA_CACHE_DIR={where} is not writable either)" if where else ""
        return ("numba finds no writable place for its kernel cache (the installed package's __pycache__ and the "
                f"user's cache folder are read-only{now}); set NUMBA_CACHE_DIR to a writable folder")
    return None


def silence() -> None:
    """No notice for the rest of the process (`imunoise warm-up` reports its compilations itself)."""
    global _SILENT
    _SILENT = True


class CompileRecorder:
    """CPU time of every kernel compilation while installed (a context manager).

    Nested compilations (a kernel's callees, compiled while the caller is typed) are charged to themselves:
    ``self_s`` of a kernel is its own compile time without its callees'. numba's own helpers (array and
    linear-algebra implementations, string formatting of error messages) compiled for a kernel are charged
    to the nearest imunoise kernel above them (``charged_to``). Rows: ``(module, function, signature, self_s,
    total_s, charged_to)``.
    """

    def __init__(self) -> None:
        self.rows: list[tuple[str, str, str, float, float, str]] = []
        self._stack: list[list[Any]] = []  # [start CPU, callees' CPU, qualified name]
        self._listener: Any = None

    def __enter__(self) -> CompileRecorder:
        from numba.core import event

        rec = self

        class _Timer(event.Listener):
            def on_start(self, ev: event.Event) -> None:
                disp = ev.data["dispatcher"]
                rec._stack.append([time.process_time(), 0.0, f"{disp.__module__}.{disp.__name__}"])

            def on_end(self, ev: event.Event) -> None:
                t0, inner, _name = rec._stack.pop()
                total = time.process_time() - t0
                if rec._stack:
                    rec._stack[-1][1] += total
                disp = ev.data["dispatcher"]
                owner = next((f[2] for f in reversed(rec._stack) if f[2].startswith("imunoise")), "")
                sig = ", ".join(str(a) for a in ev.data["args"])
                rec.rows.append((disp.__module__, disp.__name__, sig, total - inner, total, owner))

        self._listener = _Timer()
        event.register("numba:compile", self._listener)
        return self

    def __exit__(self, *exc: object) -> None:
        from numba.core import event

        event.unregister("numba:compile", self._listener)

    def by_kernel(self) -> list[tuple[str, str, int, float, float]]:
        """``(module, function, signatures, own CPU s, helpers' CPU s)`` per imunoise kernel, costliest first;
        helpers = numba's implementations compiled for it. numba helpers compiled outside any imunoise
        kernel (none expected) are one row of their own."""
        acc: dict[tuple[str, str], list[float]] = {}
        for mod, fn, _sig, own, _tot, owner in self.rows:
            if mod.startswith("imunoise"):
                acc.setdefault((mod, fn), [0, 0.0, 0.0])
                acc[(mod, fn)][0] += 1
                acc[(mod, fn)][1] += own
            else:
                key = tuple(owner.rsplit(".", 1)) if owner else ("numba", "(helpers outside a kernel)")
                acc.setdefault(key, [0, 0.0, 0.0])[2] += own
        rows = [(m, f, int(n), own, helpers) for (m, f), (n, own, helpers) in acc.items()]
        return sorted(rows, key=lambda r: -(r[3] + r[4]))
