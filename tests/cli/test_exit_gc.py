"""A command-line run freezes the objects alive at exit (imunoise.cli docstring: the interpreter's final
collection then skips them); ``main([...])`` called from Python leaves the collector as it was."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

# an atexit hook registered before main() runs after main()'s own (last in, first out) and reports
PROBE = """
import atexit, gc, sys
atexit.register(lambda: print("frozen" if gc.get_freeze_count() > 0 else "not frozen"))
import imunoise.cli
{call}
"""


def _run(call: str) -> str:
    env = dict(os.environ, PYTHONPATH=str(REPO / "src") + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = subprocess.run([sys.executable, "-c", PROBE.format(call=call), "--version"], env=env,
                         capture_output=True, text=True, timeout=300)
    return out.stdout.strip().splitlines()[-1]


def test_command_line_run_freezes_at_exit():
    assert _run("sys.argv[0] = 'imunoise'\ntry:\n    imunoise.cli.main()\nexcept SystemExit:\n    pass") == "frozen"


def test_main_with_arguments_does_not():
    assert _run("try:\n    imunoise.cli.main(['--version'])\nexcept SystemExit:\n    pass") == "not frozen"
