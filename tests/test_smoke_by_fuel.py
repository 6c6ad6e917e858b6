"""A fire's smoke by fuel, by day: black for oil, light grey for wood (docs/volumes.md).

Sunlit wood smoke (single-scattering albedo ~0.85, effect_kinds.FUELS) seen with the sun behind the
observer is a light grey plume, about as bright as the blue sky beside it, as a thin cloud is: much of its
light has scattered more than once, which a single-scattering march (a backward Henyey-Greenstein lobe,
~0.01/sr) misses: it drew the plume at 0.4x the sky, dark grey, hardly lighter than oil smoke (0.3x).
Oil smoke (albedo 0.25, soot) stays black against it."""

from __future__ import annotations

import numpy as np
import pytest

from igserver.photometry import LUMA
from igserver.render.frame import build_frame
from igserver.scene import apply_patch
from igserver.scene.files import load_scene


def luminance(renderer, fuel: str, smoke: bool) -> np.ndarray:
    s = load_scene("night_fire")
    effects = s.model_dump(mode="json")["effects"]
    effects[0].update(fuel=fuel, emits_smoke=smoke)
    s = apply_patch(s, {"time": {"utc": "2026-09-15T10:00:00Z"},  # local noon, sun 31 deg up behind the camera
                        "camera": {"position": [0.0, -45.0, 1.7], "pitch": 14.0, "width": 160, "height": 90,
                                   "exposure_ev": 14.0},
                        "effects": effects})
    renderer.render(s)
    return (renderer.read_hdr()[..., :3] / build_frame(renderer.ctx, s).exposure) @ LUMA


def plume_over_sky(renderer, fuel: str) -> float:
    """Mean ratio, over the plume's pixels against the sky (rows 0..60: above the flame), of the
    frame with the smoke to the frame without it; the plume's pixels: those it changes by 30 %."""
    with_smoke, without = luminance(renderer, fuel, True), luminance(renderer, fuel, False)
    plume = np.abs(with_smoke - without) / without > 0.3
    plume[60:] = False
    assert plume.sum() > 100, plume.sum()  # the plume is in view
    return float((with_smoke[plume] / without[plume]).mean())


@pytest.mark.parametrize("fuel, lo, hi", [("wood", 0.65, 4.0), ("oil", 0.0, 0.5)])
def test_sunlit_smoke_against_the_sky_by_fuel(renderer, fuel, lo, hi):
    # Bounds: wood light grey, at least 0.65 of the sky beside it (measured 0.82; the plume's
    # shadowed base and its sooty core keep it under the sky's brightness) and at most 4x (a white
    # cloud lit by this sun, ~0.7 E / pi, against the northern sky 20 deg up); oil under half the
    # sky (measured 0.32: black smoke, its light mostly absorbed).
    ratio = plume_over_sky(renderer, fuel)
    assert lo < ratio < hi, (fuel, ratio)



def test_a_host_setting_another_time_of_day_relights_the_smoke_at_once(renderer):
    # The smoke's sun shadow is modelled with its keyframes: a state that moves the sun by hours at the
    # same sim_time (a paused clock, a host jumping to noon) models them again, instead of lighting the
    # noon plume with the night's sun until sim_time reaches the next keyframe. (The suite's earlier
    # night renders of this fire made the wood plume 0.40 of the sky here.)
    night = load_scene("night_fire")
    effects = night.model_dump(mode="json")["effects"]
    effects[0].update(fuel="wood", emits_smoke=True)
    renderer.render(apply_patch(night, {"camera": {"position": [0.0, -45.0, 1.7], "pitch": 14.0, "width": 160,
                                                   "height": 90}, "effects": effects}))
    assert plume_over_sky(renderer, "wood") > 0.65
