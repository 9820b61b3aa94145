"""Command-line interface `imunoise`.

Each subcommand lives in its own module in this package and exposes
``register(subparsers) -> None``, which adds one or more sub-parsers whose ``func`` default is the
handler ``func(args) -> int``. Modules are discovered automatically, so adding a command is adding a file.
Errors of type :class:`imunoise.errors.ImunoiseError` become a one-line message and exit code 2 (Python
field names in it replaced by the flags that set them); every ``type=float`` option is checked finite at
parse time; Ctrl-C anywhere — also inside a numba kernel, where it surfaces as a ``SystemError`` whose
cause/context chain holds the ``KeyboardInterrupt`` — ends with one line and exit code 130.

A command-line run (``main()`` reading ``sys.argv``) ends its process, and most of the objects it makes are
modules that live to its end (numba alone makes hundreds of thousands): the collector is off while the command's
parser and numba are imported, what they made is frozen (:func:`gc.freeze`) so later collections skip it, and
the objects alive at exit are frozen too (at ``atexit``), so the interpreter's last collection does not walk
them (together ≈ 0.25 s CPU of a 1.2 s `nav --no-plots`). Nothing changes for ``main([...])`` called from
Python.

Top of the stack: a command may import any module of the data path (IMU → detection → modelling →
filter) and :mod:`imunoise.experiments`; nothing but ``imunoise.__main__`` imports the CLI.
"""

from __future__ import annotations

import argparse
import atexit
import gc
import importlib
import pkgutil
import sys

from imunoise._version import __version__
from imunoise.cli.options import finite_floats_everywhere, flag_names
from imunoise.errors import ImunoiseError

EPILOG = """examples:
  imunoise fit gyro.csv --freq 100 --model "2*AR1+WN+RW" --units deg/s --out fit/
  imunoise demo --out out/demo
run `imunoise COMMAND --help` for the options and examples of each command."""


def build_parser(command: str | None = None) -> argparse.ArgumentParser | None:
    """The `imunoise` parser with every command, or with only ``command`` when the module of that name (``-``
    dropped: ``warm-up`` → ``warmup``) registers it: a run of one command then imports and builds only its
    own parser (its options, help and errors are the same); None when that module does not register it."""
    parser = argparse.ArgumentParser(
        prog="imunoise",
        description="Stochastic error modelling of inertial sensors (GMWM) and INS/GNSS navigation.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"imunoise {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    names = sorted(m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_"))
    if command is not None:
        names = [n for n in names if n == command.replace("-", "")]
    for name in names:
        module = importlib.import_module(f"{__name__}.{name}")
        register = getattr(module, "register", None)
        if register is not None:
            register(sub)
    if command is not None and command not in sub.choices:
        return None
    finite_floats_everywhere(parser)
    return parser


def interrupted(exc: BaseException) -> bool:
    """True when ``exc`` is, or was caused by (``__cause__``/``__context__`` chain), a KeyboardInterrupt: a
    Ctrl-C inside a numba kernel reaches Python as a ``SystemError`` chained to it."""
    seen: set[int] = set()
    e: BaseException | None = exc
    while e is not None and id(e) not in seen:
        if isinstance(e, KeyboardInterrupt):
            return True
        seen.add(id(e))
        e = e.__cause__ or e.__context__
    return False


def main(argv: list[str] | None = None) -> int:
    command_line = argv is None and gc.isenabled()  # the process ends with this command (module docstring)
    if command_line:
        from imunoise.io.interrupt import install_interrupt_memory

        install_interrupt_memory()  # a Ctrl-C swallowed anywhere still ends the run with 130; workers ignore it
        atexit.register(gc.freeze)
        gc.disable()  # until the imports below are done: module objects, not garbage
    words = sys.argv[1:] if argv is None else argv
    first = words[0] if words and not words[0].startswith("-") else None
    parser = (build_parser(first) if first else None) or build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "func", None) is None:
        parser.print_help()
        return 2
    from imunoise.cli.kernel_cache import announce_cold_cache

    announce_cold_cache(args.command)  # one line on stderr if this command has to compile numba kernels
    if command_line:
        gc.freeze()  # what the imports made lives to the end: later collections skip it
        gc.enable()
    try:
        code = int(args.func(args) or 0)
        from imunoise.io.interrupt import interrupt_received

        return _interrupted(args.command) if interrupt_received() else code
    except KeyboardInterrupt:
        return _interrupted(args.command)
    except ImunoiseError as exc:
        if interrupted(exc):
            return _interrupted(args.command)
        msg = "; ".join(line.strip() for line in str(exc).splitlines() if line.strip())  # one line
        msg = flag_names(msg)
        print(f"imunoise {args.command}: error: {msg}", file=sys.stderr)
        return 2
    except FileNotFoundError as exc:
        print(f"imunoise {args.command}: error: file not found: {exc.filename}", file=sys.stderr)
        return 2
    except OSError as exc:
        if interrupted(exc):
            return _interrupted(args.command)
        # last resort: the readers and prepare_out_dir name the file themselves; this keeps any other
        # OS error (disk full, permission on a nested output) to one line without a traceback
        where = f": {exc.filename}" if exc.filename else ""
        print(f"imunoise {args.command}: error: {exc.strerror or exc}{where}", file=sys.stderr)
        return 2
    except Exception as exc:
        if interrupted(exc):
            return _interrupted(args.command)
        from imunoise.cli.kernel_cache import no_cache_message

        msg = no_cache_message(exc)
        if msg is None:
            raise
        print(f"imunoise {args.command}: error: {msg}", file=sys.stderr)
        return 2


def _interrupted(command: str) -> int:
    print(f"imunoise {command}: interrupted (Ctrl-C)", file=sys.stderr)
    return 130


if __name__ == "__main__":
    sys.exit(main())
