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
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from ...effect_kinds import EFFECT_KINDS
from ...photometry import LUMA
from ...scene.model import Effect, Scene
from ..point_lights import PointLight, flicker_gain
from .effects import CONTAINER_OVER_FLAME, effect_heat_release, effect_volumes, fade_level, puffing_frequency
from .planck import blackbody_light_rgb, efficacy_temperature

LUMINANCE = 2.0e4  # cd/m^2, core luminance at intensity 1 (same as the volume's emission)
MIN_ILLUMINANCE = 0.02  # lux: the range is where the light falls below this
MAX_RANGE = 3000.0  # m

RADIATIVE_FRACTION = 1.0 / 3.0  # chi_r: the share of a pool fire's heat release it radiates
# the kinds' fixed light colours at unit luminance
_KIND_COLOUR = {kind.name: np.array(kind.light_rgb) / float(np.array(kind.light_rgb) @ LUMA)
                for kind in EFFECT_KINDS.values() if kind.light_rgb is not None}


@dataclass(frozen=True)
class Flame:
    """The parts of an effect's light that change only with the effect, its fade level and the wind
    (not while only sim_time runs): the light is ``colour x base_intensity x flicker gain(t)``."""

    base_intensity: float  # cd before the flicker: 0.3 x core luminance x projected flame area x opacity
    colour: np.ndarray  # linear rgb at unit luminance (the kind's, or the flame's blackbody)
    position: np.ndarray  # world ENU, on the axis at 30 % of the flame height
    frequency: float  # Hz, the puffing frequency the flicker peaks at
    flicker: float  # the kind's flicker amplitude


def flame(effect: Effect, scene: Scene) -> Flame | None:
    """``effect``'s Flame (None when it casts no light or has no flame now), recomputed only when
    one of its inputs changes: the effect, its fade level at sim_time, the wind (effect_volumes'
    inputs)."""
    if not EFFECT_KINDS[effect.type].casts_light:
        return None
    w = scene.weather
    key = (effect, fade_level(effect, scene.time.sim_time), w.wind_speed, w.wind_direction)
    return FLAMES.get(effect.id, key, lambda: _flame(effect, scene))


def _flame(effect: Effect, scene: Scene) -> Flame | None:
    kind = EFFECT_KINDS[effect.type]
    volumes = [v for v in effect_volumes(effect, scene) if v.key[1] == "fire"]
    if not volumes:
        return None
    vol = volumes[0]
    flame_height = vol.height / CONTAINER_OVER_FLAME if kind.container == "pool_fire" else vol.height
    area = 0.5 * 2.0 * vol.radius * flame_height
    base = 0.3 * LUMINANCE * math.sqrt(effect.intensity) * area * vol.opacity
    if kind.light_rgb is None:  # the flame's blackbody, reddening as it cools
        cooling = 0.0 if effect.active else 1.0 - vol.level
        colour = (blackbody_light_rgb(emission_temperature(effect, scene))
                  * np.power(np.array([1.0, 0.75, 0.5]), 3.0 * cooling) * (1.0 - 0.6 * cooling))
    else:
        colour = _KIND_COLOUR[kind.name]
    position = vol.base + np.array([0.3 * vol.lean[0], 0.3 * vol.lean[1], 0.3 * flame_height])
    for a in (colour, position):
        a.flags.writeable = False  # kept between frames
    return Flame(base, colour, position, puffing_frequency(effect.diameter), kind.flicker)


def fire_light(effect: Effect, scene: Scene) -> PointLight | None:
    parts = flame(effect, scene)
    if parts is None:
        return None
    return flame_light(parts, effect, scene.time.sim_time)


def flame_light(parts: Flame, effect: Effect, t: float) -> PointLight | None:
    """The light of ``effect``'s flame ``parts`` (``flame(effect, scene)``) at sim time ``t``: its
    flicker applied. The frame's light list and the smoke's glow ask for the same light at the same
    time: the last one per effect is kept with its flame and time."""
    last = _LAST_LIGHT.get(effect.id)
    if last is not None and last[0] is parts and last[1] == t:  # (parts: for this effect, seed included)
        return last[2]
    gain = flicker_gain(parts.frequency, parts.flicker, effect.seed, t)
    intensity = parts.base_intensity * float(gain)
    light = None
    if intensity > 0.0:
        light_range = min(math.sqrt(intensity / MIN_ILLUMINANCE), MAX_RANGE)
        colour = parts.colour * intensity
        colour.flags.writeable = False  # shared by the callers of this frame
        light = PointLight(parts.position, colour, light_range)
    if len(_LAST_LIGHT) >= FLAMES.size and effect.id not in _LAST_LIGHT:
        _LAST_LIGHT.clear()
    _LAST_LIGHT[effect.id] = (parts, t, light)
    return light


class _LastPerId:
    """The last value per effect id with the key it was computed for (an equal key returns it, any
    other recomputes), at most ``size`` ids kept (least recently used dropped): hosts creating and
    removing many effects cannot grow it. ``computed`` counts recomputations (tests)."""

    def __init__(self, size: int = 256):
        self.size = size
        self._held: OrderedDict = OrderedDict()
        self.computed = 0

    def get(self, ident, key, compute):
        held = self._held.get(ident)
        if held is not None and held[0] == key:
            self._held.move_to_end(ident)
            return held[1]
        value = compute()
        self._held[ident] = (key, value)
        self._held.move_to_end(ident)
        while len(self._held) > self.size:
            self._held.popitem(last=False)
        self.computed += 1
        return value


FLAMES = _LastPerId()
_LAST_LIGHT: dict = {}  # effect id -> (its Flame, sim_time, the light then)


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
