"""The tests mirror the package: a test file sits in ``tests/<folder>/`` named after a folder of ``src/imunoise``
(or at ``tests/`` when its module sits at the package root or it checks the whole package), and no two test files
share a name (the folders are not packages: pytest imports each file by its name)."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

TESTS = Path(__file__).resolve().parent
PACKAGE = TESTS.parent / "src" / "imunoise"


def test_every_test_folder_is_a_package_folder():
    folders = {p.parent.relative_to(TESTS).as_posix() for p in TESTS.rglob("test_*.py")} - {"."}
    package = {p.relative_to(PACKAGE).as_posix() for p in PACKAGE.rglob("*") if (p / "__init__.py").is_file()}
    assert folders and folders <= package, sorted(folders - package)


def test_test_file_names_are_unique():
    names = Counter(p.name for p in TESTS.rglob("test_*.py"))
    assert [n for n, k in names.items() if k > 1] == []
    assert not any(TESTS.rglob("__init__.py"))  # a package folder named io, cli, ... would shadow other modules


def test_no_source_file_is_longer_than_450_lines():
    # a file a newcomer can read whole; a longer one holds more than one concept (split it by concept)
    long = {p.relative_to(PACKAGE).as_posix(): n for p in PACKAGE.rglob("*.py")
            if (n := len(p.read_text(encoding="utf-8").splitlines())) > 450}
    assert long == {}, long


def test_the_package_root_holds_at_most_eight_modules():
    # the root is the facade and the shared vocabulary; everything else lives in a folder named for its concept
    root = sorted(p.name for p in PACKAGE.glob("*.py"))
    assert len(root) <= 8, root
