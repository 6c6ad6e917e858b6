"""Shared fixtures: one resident renderer (one GL context) for the whole session — context creation and
shader compiles are paid once, and every GL test runs on the same context in any order. The renderer
makes its context current before each use (igserver/render/context.py: the one rule for GL contexts),
so a test that creates and releases another context cannot take the shared renderer's calls."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def renderer():
    from igserver.render.renderer import Renderer

    r = Renderer()
    yield r
    r.release()


# A module that can start other processes (a real server, the render process, the CLI, a browser)
# names one of these: its tests are marked ``process``.
PROCESS_NAMES = ("LoopbackServer", "RenderService", "subprocess", "cdp")
# A test function that names one of these itself (``import subprocess`` inside it, a helper that runs a
# server in a process of its own) is marked ``process`` too, the rest of its module not.
FUNCTION_PROCESS_NAMES = PROCESS_NAMES + ("ServerProcess",)


def pytest_collection_modifyitems(config, items):
    """Mark what each test needs, so a run can select the fast in-process, GL-free tests
    (``-m "not gl and not process"``: the mutation run's selection, scripts/mutation.sh)."""
    for item in items:
        if "renderer" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.gl)
        module = getattr(item, "module", None)
        code = getattr(getattr(item, "function", None), "__code__", None)
        if (module is not None and any(hasattr(module, name) for name in PROCESS_NAMES)) or (
                code is not None and any(name in code.co_names for name in FUNCTION_PROCESS_NAMES)):
            item.add_marker(pytest.mark.process)
