"""Sphinx configuration of the imunoise documentation (``make docs``; built by tests/test_docs.py too).

Two parts: the user guide (``guide/``, reStructuredText, its examples run by tests/test_guide_examples.py) and
the API reference (``api/``), generated from the numpydoc docstrings (autodoc + napoleon). Warnings are errors
(``-W``).
The build needs no network: the HTML refers to MathJax by URL only for rendering the equations.
"""

from __future__ import annotations

import sys
from pathlib import Path

from docutils import nodes
from sphinx.util.docutils import SphinxDirective

HERE = Path(__file__).resolve().parent
SRC = HERE.parent / "src"
if str(SRC) not in sys.path:  # the checkout's code, also when imunoise is not installed (editable installs agree)
    sys.path.insert(0, str(SRC))

import imunoise  # noqa: E402

project = "imunoise"
author = "imunoise contributors"
copyright = "imunoise contributors, BSD-3-Clause"
release = version = imunoise.__version__

extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon", "sphinx.ext.mathjax"]
exclude_patterns = ["_build", "evidence", "img"]  # Markdown records and figures, not pages
html_theme = "alabaster"
html_static_path: list[str] = []

napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False  # "Returns" as one field with its type, as numpy's reference shows it
napoleon_use_ivar = True  # "Attributes" of records as fields, not as separate (duplicate) attribute entries

autodoc_member_order = "bysource"
autodoc_typehints = "signature"
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": False}


class CliCommands(SphinxDirective):
    """``.. imunoise-cli::``: the ``--help`` text of ``imunoise`` and of every subcommand, from the live parser."""

    has_content = False

    def run(self) -> list[nodes.Node]:
        import argparse
        import os

        from imunoise.cli import build_parser

        # argparse wraps to the terminal width; the page must not depend on it (restored: the test suite
        # builds the reference in its own process)
        old = os.environ.get("COLUMNS")
        os.environ["COLUMNS"] = "100"
        try:
            parser = build_parser()
            out: list[nodes.Node] = [nodes.literal_block(text=parser.format_help())]
            subs = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
            for name, sub in sorted(subs.choices.items()):
                section = nodes.section(ids=[f"cmd-{name}"], names=[f"imunoise {name}"])
                section += nodes.title(text=f"imunoise {name}")
                section += nodes.literal_block(text=sub.format_help())
                out.append(section)
        finally:
            if old is None:
                os.environ.pop("COLUMNS", None)
            else:
                os.environ["COLUMNS"] = old
        return out


def setup(app):
    app.add_directive("imunoise-cli", CliCommands)
    return {"parallel_read_safe": True}
