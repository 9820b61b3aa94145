"""The shell of the bit-identity scripts (``filter_model_identity.py``, ``online_engine_identity.py``): ``run OUT``
saves what the script's ``run`` returns (a dict) with the code on ``PYTHONPATH``; ``compare A B`` checks two saved
runs key by key with the script's comparator and prints each identical key. Not a script itself: the scripts import
it from their own folder (``python scripts/NAME.py`` puts that folder on ``sys.path``).
"""

from __future__ import annotations

import logging
import pickle
import sys
from collections.abc import Callable


def same_exactly(x, y, path: str) -> None:
    """The plain comparator: ``x == y``, else an ``AssertionError`` naming the key and both values."""
    assert x == y, (path, x, y)


def run_or_compare(argv: list[str], run: Callable[[], dict], same: Callable[[object, object, str], None],
                   usage: str) -> int:
    """``run OUT`` (pickle ``run()`` into OUT) or ``compare A B`` (``same(a[k], b[k], k)`` for every key, the
    keys equal); otherwise print ``usage`` and return 2."""
    logging.disable(logging.WARNING)
    if len(argv) == 2 and argv[0] == "run":
        with open(argv[1], "wb") as fh:
            pickle.dump(run(), fh)
        return 0
    if len(argv) == 3 and argv[0] == "compare":
        with open(argv[1], "rb") as fa, open(argv[2], "rb") as fb:
            a, b = pickle.load(fa), pickle.load(fb)
        assert set(a) == set(b), set(a) ^ set(b)
        for k in a:
            same(a[k], b[k], k)
            print("identical:", k)
        return 0
    print(usage, file=sys.stderr)
    return 2
