"""Layers point one way: no import cycle among the project's modules or packages (imports inside functions
included), and the runtime imports nothing of the training side."""
from __future__ import annotations

import ast
from graphlib import CycleError, TopologicalSorter
from pathlib import Path

import pytest

from tests.conftest import REPOSITORY

PACKAGES = ("naoslam", "detector", "augment", "export", "calibration")


def _module_name(path: Path) -> str:
    parts = path.relative_to(REPOSITORY).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _import_graph() -> dict[str, set[str]]:
    """Each project module and the project modules it imports, anywhere in the file."""
    files = {_module_name(path): path for package in PACKAGES for path in (REPOSITORY / package).rglob("*.py")}
    graph = {}
    for name, path in files.items():
        imported = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                imported |= {node.module, *(f"{node.module}.{alias.name}" for alias in node.names)}
            elif isinstance(node, ast.Import):
                imported |= {alias.name for alias in node.names}
        graph[name] = {module for module in imported if module in files and module != name}
    return graph


def _layer(module: str) -> str:
    """The package a module belongs to, ``detector``'s subpackages (and top modules) each a layer of their own."""
    parts = module.split(".")
    return ".".join(parts[:2]) if parts[0] == "detector" and len(parts) > 1 else parts[0]


def _cycle(graph: dict[str, set[str]]) -> list[str]:
    try:
        TopologicalSorter(graph).prepare()
    except CycleError as error:
        return error.args[1]
    return []


def test_no_module_imports_itself_through_others():
    assert _cycle(_import_graph()) == []


def test_no_package_imports_itself_through_others():
    layers: dict[str, set[str]] = {}
    for module, imported in _import_graph().items():
        layers.setdefault(_layer(module), set()).update(_layer(m) for m in imported if _layer(m) != _layer(module))
    assert _cycle(layers) == []


def test_the_runtime_imports_nothing_of_the_training_side():
    outside = {module: sorted(m for m in imported if not m.startswith("naoslam"))
               for module, imported in _import_graph().items() if module.startswith("naoslam")}
    assert {module: found for module, found in outside.items() if found} == {}


@pytest.mark.parametrize("graph, expected", [({"a": {"b"}, "b": {"a"}}, True), ({"a": {"b"}, "b": set()}, False)])
def test_a_cycle_is_found(graph, expected):
    assert bool(_cycle(graph)) is expected


#: The training side's stages: each imports the core (datasets, file safety, console, model files) and naoslam,
#: never another stage; the command line, the demo and the SLAM runs sit on top of them.
STAGES = ("augment", "export", "calibration", "detector.training", "detector.evaluation", "detector.synth")


def test_no_stage_imports_another():
    crossing = {(_layer(module), _layer(imported)) for module, imports in _import_graph().items()
                for imported in imports
                if _layer(module) in STAGES and _layer(imported) in STAGES and _layer(imported) != _layer(module)}
    assert crossing == set()
