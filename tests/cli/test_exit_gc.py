"""A command-line run turns the collector off while its parser and numba are imported, freezes what they made,
turns it back on for the command and freezes what is alive at exit (imunoise.cli docstring); ``main([...])``
called from Python leaves the collector as it was."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

# an atexit hook registered before main() runs after main()'s own (last in, first out) and reports; the
# handler is wrapped to report the collector's state while the command runs
PROBE = """
import atexit, gc, sys
atexit.register(lambda: print("exit:", "frozen" if gc.get_freeze_count() > 0 else "not frozen"))
import imunoise.cli.nav as nav
run = nav.run
def probe(args):
    print("command:", "on" if gc.isenabled() else "off", "frozen" if gc.get_freeze_count() > 0 else "not frozen")
    return run(args)
nav.run = probe
import imunoise.cli
{call}
"""
ARGS = ["nav", "--data", "no/such/folder", "--out", "unused"]


def _run(call: str) -> list[str]:
    env = dict(os.environ, PYTHONPATH=str(REPO / "src") + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = subprocess.run([sys.executable, "-c", PROBE.format(call=call), *ARGS], env=env, capture_output=True,
                         text=True, timeout=300)
    return out.stdout.strip().splitlines()


def test_command_line_run_freezes_after_imports_and_at_exit():
    assert _run("sys.argv[0] = 'imunoise'\nsys.exit(imunoise.cli.main())") == ["command: on frozen", "exit: frozen"]


def test_main_with_arguments_does_not():
    assert _run(f"sys.exit(imunoise.cli.main({ARGS!r}))") == ["command: on not frozen", "exit: not frozen"]
