"""Shared fixtures: one resident renderer for the session (context creation and shader compiles
are paid once), and a helper that makes a tiny scene from a patch."""

from __future__ import annotations

import pytest



@pytest.fixture(scope="session")
def renderer():
    from igserver.render.renderer import Renderer

    r = Renderer()
    yield r
    r.release()
