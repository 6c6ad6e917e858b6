"""The package's layering, read from the source: every module imports; the scene model and the protocol's
models sit below the renderer (they never reach render/, directly or through another module); the
import circles that once tied the command line to the app, the lights to the fire lights and the BRDF
tables to the surfaces study stay broken; one LUMA; no study knob read from the environment."""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

import igserver

PACKAGE = Path(igserver.__file__).resolve().parent


def _module_name(path: Path) -> str:
    parts = ["igserver", *path.relative_to(PACKAGE).with_suffix("").parts]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _imports(name: str, path: Path) -> set[str]:
    """The igserver modules ``name`` imports anywhere in its source (functions included: a lazy import
    is still a dependency), each resolved to the module itself, not to the package above it."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(parent + ([node.module] if node.module else []))
            # ``from pkg import name``: a submodule when pkg/name.py exists, else a name in pkg
            targets = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in MODULES else base for alias in node.names]
        else:
            continue
        for target in targets:
            while target not in MODULES and "." in target:
                target = target.rpartition(".")[0]
            if target in MODULES and target != name:
                found.add(target)
    return found


GRAPH = {name: _imports(name, path) for name, path in MODULES.items()}


def _reachable(start: str) -> set[str]:
    seen, todo = set(), [start]
    while todo:
        for nxt in GRAPH[todo.pop()]:
            if nxt not in seen:
                seen.add(nxt)
                todo.append(nxt)
    return seen


@pytest.mark.parametrize("name", [n for n in MODULES if not n.endswith("__main__")])
def test_every_module_imports(name):
    importlib.import_module(name)


@pytest.mark.parametrize("low", ["igserver.scene", "igserver.protocol.models", "igserver.assets"])
def test_models_sit_below_the_renderer(low):
    # a module of the scene model, of the protocol's models or of the assets reaches no render/ module
    for name in [n for n in MODULES if n == low or n.startswith(low + ".")]:
        upward = sorted(m for m in _reachable(name) | GRAPH[name] if m.startswith("igserver.render"))
        assert not upward, f"{name} reaches {upward}"


@pytest.mark.parametrize("a, b", [
    ("igserver.cli", "igserver.protocol.app"),
    ("igserver.render.lights", "igserver.render.volumes.fire_lights"),
    ("igserver.quality.brdf_tables", "igserver.quality.surfaces"),
    ("igserver.render.common.aerial_table", "igserver.render.sky.frame_sky"),
])
def test_no_import_circle(a, b):
    assert not (b in _reachable(a) and a in _reachable(b)), f"{a} and {b} import each other"


def test_the_walk_sees_imports():
    # the graph is not vacuous: relative, absolute and lazy imports are all found
    assert "igserver.assets.gltf" in GRAPH["igserver.scene.surfaces"]
    assert "igserver.render.volumes.fire_lights" in GRAPH["igserver.render.lights"]
    assert "igserver.protocol.app" in GRAPH["igserver.cli"]  # imported inside cmd_serve


def test_one_luma():
    # Rec. 709 luminance weights are written once, in igserver/photometry.py, and imported everywhere
    spelled = [name for name, path in MODULES.items() if "0.2126" in path.read_text()]
    assert spelled == ["igserver.photometry"]


def test_no_study_knob_in_the_environment():
    # reference paths of the quality studies are arguments (Renderer(atmosphere_direct=...),
    # SurfacesPass.aerial_exact), not process-wide environment variables
    for name, path in MODULES.items():
        text = path.read_text()
        assert "IGSERVER_ATMOSPHERE_DIRECT" not in text and "IGSERVER_AERIAL_EXACT" not in text, name
