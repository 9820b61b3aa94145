"""Module boundaries: no module reaches into another's private names, the EKF owns its state (the online
engine never writes an attribute of its EKF), and a GMWMFit is assembled in one place."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "imunoise"
# where the private-import rule is enforced so far (the rest of the package: private_imports_of)
ENFORCED = sorted(SRC.rglob("*.py"))  # every module of the package


def _module_name(path: Path) -> str:
    rel = path.relative_to(SRC.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def private_imports(source: str, module: str, *, is_package: bool = False) -> list[str]:
    """``from imunoise.X import _name`` (absolute or relative) in the source of ``module`` where X is another
    module: "lineno: imunoise.X._name" per name."""
    package = module if is_package else module.rpartition(".")[0]
    out = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.ImportFrom):
            continue
        if node.level:
            base = package.split(".")
            base = base[: len(base) - node.level + 1]
            mod = ".".join(base + ([node.module] if node.module else []))
        else:
            mod = node.module or ""
        if not (mod == "imunoise" or mod.startswith("imunoise.")) or mod == module:
            continue
        for alias in node.names:
            if alias.name.startswith("_") and not alias.name.startswith("__"):
                out.append(f"{node.lineno}: {mod}.{alias.name}")
    return out


def private_imports_of(path: Path) -> list[str]:
    found = private_imports(path.read_text(encoding="utf-8"), _module_name(path), is_package=path.name == "__init__.py")
    return [f"{path.relative_to(SRC.parent)}:{f}" for f in found]


def fit_constructions(source: str, filename: str = "<src>") -> list[str]:
    """Calls ``GMWMFit(...)`` (or ``x.GMWMFit(...)``): a fit is assembled only by ``GMWMFit.from_problem``
    (and read back by ``from_dict``, which calls ``cls(...)``), so WV, Ω, rate and GOF come from one problem."""
    out = []
    for node in ast.walk(ast.parse(source, filename=filename)):
        if isinstance(node, ast.Call):
            f = node.func
            name = f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else ""
            if name == "GMWMFit":
                out.append(f"{filename}:{node.lineno}")
    return out


def _ekf_names(tree: ast.AST) -> set[str]:
    """Names (variables or attributes) that hold an EKF: ``ekf`` and whatever is assigned ``LooselyCoupledEKF(...)``."""
    names = {"ekf"}
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign) and isinstance(node.value, ast.Call):
            f = node.value.func
            if (isinstance(f, ast.Name) and f.id == "LooselyCoupledEKF") or (
                isinstance(f, ast.Attribute) and f.attr == "LooselyCoupledEKF"
            ):
                for t in node.targets:
                    if isinstance(t, ast.Name):
                        names.add(t.id)
                    elif isinstance(t, ast.Attribute):
                        names.add(t.attr)
    return names


def _holds_ekf(expr: ast.AST, names: set[str]) -> bool:
    return (isinstance(expr, ast.Name) and expr.id in names) or (isinstance(expr, ast.Attribute) and expr.attr in names)


def ekf_attribute_writes(source: str, filename: str = "<src>") -> list[str]:
    """Assignments (=, +=, annotated, del, setattr) whose target is an attribute of an EKF object or part of one,
    e.g. ``ekf.P = ...``, ``self.ekf.nav[10:13] = ...``; ``self.ekf = LooselyCoupledEKF(...)`` is not one."""
    tree = ast.parse(source, filename=filename)
    names = _ekf_names(tree)
    out: list[tuple[int, str]] = []

    def check(target: ast.AST, lineno: int) -> None:
        if isinstance(target, ast.Tuple | ast.List):
            for t in target.elts:
                check(t, lineno)
            return
        node = target
        while isinstance(node, ast.Attribute | ast.Subscript | ast.Starred):
            node = node.value
            if _holds_ekf(node, names):
                out.append((lineno, ast.unparse(target)))
                return

    for node in ast.walk(tree):
        if isinstance(node, ast.Assign):
            for t in node.targets:
                check(t, node.lineno)
        elif isinstance(node, ast.AugAssign | ast.AnnAssign):
            check(node.target, node.lineno)
        elif isinstance(node, ast.Delete):
            for t in node.targets:
                check(t, node.lineno)
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("setattr", "delattr"):
            if node.args and _holds_ekf(node.args[0], names):
                out.append((node.lineno, ast.unparse(node)))
    return [f"{filename}:{n}: {what}" for n, what in sorted(out, key=lambda w: w[0])]


@pytest.mark.parametrize("path", ENFORCED, ids=lambda p: str(p.relative_to(SRC)))
def test_no_private_names_imported_from_other_modules(path):
    assert private_imports_of(path) == []


def test_private_import_check_finds_offenders():
    src = (
        "from imunoise.nav.ekf import AXES, _sensor_errors\n"
        "from imunoise.nav.probe import _own\n"  # the module's own name: not another module
        "def f():\n"
        "    from .ekf import _initial_P\n"
        "    from .. import _lazy\n"
        "    from imunoise.errors import DataError\n"
        "    from numpy import _private_numpy\n"
    )
    assert private_imports(src, "imunoise.nav.probe") == [
        "1: imunoise.nav.ekf._sensor_errors",
        "4: imunoise.nav.ekf._initial_P",
        "5: imunoise._lazy",
    ]


def test_enforced_list_covers_the_package():
    names = {str(p.relative_to(SRC)) for p in ENFORCED}
    assert {"noise/estimator.py", "noise/selection.py", "noise/allan/__init__.py", "noise/em.py",
            "noise/fitting/result.py", "noise/fitting/estimate.py",
            "online/navigator.py", "online/jobs.py", "nav/ekf.py", "cli/fit.py", "io/kfgins.py",
            "detect/detector.py"} <= names
    assert all(p.exists() for p in ENFORCED)


def test_gmwmfit_is_assembled_only_by_its_factory():
    found = []
    for path in sorted(SRC.rglob("*.py")):
        found += fit_constructions(path.read_text(encoding="utf-8"), str(path.relative_to(SRC)))
    assert found == []


def test_fit_construction_check_finds_offenders():
    src = (
        "fit = GMWMFit(model=m, objective=f)\n"
        "fit = estimator.GMWMFit(m, f)\n"
        "fit = GMWMFit.from_problem(problem, m)\n"  # the factory: allowed
        "def f(cls):\n"
        "    return cls(model=m)\n"  # from_dict inside the class: allowed
    )
    assert fit_constructions(src) == ["<src>:1", "<src>:2"]


def test_online_writes_no_attribute_of_its_ekf():
    paths = sorted((SRC / "online").glob("*.py"))
    assert SRC / "online" / "navigator.py" in paths  # the module that holds the EKF
    for path in paths:
        name = str(path.relative_to(SRC))
        assert ekf_attribute_writes(path.read_text(encoding="utf-8"), name) == [], name


def test_ekf_write_check_finds_offenders():
    src = (
        "class N:\n"
        "    def __init__(self):\n"
        "        self.ekf = LooselyCoupledEKF(c, m, i)\n"  # allowed: the navigator's own attribute
        "        self.ekf.nav[10:13] = dth\n"
        "        self.ekf.xm, self.ekf.P = x, P\n"
        "        self.ekf.acc[0] += 1.0\n"
        "def f(ekf, e2):\n"
        "    ekf.layout = new\n"
        "    setattr(ekf, 'P', P)\n"
        "    e = LooselyCoupledEKF(c, m, i)\n"
        "    e.t = 0.0\n"
        "    x = ekf.state()\n"  # allowed: reads and method calls
    )
    found = [f.split(": ", 1)[1] for f in ekf_attribute_writes(src)]
    assert found == [
        "self.ekf.nav[10:13]",
        "self.ekf.xm",
        "self.ekf.P",
        "self.ekf.acc[0]",
        "ekf.layout",
        "setattr(ekf, 'P', P)",
        "e.t",
    ]
