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
    frame_mod._view_sky_cache.clear()
    frame_mod._celestial_state.cache_clear()


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
