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
