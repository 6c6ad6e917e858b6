"""Flicker lights of fires (docs/design.md#fire-and-smoke): one point light per burning fire or gas burner.

Intensity I (cd) ~ mean flame luminance x projected flame area: 0.3 x the core luminance over
0.5 D L (a tapered flame of diameter D, visible height L). Colour: a blackbody at the flame's
emission temperature (planck.py: CIE 1931, unit luminance), reddening as a fire dies down. That
temperature makes the light agree with the heat release: a pool fire radiates a third of its Q
(chi_r = 0.2-0.4 for large sooty pools: Koseki 1989, the SFPE Handbook), and the light sends
4 pi I lumens, so its radiation's luminous efficacy is 4 pi I / (chi_r Q) lm/W, which a blackbody
has at one temperature (planck.efficacy_temperature): 1,650-1,700 K for 2-3 m oil pools (a fixed
1,350 K, 0.02 lm/W, would have radiated ten times Q). Intensity and colour follow the fade level, and
a seeded flicker whose spectrum peaks at the puffing frequency f = 1.5 / sqrt(D) Hz
(point_lights.flicker_gain: deterministic in seed and sim_time, phases reduced in float64).
The light sits on the axis at 30 % of the flame height, where the glow's centroid is.
"""

from __future__ import annotations

import math

import numpy as np

from ...effect_kinds import EFFECT_KINDS
from ...photometry import LUMA
from ...scene.model import Effect, Scene
from ..point_lights import PointLight, flicker_gain
from .effects import CONTAINER_OVER_FLAME, effect_heat_release, effect_volumes, puffing_frequency
from .planck import blackbody_light_rgb, efficacy_temperature

LUMINANCE = 2.0e4  # cd/m^2, core luminance at intensity 1 (same as the volume's emission)
MIN_ILLUMINANCE = 0.02  # lux: the range is where the light falls below this
MAX_RANGE = 3000.0  # m

RADIATIVE_FRACTION = 1.0 / 3.0  # chi_r: the share of a pool fire's heat release it radiates
# the kinds' fixed light colours at unit luminance
_KIND_COLOUR = {kind.name: np.array(kind.light_rgb) / float(np.array(kind.light_rgb) @ LUMA)
                for kind in EFFECT_KINDS.values() if kind.light_rgb is not None}


def fire_light(effect: Effect, scene: Scene) -> PointLight | None:
    kind = EFFECT_KINDS[effect.type]
    if not kind.casts_light:
        return None
    volumes = [v for v in effect_volumes(effect, scene) if v.key[1] == "fire"]
    if not volumes:
        return None
    vol = volumes[0]
    flame_height = vol.height / CONTAINER_OVER_FLAME if kind.container == "pool_fire" else vol.height
    area = 0.5 * 2.0 * vol.radius * flame_height
    gain = flicker_gain(puffing_frequency(effect.diameter), kind.flicker, effect.seed,
                        scene.time.sim_time)
    intensity = 0.3 * LUMINANCE * math.sqrt(effect.intensity) * area * vol.opacity * float(gain)
    if kind.light_rgb is None:  # the flame's blackbody, reddening as it cools
        cooling = 0.0 if effect.active else 1.0 - vol.level
        colour = (blackbody_light_rgb(emission_temperature(effect, scene))
                  * np.power(np.array([1.0, 0.75, 0.5]), 3.0 * cooling) * (1.0 - 0.6 * cooling))
    else:
        colour = _KIND_COLOUR[kind.name]
    if intensity <= 0.0:
        return None
    position = vol.base + np.array([0.3 * vol.lean[0], 0.3 * vol.lean[1], 0.3 * flame_height])
    light_range = min(math.sqrt(intensity / MIN_ILLUMINANCE), MAX_RANGE)
    return PointLight(position, colour * intensity, light_range)


def emission_temperature(effect: Effect, scene: Scene) -> float:
    """K, the temperature of a blackbody whose radiation has the luminous efficacy of the burning
    fire's light: 4 pi I / (chi_r Q), with I its mean intensity at full size (no fade, no flicker)."""
    vol = next(v for v in effect_volumes(effect, scene) if v.key[1] == "fire")
    full = vol.nominal_radius / max(vol.radius, 1e-9)  # the fade scales radius and height alike
    height = vol.height * full
    flame = height / CONTAINER_OVER_FLAME if EFFECT_KINDS[effect.type].container == "pool_fire" else height
    intensity = 0.3 * LUMINANCE * math.sqrt(effect.intensity) * vol.nominal_radius * flame
    radiated = RADIATIVE_FRACTION * effect_heat_release(effect) * 1000.0  # W
    return efficacy_temperature(4.0 * math.pi * intensity / max(radiated, 1e-9))


def fire_lights(scene: Scene) -> list[PointLight]:
    lights = []
    for effect in scene.effects:
        light = fire_light(effect, scene)
        if light is not None:
            lights.append(light)
    return lights
