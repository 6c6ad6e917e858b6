"""Gathering the frame's point and spot lights: host lights plus lights that effects contribute
(their record and flicker: point_lights.py).
"""

from __future__ import annotations

import math

import numpy as np

from ..scene.model import Flicker, Scene
from .camera import CameraView, body_to_world
from .point_lights import PointLight, flicker_gain
from .volumes.fire_lights import fire_lights


def _flicker(flicker: Flicker, sim_time: float) -> float:
    if not flicker.enabled:
        return 1.0
    return float(flicker_gain(flicker.frequency, flicker.amplitude, flicker.seed, sim_time))


def host_lights(scene: Scene) -> list[PointLight]:
    lights = []
    for light in scene.lights:
        color = np.asarray(light.color) * light.intensity * _flicker(light.flicker, scene.time.sim_time)
        if light.type == "spot":
            axis = body_to_world(light.heading, light.pitch, 0.0)[:, 1]
            lights.append(PointLight(np.asarray(light.position, float), color, light.range, axis,
                                     math.cos(math.radians(light.cone_inner)), math.cos(math.radians(light.cone_outer))))
        else:
            lights.append(PointLight(np.asarray(light.position, float), color, light.range))
    return lights


class FrameLights(list):
    """The frame's point and spot lights, and whether its view has tile light lists (light_tiles.py:
    some screen tile lists fewer of them than the frame has; the shaders' LIGHT_TILES)."""

    tiled = False


# Functions (scene) -> list[PointLight] whose lights the frame gathers: the host's, the fires'.
LIGHT_SOURCES = [host_lights, fire_lights]


def gather_lights(scene: Scene, view: CameraView, max_lights: int) -> list[PointLight]:
    """All lights that can reach the view, brightest-at-the-camera first (importance: the brightest
    channel over the squared distance, at least 1 m^2), at most ``max_lights``. Per light in plain
    floats: a 3-vector's max and length in numpy cost more than the light."""
    ranked = []
    for light in (light for source in LIGHT_SOURCES for light in source(scene)):
        peak = max(light.color.tolist())
        if peak > 0.0 and view.sphere_visible(light.position, light.range):
            rel = view.relative(light.position)
            d = math.sqrt(float(rel @ rel))  # np.linalg.norm's sum and root
            ranked.append((peak / max(d * d, 1.0), light))
    ranked.sort(key=_importance, reverse=True)  # stable: equal lights keep their order
    return [light for _, light in ranked[:max_lights]]


def _importance(item: tuple) -> float:
    return item[0]


def light_uniforms(lights: list[PointLight], view: CameraView, max_lights: int) -> dict:
    pos = np.zeros((max_lights, 4), np.float32)
    col = np.zeros((max_lights, 4), np.float32)
    dirs = np.zeros((max_lights, 4), np.float32)
    cos_inner = np.ones(max_lights, np.float32)
    for i, light in enumerate(lights):
        pos[i, :3], pos[i, 3] = view.relative(light.position), light.range
        col[i, :3] = light.color
        if light.spot_dir is not None:
            col[i, 3] = 1.0
            dirs[i, :3], dirs[i, 3] = light.spot_dir, light.cos_outer
            cos_inner[i] = max(light.cos_inner, light.cos_outer + 1e-4)
    return {
        "u_light_count": len(lights),
        "u_light_pos": pos.tobytes(), "u_light_color": col.tobytes(),
        "u_light_dir": dirs.tobytes(), "u_light_cos_inner": cos_inner.tobytes(),
    }
