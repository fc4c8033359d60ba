"""The package's import graph has layers: a module imports only from its own layer or the layers before it, and
no two modules import each other (directly or around a circle). README's layout lists the layers in this order."""

from __future__ import annotations

import ast

from conftest import REPO

LAYERS = [
    ["errors", "yamlio", "outputs", "data", "symbolic_system"],
    ["unmodelled", "torque_disturbance", "rig", "plant"],
    ["friction", "encoder", "actuator", "drive", "world", "controllers"],
    ["observers", "linearization", "analysis"],
    ["config", "excitation", "diagram", "lab_controller", "simulate", "sweep", "results", "plotting"],
    ["parallel"],
    ["effects"],
    ["rig_file"],
    ["diagnosis"],
    ["design"],
    ["tune"],
    ["paper"],
    ["real_rig"],
    ["cli"],
]
LAYER = {name: number for number, names in enumerate(LAYERS) for name in names}
# The diagnosis' stages, in the same way (its package docstring lists them in this order).
DIAGNOSIS_LAYERS = [["settings", "formatting"], ["logs"], ["gap", "result"], ["selection"], ["report"], ["pipeline"]]
DIAGNOSIS_LAYER = {name: number for number, names in enumerate(DIAGNOSIS_LAYERS) for name in names}
PACKAGE = REPO / "furuta_drake"


def module_name(path) -> str:
    parts = path.relative_to(REPO).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports() -> dict[str, set[str]]:
    """Each module of the package -> the package's modules it imports (at any depth of its code)."""
    graph = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        found = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("furuta_drake."):
                found.add(node.module)
                found |= {f"{node.module}.{alias.name}" for alias in node.names}
            elif isinstance(node, ast.ImportFrom) and node.module == "furuta_drake":
                found |= {f"furuta_drake.{alias.name}" for alias in node.names}
        graph[module_name(path)] = found
    return {name: {target for target in targets if target in graph} for name, targets in graph.items()}


def layer(module: str) -> int | None:
    parts = module.split(".")
    return LAYER.get(parts[1]) if len(parts) > 1 else None


def test_every_module_sits_in_a_layer():
    assert [name for name in imports() if name != "furuta_drake" and layer(name) is None] == []


def test_no_module_imports_from_a_later_layer():
    upward = [
        f"{name} (layer {layer(name)}) imports {target} (layer {layer(target)})"
        for name, targets in imports().items()
        for target in targets
        if name != "furuta_drake" and layer(target) > layer(name)
    ]
    assert upward == [], "\n".join(upward)


def diagnosis_stage(module: str) -> int | None:
    parts = module.split(".")
    return DIAGNOSIS_LAYER.get(parts[2]) if len(parts) > 2 and parts[1] == "diagnosis" else None


def test_every_diagnosis_module_sits_in_a_stage():
    modules = [name for name in imports() if name.startswith("furuta_drake.diagnosis.")]
    assert len(modules) > 30
    assert [name for name in modules if diagnosis_stage(name) is None] == []


def test_no_diagnosis_stage_imports_from_a_later_one():
    upward = [
        f"{name} (stage {diagnosis_stage(name)}) imports {target} (stage {diagnosis_stage(target)})"
        for name, targets in imports().items()
        if diagnosis_stage(name) is not None
        for target in targets
        if diagnosis_stage(target) is not None and diagnosis_stage(target) > diagnosis_stage(name)
    ]
    assert upward == [], "\n".join(upward)


def test_the_import_graph_has_no_circle():
    graph = imports()
    state: dict[str, int] = {}
    circles = []

    def visit(node: str, path: list[str]) -> None:
        state[node] = 1
        for target in sorted(graph[node]):
            if state.get(target) == 1:
                circles.append(" -> ".join(path[path.index(target) :] + [target]))
            elif target not in state:
                visit(target, path + [target])
        state[node] = 2

    for node in sorted(graph):
        if node not in state:
            visit(node, [node])
    assert circles == [], "\n".join(circles)
