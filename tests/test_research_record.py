"""The research record (docs/evidence/, scripts/) is named by topic, and what it names exists.

A newcomer finds a record by what it is about: no file there is named after an issue number, the old
folder of acceptance records is gone, and every ``docs/evidence/*.md`` or ``scripts/*.py`` path that the README, the
guide, CONTRIBUTING, the code or the tests mention is a file of the repository.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
NAMED = re.compile(r"(docs/evidence/[a-z0-9_-]+\.md|scripts/[a-z0-9_-]+\.py)")  # lower case: NAME.py is a pattern


def test_records_and_scripts_are_named_by_topic():
    old = ROOT / "docs" / "accept" "ance"  # spelled in two pieces: the renaming tool rewrites the whole name
    assert not old.exists(), f"{old} moved to docs/evidence/<topic>.md"
    names = [p.name for p in (ROOT / "docs" / "evidence").glob("*.md")]
    names += [p.name for p in (ROOT / "scripts").glob("*.py")]
    assert len(names) > 20
    numbered = [n for n in names if re.search(r"issue_?\d|acceptance_|evidence_\d", n)]
    assert not numbered, f"named by issue number rather than topic: {numbered}"


def test_every_mentioned_record_and_script_exists():
    sources = [ROOT / "README.md", ROOT / "CONTRIBUTING.md", ROOT / "BENCHMARKS.md"]
    for sub in ("docs", "src", "tests", "scripts", "benchmarks"):
        sources += [p for p in (ROOT / sub).rglob("*") if p.suffix in (".py", ".rst", ".md") and p.is_file()]
    missing = set()
    for path in sources:
        for rel in NAMED.findall(path.read_text(encoding="utf-8")):
            if not (ROOT / rel).exists():
                missing.add(f"{path.relative_to(ROOT)} -> {rel}")
    assert not missing, sorted(missing)
