"""Ctrl-C that is never lost: a command-line run remembers every SIGINT it received, so that an interrupt
swallowed on its way up (a ``KeyboardInterrupt`` raised inside a C callback of llvmlite or in a finaliser is
printed as "Exception ignored" and dropped by Python) still stops the run before its outputs are published
(:func:`imunoise.io.atomic.staged_run` calls :func:`raise_if_interrupted`) and still ends it with exit code 130.

Worker processes forked by a run ignore SIGINT: a Ctrl-C in a terminal reaches the whole process group, and
the parent alone decides (its pool is terminated when the ``KeyboardInterrupt`` unwinds it); without this every
worker would print its own traceback. Dask's local worker processes are spawned, not forked: they load this
module as their preload (:func:`dask_setup`) and ignore SIGINT from then on, for the same reason.

:func:`interrupt_point` is where the tests interrupt a command at a known step, deterministically: with
``IMUNOISE_TEST_SIGINT=NAME`` in the environment the process sends itself a real SIGINT when it reaches the
point ``NAME`` (``NAME:group``: to its whole process group, workers included; ``NAME:swallowed``: raised and
caught there, as the llvmlite case). Unset, it costs one dictionary look-up.
"""

from __future__ import annotations

import os
import signal
import time

__all__ = ["dask_setup", "install_interrupt_memory", "interrupt_received", "raise_if_interrupted", "interrupt_point"]

_received = False
_installed = False
TEST_ENV = "IMUNOISE_TEST_SIGINT"


def _on_sigint(signum, frame) -> None:  # noqa: ARG001 - the signal module's handler signature
    global _received
    _received = True
    raise KeyboardInterrupt


def _ignore_sigint_in_child() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def install_interrupt_memory() -> None:
    """For a command-line run (the process ends with it): SIGINT raises ``KeyboardInterrupt`` as usual and is
    also remembered; processes forked from now on ignore SIGINT. Idempotent; a no-op outside the main thread."""
    global _installed
    if _installed:
        return
    try:
        signal.signal(signal.SIGINT, _on_sigint)
    except ValueError:  # pragma: no cover - not the main thread
        return
    os.register_at_fork(after_in_child=_ignore_sigint_in_child)
    _installed = True


def dask_setup(worker=None) -> None:  # noqa: ARG001 - the Dask preload interface passes the worker
    """Run in each Dask worker process given this module as ``preload`` (the worker's main thread, at its
    start): the worker ignores SIGINT, the parent alone decides and closes the cluster."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def interrupt_received() -> bool:
    """True once a SIGINT reached this process after :func:`install_interrupt_memory` (even if swallowed)."""
    return _received


def raise_if_interrupted() -> None:
    """Raise ``KeyboardInterrupt`` if a SIGINT was received and swallowed: called before outputs are published."""
    if _received:
        raise KeyboardInterrupt


def interrupt_point(name: str) -> None:
    """A named step where a test may interrupt the run (module docstring); nothing when not asked for."""
    want = os.environ.get(TEST_ENV)
    if not want:
        return
    point, _, how = want.partition(":")
    if point != name:
        return
    if how == "group":
        os.killpg(os.getpgid(0), signal.SIGINT)
        time.sleep(5.0)  # interrupted at once by the handler's KeyboardInterrupt (PEP 475)
    elif how == "swallowed":
        try:
            signal.raise_signal(signal.SIGINT)
        except KeyboardInterrupt:
            pass  # what a C callback or a finaliser does with it
    else:
        signal.raise_signal(signal.SIGINT)
