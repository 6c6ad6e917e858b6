"""Gathering the frame's point and spot lights: host lights plus lights that effects contribute.

Flicker (a lantern, burning debris, a fire's glow) is a deterministic function of the light's
seed and sim_time: a sum of sinusoids log-spaced around the peak frequency f with Gaussian
weights in ln f, so the variation's spectrum peaks at f for every seed (a fire's f is the
pool-fire puffing frequency 1.5/sqrt(D), volumes/fire_lights.py). Phases are reduced in float64.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..scene.model import Flicker, Scene
from .camera import CameraView, body_to_world

FLICKER_PARTIALS = 13  # odd: one partial sits at the peak
FLICKER_LOG_SPREAD = 0.6  # partials span f * exp(+-0.6): a band ~1 octave wide around the peak
FLICKER_LOG_WIDTH = 0.25  # Gaussian width (in ln f) of the partials' weights: the spectral peak


@dataclass(frozen=True)
class PointLight:
    position: np.ndarray  # world ENU, float64
    color: np.ndarray  # linear rgb * intensity (cd)
    range: float
    spot_dir: np.ndarray | None = None  # unit, world
    cos_inner: float = 1.0
    cos_outer: float = 1.0


@lru_cache(maxsize=256)  # per light's constants; a seeded generator costs more than the flicker itself
def _partials(frequency: float, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frequencies log-spaced around ``frequency`` (seeded jitter), weights Gaussian in ln f.

    The largest weight is always the partial nearest the peak (within exp(+-0.03)), so the
    spectrum peaks at ``frequency`` for every seed; the neighbours make the signal irregular
    (beats) rather than a pure tone, like a pool fire's puffing.
    """
    rng = np.random.default_rng(seed)
    x = np.linspace(-FLICKER_LOG_SPREAD, FLICKER_LOG_SPREAD, FLICKER_PARTIALS)
    x = x + rng.uniform(-0.03, 0.03, FLICKER_PARTIALS)
    freqs = frequency * np.exp(x)
    phases = rng.uniform(0.0, 2 * math.pi, FLICKER_PARTIALS)
    weights = np.exp(-0.5 * (x / FLICKER_LOG_WIDTH) ** 2) * rng.uniform(0.85, 1.0, FLICKER_PARTIALS)
    weights[FLICKER_PARTIALS // 2] = 1.0  # the peak partial dominates
    out = (freqs, phases, weights / np.sqrt(np.sum(weights**2)))
    for a in out:
        a.flags.writeable = False  # shared by every call with these arguments
    return out


def flicker_gain(frequency: float, amplitude: float, seed: int, sim_time) -> np.ndarray | float:
    """Intensity multiplier >= 0 around 1 with relative RMS variation ~ amplitude / sqrt(2)."""
    freqs, phases, weights = _partials(frequency, seed)
    t = np.asarray(sim_time, dtype=np.float64)
    # float64 phase reduction: fmod(f*t, 1) keeps full precision at t = 1e9 s
    cycles = np.fmod(np.multiply.outer(t, freqs), 1.0)
    signal = np.sum(weights * np.sin(2 * math.pi * cycles + phases), axis=-1)
    gain = np.maximum(1.0 + amplitude * signal, 0.0)
    return float(gain) if gain.ndim == 0 else gain


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


def _fire_lights(scene: Scene) -> list[PointLight]:
    # imported on first use: volumes.fire_lights itself imports this module
    from .volumes.fire_lights import fire_lights

    return fire_lights(scene)


# Functions (scene) -> list[PointLight] that pipelines register (fire flicker lights, ...).
LIGHT_SOURCES = [host_lights, _fire_lights]


def gather_lights(scene: Scene, view: CameraView, max_lights: int) -> list[PointLight]:
    """All lights that can reach the view, brightest-at-the-camera first, at most ``max_lights``."""
    lights = [light for source in LIGHT_SOURCES for light in source(scene)]
    lights = [l for l in lights if float(np.max(l.color)) > 0.0 and view.sphere_visible(l.position, l.range)]

    def importance(light: PointLight) -> float:
        d = float(np.linalg.norm(view.relative(light.position)))
        return float(np.max(light.color)) / max(d * d, 1.0)

    lights.sort(key=importance, reverse=True)
    return lights[:max_lights]


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
