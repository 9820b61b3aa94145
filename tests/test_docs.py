"""API reference and docstrings (architecture issue: numpydoc docstrings, ``make docs``, package docstrings).

The Sphinx build of docs/ (user guide + API reference) must pass with warnings as errors (what ``make docs``
runs), the exported
names and the main entry points must document their parameters in numpydoc sections, and each package's
docstring must say what it owns; the import layering those docstrings state is checked against the code.
"""

from __future__ import annotations

import ast
import inspect
import re
from pathlib import Path

import pytest

import imunoise

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "imunoise"


def _section(doc: str | None, name: str) -> bool:
    """A numpydoc section header: the name on its own line, underlined with dashes of the same length."""
    return re.search(rf"^{name}\n-{{{len(name)}}}$", doc or "", flags=re.MULTILINE) is not None


# ---------------------------------------------------------------------------------------------------
# the Sphinx build
# ---------------------------------------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:The mapping interface for autodoc options")  # napoleon inside Sphinx 9
def test_sphinx_build_has_no_warnings_and_documents_the_api(tmp_path):
    from sphinx.cmd.build import build_main

    from imunoise.cli import build_parser

    out, warn = tmp_path / "html", tmp_path / "warnings.txt"
    code = build_main(["-W", "--keep-going", "-q", "-b", "html", "-w", str(warn), str(ROOT / "docs"), str(out)])
    assert code == 0, f"Sphinx build failed (make docs):\n{warn.read_text() if warn.exists() else ''}"
    assert not warn.exists() or not warn.read_text().strip(), warn.read_text()

    def page(name: str) -> str:
        return (out / "api" / f"{name}.html").read_text(encoding="utf-8")

    expect = {
        "index": ["facade.html", "online.html", "cli.html"],
        "facade": ["imunoise.__all__", "ImunoiseError", "select_model"],
        "wv": ["wavelet_variance", "WVAccumulator", "WaveletVariance", "WVStream"],
        "estimator": ["gmwm", "GMWMFit", "refit"],
        "selection": ["select_model"],
        "allan": ["allan_fit", "read_allan"],
        "em": ["em_fit"],
        "detect": ["detect_static", "StaticDetector"],
        "nav": ["run_ekf", "LooselyCoupledEKF", "InitialState", "nav_errors"],
        "online": ["OnlineNavigator", "push_imu", "push_gnss"],
        "sim": ["simulate_drive", "DriveConfig"],
        "io": ["read_imu", "read_gnss", "read_imu_source"],
        "export": ["export_text", "write_export"],
    }
    for name, words in expect.items():
        text = page(name)
        missing = [w for w in words if w not in text]
        assert not missing, f"{name}.html lacks {missing}"
    # numpydoc sections become field lists, not literal "Parameters" / "-------" text
    assert '>Parameters<span class="colon">' in page("wv"), "napoleon did not turn Parameters into a field list"
    assert "----------" not in page("wv")
    # the front page leads to the guide and the reference; each guide page is built with its examples
    front = (out / "index.html").read_text(encoding="utf-8")
    guide = sorted(p.stem for p in (ROOT / "docs" / "guide").glob("*.rst"))
    assert all(f"guide/{g}.html" in front for g in guide) and "api/index.html" in front
    for g in guide:
        html = (out / "guide" / f"{g}.html").read_text(encoding="utf-8")
        assert "readme-test" not in html  # the test tags are comments, not text
    assert 'class="highlight-python' in (out / "guide" / "modelling.html").read_text(encoding="utf-8")
    # the CLI page holds the --help of every registered command
    cli = page("cli")
    sub = next(a for a in build_parser()._actions if a.__class__.__name__ == "_SubParsersAction")
    missing = [c for c in sub.choices if f"imunoise {c}" not in cli]
    assert not missing, f"cli.html lacks the commands {missing}"


# ---------------------------------------------------------------------------------------------------
# docstrings of the public API
# ---------------------------------------------------------------------------------------------------
# exception classes take only a message; what each one means is its one-line docstring
EXEMPT = {
    "ImunoiseError": "exception: message only",
    "DataError": "exception: message only",
    "ModelError": "exception: message only",
    "UnitError": "exception: message only",
    "FitError": "exception: message only",
}


def test_exported_names_document_parameters():
    bad = []
    for name in imunoise.__all__:
        obj = getattr(imunoise, name)
        if not (inspect.isclass(obj) or inspect.isfunction(obj)) or name in EXEMPT:
            continue
        doc = inspect.getdoc(obj)
        ok = _section(doc, "Parameters") or (inspect.isclass(obj) and _section(doc, "Attributes"))
        if not ok:
            bad.append(name)
    assert not bad, f"exported names without a numpydoc Parameters (or, for classes, Attributes) section: {bad}"
    assert set(EXEMPT) <= set(imunoise.__all__), "an exempt name is no longer exported: drop it from EXEMPT"


def _main_entry_points():
    from imunoise import export
    from imunoise.detect import StaticDetector, detect_static
    from imunoise.io.kfgins import read_gnss, read_imu
    from imunoise.nav import LooselyCoupledEKF, run_ekf
    from imunoise.noise import allan
    from imunoise.online import OnlineNavigator, run_online
    from imunoise.sim import simulate_drive

    objs = {
        "detect_static": detect_static,
        "StaticDetector": StaticDetector,
        "StaticDetector.push": StaticDetector.push,
        "StaticDetector.push_chunk": StaticDetector.push_chunk,
        "run_ekf": run_ekf,
        "LooselyCoupledEKF": LooselyCoupledEKF,
        "OnlineNavigator": OnlineNavigator,
        "run_online": run_online,
        "simulate_drive": simulate_drive,
        "read_imu": read_imu,
        "read_gnss": read_gnss,
        "allan_fit": allan.allan_fit,
        "read_allan": allan.read_allan,
    }
    for meth in ("propagate", "update_gnss", "zupt_update", "zaru_update", "swap_model"):
        objs[f"LooselyCoupledEKF.{meth}"] = getattr(LooselyCoupledEKF, meth)
    for meth in ("push_imu", "push_gnss", "run"):
        objs[f"OnlineNavigator.{meth}"] = getattr(OnlineNavigator, meth)
    for name in ("axis_noise", "sensor_noise", "export_text", "write_export", "read_export", "parse_inflate"):
        objs[f"export.{name}"] = getattr(export, name)
    return objs


def test_main_entry_points_document_parameters():
    bad = [name for name, obj in _main_entry_points().items() if not _section(inspect.getdoc(obj), "Parameters")]
    assert not bad, f"without a numpydoc Parameters section: {bad}"


# ---------------------------------------------------------------------------------------------------
# package docstrings and the layering they state
# ---------------------------------------------------------------------------------------------------
PACKAGES = sorted(p.parent for p in SRC.rglob("__init__.py"))


@pytest.mark.parametrize("pkg", PACKAGES, ids=lambda p: p.relative_to(SRC.parent).as_posix())
def test_package_docstring_says_what_it_owns(pkg):
    doc = ast.get_docstring(ast.parse((pkg / "__init__.py").read_text(encoding="utf-8"))) or ""
    flat = " ".join(doc.split())
    assert len(doc.splitlines()) >= 2, f"{pkg.name}/__init__.py: the docstring must say what the package owns"
    assert "IMU → detection → modelling → filter" in flat, f"{pkg.name}: place the package on the data path"


# stage of each top-level module or package along IMU → detection → modelling → filter (0: shared support)
STAGE = {
    "errors": 0, "units": 0, "report": 0, "_version": 0,
    "imu": 1,
    "io": 1,
    "detect": 2, "lines": 2,
    "noise": 3, "export": 3,
    "nav": 4,
    "online": 5, "inuse": 5,
    "sim": 6,
    "experiments": 7, "batch": 7, "calibrate": 7,
    "cli": 8, "__main__": 8,
}


def _imported_stages(path: Path) -> list[tuple[int, str, int]]:
    """(line, imported imunoise module, its stage) for every import in the file (also inside functions)."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            mods = [node.module]
            if node.module == "imunoise":  # the facade: judge by what is taken from it
                mods = [imunoise._LAZY.get(a.name, "imunoise.noise.model")
                        if a.name != "__version__" else "imunoise.errors"
                        for a in node.names]
        elif isinstance(node, ast.Import):
            mods = [a.name for a in node.names]
        else:
            continue
        for mod in mods:
            parts = mod.split(".")
            if parts[0] == "imunoise" and len(parts) > 1:
                out.append((node.lineno, mod, STAGE[parts[1]]))
    return out


def test_stages_import_only_earlier_stages():
    bad = []
    for path in sorted(SRC.rglob("*.py")):
        rel = path.relative_to(SRC)
        if rel.name == "__init__.py" and len(rel.parts) == 1:
            continue  # the facade re-exports from every stage, lazily
        own = STAGE[rel.parts[0].removesuffix(".py")]
        found = _imported_stages(path)
        bad += [f"{rel}:{line} imports {mod} (stage {st} > {own})" for line, mod, st in found if st > own]
    assert not bad, "a stage imports a later one:\n" + "\n".join(bad)
    assert set(STAGE) >= {p.stem for p in SRC.iterdir() if p.suffix == ".py" or (p / "__init__.py").exists()} - {
        "__init__"
    }, "a new top-level module needs its stage in STAGE"
