"""Data flows one way: no import cycle among the package's modules, and no module imports from a higher layer.

Every ``import``/``from ... import`` of every module is read (top level, inside functions and under
``TYPE_CHECKING`` alike). The layers, lowest first, follow the data path IMU → detection → modelling → filter
(a module may import its own layer and lower ones; the package ``__init__`` files re-export lazily and are
left out of the layer rule, not of the cycle rule). Within modelling: the processes and the model, the
estimator's machinery (``fitting``), the estimator and the model selection, then what is built on fits (the
Allan and EM baselines, the equivalent (N, K), the IMU model and its exports). ``tests/test_docs.py`` checks the
coarser stages the package docstrings state; this order refines it.
"""

from __future__ import annotations

import ast
import os
from pathlib import Path

SRC = Path(os.environ.get("IMUNOISE_LAYERS_SRC", Path(__file__).resolve().parents[1] / "src" / "imunoise"))

LAYERS: list[tuple[str, ...]] = [
    ("imunoise._version", "imunoise.errors", "imunoise.units", "imunoise.imu", "imunoise.report"),
    ("imunoise.io",),
    ("imunoise.detect", "imunoise.lines"),
    ("imunoise.noise", "imunoise.noise.wv", "imunoise.noise.wv_stream", "imunoise.noise.wv_log",
     "imunoise.noise.ar1_math", "imunoise.noise.process_base", "imunoise.noise.process_ma1",
     "imunoise.noise.process_white", "imunoise.noise.process_bias", "imunoise.noise.process_ar1",
     "imunoise.noise.processes", "imunoise.noise.state_space", "imunoise.noise.model"),
    ("imunoise.noise.fitting",),
    ("imunoise.noise.estimator", "imunoise.noise.selection"),
    ("imunoise.noise.allan", "imunoise.noise.plots", "imunoise.noise.em", "imunoise.noise.em_kalman",
     "imunoise.noise.equivalent_noise", "imunoise.noise.imu_model", "imunoise.export"),
    ("imunoise.nav",),
    ("imunoise.online",),
    ("imunoise.sim",),
    ("imunoise.inuse",),
    ("imunoise.calibrate", "imunoise.batch"),
    ("imunoise.experiments",),
    ("imunoise.cli", "imunoise.__main__"),
]


def _name(path: Path) -> str:
    parts = list(path.relative_to(SRC.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


MODULES = {_name(p): p for p in SRC.rglob("*.py")}


def imports_of(module: str) -> set[str]:
    """The package modules ``module`` imports anywhere in its source (a ``from pkg import sub`` names sub)."""
    path = MODULES[module]
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            for a in node.names:
                out.add(f"{mod}.{a.name}" if f"{mod}.{a.name}" in MODULES else mod)
    return {m for m in out if m in MODULES and m != module}


def layer_of(module: str) -> int:
    best, depth = -1, -1
    for i, layer in enumerate(LAYERS):
        for prefix in layer:
            if (module == prefix or module.startswith(prefix + ".")) and len(prefix) > depth:
                best, depth = i, len(prefix)
    return best


def test_every_module_has_a_layer():
    assert [m for m in MODULES if m != "imunoise" and layer_of(m) < 0] == []


def test_no_import_from_a_higher_layer():
    bad = []
    for m in MODULES:
        if MODULES[m].name == "__init__.py":
            continue  # lazy re-exports of the package's public names
        for dep in imports_of(m):
            if dep != "imunoise" and layer_of(dep) > layer_of(m):
                bad.append(f"{m} (layer {layer_of(m)}) imports {dep} (layer {layer_of(dep)})")
    assert bad == []


def test_no_import_cycle():
    graph = {m: imports_of(m) for m in MODULES}
    state: dict[str, int] = {}
    cycles: list[list[str]] = []

    def visit(m: str, stack: list[str]) -> None:
        state[m] = 1
        stack.append(m)
        for d in sorted(graph[m]):
            if state.get(d) == 1:
                cycles.append(stack[stack.index(d):] + [d])
            elif d not in state:
                visit(d, stack)
        stack.pop()
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [])
    # a package __init__ re-exporting its own submodules is not a cycle of the data path
    real = [c for c in cycles if not any(MODULES[x].name == "__init__.py" for x in c[:-1])]
    assert real == []
