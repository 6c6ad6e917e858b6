"""The one rule for GL contexts (igserver/render/context.py): a context is made current before use.

Regression for the order-dependent failure that kept the volume tests on a private context: the shared
renderer has rendered, then a second standalone EGL context is created and released in the same thread
(a quality tool's scratch context, another test's renderer). Creating a context makes it current and
releasing it leaves none current; moderngl does not switch back, so without the rule the shared
renderer's draws and reads went nowhere (blank or stale frames, volume energies 0, then a crash).
This module creates one extra context on purpose: it is the case under test.
"""

from __future__ import annotations

import numpy as np

from igserver.render.context import create_context, release_context

from helpers import tiny

# A fire in front of a night camera: sky, surfaces, depth copy, volumes and post all run, so every
# kind of GL work (draws, compute dispatches for the volume modelling, a blit, readback) is exercised.
FIRE = {"time": {"utc": "2026-01-15T22:00:00Z", "sim_time": 100.0}, "camera": {"position": [0, -14, 3], "pitch": 5,
        "exposure_ev": 10}, "weather": {"wind_speed": 0.0}, "effects": [{"id": "f", "position": [0, 0, 0], "diameter": 2}]}


def _other_context_comes_and_goes() -> None:
    other = create_context()  # becomes the thread's current context
    other.clear(1.0, 0.0, 1.0, 1.0)  # do some work on it, as a tool would
    release_context(other)  # ... and release it: now no context is current


def test_shared_renderer_survives_another_context(renderer):
    scene = tiny(FIRE, 96, 54)
    first = renderer.render(scene)
    assert "volumes" in first.passes
    hdr_first = renderer.read_hdr()
    _other_context_comes_and_goes()
    second = renderer.render(scene)
    hdr_second = renderer.read_hdr()
    # The same state renders the same picture (the dither is a function of the pixel and host_frame).
    assert np.array_equal(first.rgba, second.rgba)
    assert np.array_equal(hdr_first, hdr_second)
    assert np.isfinite(hdr_second).all() and hdr_second[..., :3].max() > 0.0


def test_raw_context_use_through_the_renderer_is_made_current(renderer):
    """Code that holds the renderer's GL objects and uses ``renderer.ctx`` directly (quality tools,
    compute probes) reaches them after another context came and went."""
    values = np.arange(64, dtype="f4")
    buffer = renderer.ctx.buffer(values.tobytes())
    try:
        _other_context_comes_and_goes()
        renderer.ctx.finish()  # the access makes the renderer's context current again
        assert np.array_equal(np.frombuffer(buffer.read(), "f4"), values)
    finally:
        renderer.ctx.finish()
        buffer.release()
