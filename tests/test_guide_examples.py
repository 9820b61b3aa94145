"""Every example of the user guide (docs/guide/*.rst, built by ``make docs``) runs as written.

The pages run in the order of the table of contents, each page's blocks in order, in one scratch repository
root (how: tests/doc_examples.py). The slow-tagged blocks run in test_readme.py's slow test.
"""

from __future__ import annotations

import pytest

from conftest import REPO
from doc_examples import TEST_TIMEOUT_S, guide_blocks, guide_pages, run_all

BLOCKS = guide_blocks()


def test_every_guide_page_is_in_the_table_of_contents():
    listed = {p.name for p in guide_pages()}
    present = {p.name for p in (REPO / "docs" / "guide").glob("*.rst")}
    assert listed == present, f"pages not in docs/index.rst: {present - listed}; listed but absent: {listed - present}"


@pytest.mark.slow  # the guide's examples end to end (several minutes); make test runs them
@pytest.mark.timeout(TEST_TIMEOUT_S)
def test_guide_examples(tmp_path):
    """The untagged blocks of every page, in the guide's order."""
    run_all([b for b in BLOCKS if b.tag == ""], tmp_path)


@pytest.mark.slow
@pytest.mark.timeout(TEST_TIMEOUT_S)
def test_guide_shared_examples(tmp_path, shared_data):
    """Blocks tagged needs-shared: they read ../shared/data (skipped when it is absent)."""
    shared_data()  # skips with the reason when ../shared/data is missing
    run_all([b for b in BLOCKS if b.tag == "needs-shared"], tmp_path)


@pytest.mark.parametrize("block", [b for b in BLOCKS if b.tag in ("skip", "template")],
                         ids=lambda b: f"{b.source.split('/')[-1]}:{b.line}")
def test_guide_skipped_blocks_are_reported(block):
    assert block.note, f"{block.label}: a skip tag or a template line needs a reason"
    pytest.skip(f"{block.label}: {block.tag}: {block.note}")
