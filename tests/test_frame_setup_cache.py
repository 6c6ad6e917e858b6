"""The per-frame setup's memoised parts (render/frame.py, sky/frame_sky.py: light, fog-layer table,
meter samples, ephemeris) give exactly what a cold computation gives, whatever changed since the
entry was made: each case changes one input a stale key would miss."""

import numpy as np
import pytest

from igserver.render import frame as frame_mod
from igserver.render.sky import frame_sky
from igserver.scene import apply_patch

from helpers import tiny

BASE = {"ocean": {"enabled": True}, "atmosphere": {"visibility": 12000.0, "visibility_transition": 0.0},
        "time": {"sun_override": {"elevation": 8.0, "azimuth": 230.0}}}
CHANGES = [
    {"time": {"sun_override": {"elevation": 3.0, "azimuth": 230.0}}},  # sun: light, haze table, meter
    {"atmosphere": {"visibility": 800.0}},  # fog: density, phase function, albedo
    {"atmosphere": {"visibility": 20000.0}},  # haze density alone (same layer shape and phase)
    {"camera": {"heading": 120.0}},  # view: meter samples
    {"camera": {"position": [0.0, 0.0, 400.0]}},  # altitude: light, sky view, meter
    {"time": {"utc": "2026-03-01T03:00:00Z", "sun_override": None}},  # ephemeris
]


def _clear_caches():
    frame_sky._sky_light_cache.clear()
    frame_sky.SKY_PARTS.clear()
    frame_mod._view_sky_cache.clear()
    frame_mod._celestial_state.cache_clear()
    frame_mod.SETUP.clear()


def _snapshot(renderer, scene):
    f = frame_mod.build_frame(renderer.ctx, scene, None)
    values = {k: v for k, v in f.uniforms.items() if not isinstance(v, bytes)}
    haze = frame_sky.held_haze_table(renderer.ctx)
    table = np.frombuffer(haze[0].read(), np.float32).copy() if haze is not None else None
    return values, f.ev100, f.meter_luminance, table


@pytest.mark.parametrize("change", CHANGES, ids=["sun", "fog", "haze_density", "heading", "altitude", "utc"])
def test_memoised_setup_equals_cold(renderer, change):
    base = tiny(BASE)
    changed = apply_patch(base, change)
    for first, second in ((base, changed), (changed, base)):
        _clear_caches()
        _snapshot(renderer, first)  # fills every cache with the other state
        warm = _snapshot(renderer, second)
        _clear_caches()
        cold = _snapshot(renderer, second)
        # Exact equality: a hit must be the same computation, not an approximation of it.
        assert warm[0] == cold[0]
        assert warm[1:3] == cold[1:3]
        assert (warm[3] is None) == (cold[3] is None)
        if cold[3] is not None:
            np.testing.assert_array_equal(warm[3], cold[3])
    # The change really is visible to the setup (else the case tests nothing).
    _clear_caches()
    assert _snapshot(renderer, base)[0] != _snapshot(renderer, changed)[0]


def _setup_counts() -> dict:
    # (the provisional meter's solve, "meter_target", follows the fire's flicker: per frame in the demo)
    out = {f"setup.{k}": v for k, v in frame_mod.SETUP.computed.items() if k != "meter_target"}
    out.update({f"sky.{k}": v for k, v in frame_sky.SKY_PARTS.computed.items()})
    return out


def _demo_stream(renderer, scene, frames, t0):
    for i in range(frames):
        renderer.render(apply_patch(scene, {"time": {"sim_time": t0 + i / 30.0}}))


def _demo():
    from igserver.scene import load_scene
    return apply_patch(load_scene("demo"), {"camera": {"width": 64, "height": 36}})


def test_a_stream_that_only_advances_sim_time_rederives_no_setup_item(renderer):
    # The demo's fire flickers and its cirrus drifts with sim_time: those are per frame; the view,
    # sun and moon, fog layer, sky light and uniforms are not.
    scene = _demo()
    _demo_stream(renderer, scene, 3, scene.time.sim_time)
    before = _setup_counts()
    assert {"setup.view", "setup.celestial", "setup.light_uniforms", "sky.sky", "sky.haze"} <= set(before)
    _demo_stream(renderer, scene, 6, scene.time.sim_time + 1.0)
    assert _setup_counts() == before


@pytest.mark.parametrize("patch, items", [
    ({"camera": {"heading": 291.0}}, {"setup.view"}),
    ({"camera": {"position": [0.0, -120.0, 30.0]}}, {"setup.view", "sky.sky"}),
    ({"time": {"sun_override": {"elevation": 4.0, "azimuth": 280.0}}},
     {"setup.celestial", "setup.light_uniforms", "sky.sky"}),
    ({"atmosphere": {"visibility": 5000.0}}, {"sky.haze", "sky.sky"}),
    ({"weather": {"cirrus_coverage": 0.6}}, {"sky.sky"}),
])
def test_each_setup_input_recomputes_its_items_and_nothing_else(renderer, patch, items):
    scene = _demo()
    _demo_stream(renderer, scene, 2, scene.time.sim_time)
    before = _setup_counts()
    changed = apply_patch(scene, patch)
    renderer.render(apply_patch(changed, {"time": {"sim_time": scene.time.sim_time + 2.0}}))
    after = _setup_counts()
    grew = {k for k in after if after[k] != before.get(k)}
    assert items <= grew, (patch, grew)
    assert not grew & {"setup.view"} or "camera" in patch, grew  # only the camera makes a new view
    renderer.render(apply_patch(changed, {"time": {"sim_time": scene.time.sim_time + 2.5}}))
    assert _setup_counts() == after


def test_the_provisional_meter_solves_once_per_change_of_its_samples(renderer):
    # A view without flickering lights meters the same samples every frame: solved once; the fire's
    # flicker changes them every frame: solved every frame.
    from igserver.scene import load_scene
    for name, fire in (("harbour_noon", False), ("night_fire", True)):
        scene = apply_patch(load_scene(name), {"camera": {"width": 64, "height": 36}})
        _demo_stream(renderer, scene, 2, scene.time.sim_time)
        before = frame_mod.SETUP.computed["meter_target"]
        _demo_stream(renderer, scene, 4, scene.time.sim_time + 1.0)
        assert frame_mod.SETUP.computed["meter_target"] - before == (4 if fire else 0), name
