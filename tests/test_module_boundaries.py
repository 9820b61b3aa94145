"""Module boundaries: no module reaches into another's private names (imported or as attributes of its
objects), the EKF owns its state (the online engine never writes an attribute of its EKF), and a GMWMFit is
assembled in one place."""

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


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def defined_private_names(tree: ast.AST) -> set[str]:
    """The private names a module defines: its module-level and class-level names (assignments, annotations,
    imports, functions, classes), every function or method it defines, and the attributes it sets on ``self``
    or ``cls``."""
    names: set[str] = set()

    def body(stmts: list[ast.stmt]) -> None:
        for s in stmts:
            if isinstance(s, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
                names.add(s.name)
            elif isinstance(s, ast.Assign):
                names.update(n.id for t in s.targets for n in ast.walk(t) if isinstance(n, ast.Name))
            elif isinstance(s, ast.AnnAssign) and isinstance(s.target, ast.Name):
                names.add(s.target.id)
            elif isinstance(s, ast.Import | ast.ImportFrom):
                names.update((a.asname or a.name).split(".")[0] for a in s.names)

    body(tree.body)
    for node in ast.walk(tree):
        if isinstance(node, ast.ClassDef):
            body(node.body)
        elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            names.add(node.name)
        elif (isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store | ast.Del)
              and isinstance(node.value, ast.Name) and node.value.id in ("self", "cls")):
            names.add(node.attr)
    return {n for n in names if _private(n)}


def private_attribute_uses(source: str, package_names: set[str], filename: str = "<src>") -> list[str]:
    """``x._name`` (read, write or call; also ``getattr/setattr/hasattr/delattr(x, "_name")``) where ``x`` is
    not ``self``/``cls``, ``_name`` is not a name this module defines (:func:`defined_private_names`: then it is
    another module's) and ``_name`` is one a module of the package defines (``package_names``; private names
    of other libraries, e.g. argparse's, are theirs to keep): "filename:lineno: x._name" per use."""
    tree = ast.parse(source, filename=filename)
    own = defined_private_names(tree)
    out = []
    for node in ast.walk(tree):
        base = None
        if isinstance(node, ast.Attribute) and _private(node.attr):
            base, name, what = node.value, node.attr, ast.unparse(node)
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
              and node.func.id in ("getattr", "setattr", "hasattr", "delattr") and len(node.args) >= 2
              and isinstance(node.args[1], ast.Constant) and isinstance(node.args[1].value, str)
              and _private(node.args[1].value)):
            base, name, what = node.args[0], node.args[1].value, ast.unparse(node)
        if base is None or (isinstance(base, ast.Name) and base.id in ("self", "cls")):
            continue
        if name not in own and name in package_names:
            out.append((node.lineno, node.col_offset, what))
    return [f"{filename}:{n}: {what}" for n, _, what in sorted(out)]


def package_private_names() -> set[str]:
    return set().union(*(defined_private_names(ast.parse(p.read_text(encoding="utf-8"))) for p in ENFORCED))


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


def test_no_private_attributes_of_other_modules():
    """No module reads, writes or calls another module's private attributes (``nav._store``, ``acc._stats``):
    what a module needs from another is public (a property, a method, a state object's field)."""
    names = package_private_names()
    found = []
    for path in ENFORCED:
        found += private_attribute_uses(path.read_text(encoding="utf-8"), names, str(path.relative_to(SRC)))
    assert found == []


def test_private_attribute_check_finds_offenders():
    src = (
        "import argparse\n"
        "_CACHE = {}\n"
        "class Engine:\n"
        "    def __init__(self, nav):\n"
        "        self._own = 1\n"  # the module's own attribute: allowed, on any object of it
        "        self._nav = nav\n"
        "    def run(self, other):\n"
        "        other._own += 1\n"
        "        x = self._nav._store\n"  # another module's attribute through one of ours
        "        nav_learn = other._learn_from(x)\n"
        "        other._t_in = 0.0\n"  # a write into another module's object
        "        s = getattr(other, '_store', None)\n"
        "        a = argparse._SubParsersAction\n"  # not the package's: argparse keeps its own
        "        return _CACHE, self._helper(), other.__class__\n"
        "    def _helper(self):\n"
        "        return cls._helper\n"
    )
    names = {"_store", "_learn_from", "_t_in", "_own", "_helper", "_CACHE", "_nav"}
    assert [f.split(": ", 1)[1] for f in private_attribute_uses(src, names)] == [
        "self._nav._store",
        "other._learn_from",
        "other._t_in",
        "getattr(other, '_store', None)",
    ]
    # the same use in the module that defines the name is not a crossing
    assert private_attribute_uses("class N:\n    def f(self):\n        self._store = 1\n"
                                  "def g(nav):\n    return nav._store\n", names) == []


def test_private_attribute_check_catches_a_planted_violation(tmp_path):
    """The package-wide check, run on a copy of a real module with one crossing planted, finds exactly it."""
    path = SRC / "experiments" / "window_errors.py"
    planted = path.read_text(encoding="utf-8") + "\n\ndef _planted(nav):\n    return nav._pending_samples, nav.state\n"
    names = package_private_names() | {"_pending_samples"}
    found = private_attribute_uses(planted, names, "window_errors.py")
    assert len(found) == 1 and found[0].endswith("nav._pending_samples")
