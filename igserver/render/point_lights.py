"""A point or spot light as the frame gathers it, and seeded flicker: what host lights and the lights of
effects (volumes/fire_lights.py) are made of.

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
