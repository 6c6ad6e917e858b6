"""The precipitation particles on the CPU (seed 003, DESIGN §4.5), no GL.

The paper's method: particles fill a cube of side L that travels with the camera; a particle that
leaves the cube re-enters on the opposite face; the cube is repeated (tiled) to fill the visible
volume. Each particle is drawn as a streak from its earlier to its current position.

Motion: particle i starts at p0_i (uniform in the cube) and moves with the air plus its own fall,
    p_i(t) = p0_i + (w + (0, 0, -v_i)) t + f_i(t)
with w the one wind (igserver.weather.wind_vector), v_i its terminal speed from its diameter and
f_i a horizontal flutter (snow: a circle of radius a_i at frequency nu_i; rain: none). Its position
relative to the camera c, wrapped into the cube, is
    q_i = (p_i(t) - c) mod L    in [0, L)^3
and its copies are q_i + L k for integer tiles k. float64 on the CPU: (v t) mod L and the flutter
phase nu t mod 1 are reduced before they are summed, so t = 1e9 s and c = 1e6 m stay exact to
micrometres; the GPU only ever sees q_i in [0, L) and tile offsets of a few tens of metres.

The streak is the particle's own displacement over the exposure T (``streak_time``):
    s_i = p_i(t) - p_i(t - T),
the paper's "previous to current position" with the previous position taken T earlier rather
than one frame earlier: it depends neither on the frame rate nor on how the camera moved, so a
camera at 250 m/s sees the same streaks as a parked one (no smear).

Density: the real number of visible drops (weather.visible_number_density: thousands per m^3 in
heavy rain) is far beyond any budget, so each drawn streak stands for m drops; its opacity carries
m (render/precip/precip.vert.glsl), so the mean coverage - the optical depth of the drops -
is exact for any m and only the graininess changes. m is DROPS_PER_STREAK (the quality knob, so the
drawn count follows the rate) and grows only where the cost cap binds: the drawn streaks (tiles x
particles per tile) never exceed ``max_streaks``.

Level of detail: a tile whose centre is beyond r0 2^l (``lod_distance`` r0) draws only the first
n / 4^l particles of the cube (a prefix of a uniform random set is uniform), each standing for
4^l times more drops. The solid angle of a shell grows like r^2 while its streaks shrink like 1/r,
so this keeps about as many streaks per steradian per shell as near the camera, and cuts the drawn
count ~9x at a 30 m fade against drawing every tile in full.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...scene.model import Scene
from ...weather import (
    FLAKE_OVER_MELTED, VISIBLE_DIAMETER, fall_speed, size_distribution, visible_number_density, wind_vector,
)
from ..camera import CameraView

BLOCK = 4096  # particles per random block: the pool grows in blocks, so a prefix never changes
SNOW_SPEED_SCATTER = (0.75, 1.2)  # per-flake factor on the Locatelli-Hobbs speed (riming, shape)
SNOW_FLUTTER_RADIUS = (0.02, 0.08)  # m, radius of a flake's horizontal flutter circle (a few cm)
SNOW_FLUTTER_HZ = (0.4, 1.2)  # Hz: flutter speeds 0.05-0.6 m/s, below the fall speed


@dataclass(frozen=True)
class PrecipSettings:
    tile_size: float = 4.0  # m, side of the wrapped cube
    drops_per_streak: dict | None = None  # per kind; None = DEFAULT_DROPS_PER_STREAK
    max_streaks: int = 32768  # cost cap: drawn streaks per frame (tiles x particles per tile)
    fade_distance: dict | None = None  # per kind, m; None = DEFAULT_FADE
    lod_distance: float = 8.0  # m, r0: tiles beyond r0 2^l draw 1/4^l of the particles

    def drops(self, kind: str) -> float:
        return (self.drops_per_streak or DEFAULT_DROPS_PER_STREAK)[kind]

    def fade(self, kind: str) -> float:
        return (self.fade_distance or DEFAULT_FADE)[kind]


# Real drops per drawn streak (the knob): chosen with igserver quality weather (quality/precipitation.py):
# the lowest image error within 12 000 streaks at 640x360 in the rain_harbour and snow scenes.
DEFAULT_DROPS_PER_STREAK = {"rain": 64.0, "snow": 128.0}
# Streaks fade out to this distance; beyond, the precipitation is a veil carried by its extinction
# (weather.effective_visibility). A 2 mm drop at 30 m is 1/40 px at 640x360: only the sum shows.
DEFAULT_FADE = {"rain": 30.0, "snow": 40.0}


def _block(kind: str, index: int, tile_size: float) -> dict[str, np.ndarray]:
    rng = np.random.default_rng([0x5EED, 1 if kind == "rain" else 2, index])
    n = BLOCK
    return {
        "p0": rng.uniform(0.0, tile_size, (n, 3)),
        "u_size": rng.uniform(0.0, 1.0, n),  # quantile of the truncated size distribution
        "speed_factor": rng.uniform(*SNOW_SPEED_SCATTER, n) if kind == "snow" else np.ones(n),
        "flutter_radius": rng.uniform(*SNOW_FLUTTER_RADIUS, n) if kind == "snow" else np.zeros(n),
        "flutter_hz": rng.uniform(*SNOW_FLUTTER_HZ, n),
        "flutter_phase": rng.uniform(0.0, 1.0, n),
        "brightness": rng.uniform(0.7, 1.3, n),
    }


class ParticlePool:
    """Per-particle random constants, grown in fixed blocks (deterministic, prefix-stable)."""

    def __init__(self):
        self._pools: dict[tuple, dict[str, np.ndarray]] = {}

    def get(self, kind: str, tile_size: float, n: int) -> dict[str, np.ndarray]:
        key = (kind, tile_size)
        pool = self._pools.get(key)
        have = 0 if pool is None else len(pool["p0"])
        if pool is None or have < n:
            blocks = [_block(kind, i, tile_size) for i in range(have // BLOCK, math.ceil(max(n, 1) / BLOCK))]
            merged = {k: np.concatenate(([pool[k]] if pool else []) + [b[k] for b in blocks]) for k in blocks[0]}
            self._pools[key] = pool = merged
        return {k: v[:n] for k, v in pool.items()}


def diameters(kind: str, rate: float, quantile: np.ndarray) -> np.ndarray:
    """mm: drop diameter (rain) or flake diameter (snow) from the truncated exponential distribution
    between the visible sizes, by inverse CDF of each particle's fixed quantile."""
    _, lam = size_distribution(kind, rate)
    d1, d2 = VISIBLE_DIAMETER[kind]
    # D = d1 - ln(1 - q (1 - e^(-Lambda (d2 - d1)))) / Lambda: relative to d1, so no exp(-Lambda d1)
    # underflows to 0 for drizzle (Lambda -> inf); log1p/expm1 keep it exact for Lambda -> 0 too.
    d = d1 - np.log1p(quantile * np.expm1(-lam * (d2 - d1))) / lam
    return d * FLAKE_OVER_MELTED if kind == "snow" else d


@dataclass
class ParticleFrame:
    """What the GPU draws this frame."""

    positions: np.ndarray  # (n, 3) float64 in [0, L): camera-relative, wrapped
    streaks: np.ndarray  # (n, 3) m, p(t) - p(t - T)
    diameters: np.ndarray  # (n,) m
    brightness: np.ndarray  # (n,)
    tiles: np.ndarray  # (k, 3) m, camera-relative offsets of the visible tiles, sorted by level
    levels: list[tuple[int, int, int, float]]  # (first tile, tile count, particles, drops per streak)
    real_per_tile: float  # visible drops in one cube
    tile_size: float
    fade: float

    @property
    def streak_count(self) -> int:
        return sum(count * n for _, count, n, _ in self.levels)

    @property
    def drops_per_streak(self) -> float:
        """m of the nearest level (the knob, or more where the cap binds)."""
        return self.levels[0][3] if self.levels else 0.0


def visible_tiles(view: CameraView, tile_size: float, fade: float) -> np.ndarray:
    """Camera-relative offsets L k of the tiles [L k, L (k + 1)) that reach within ``fade`` of the
    camera and intersect the frustum (bounding-sphere test)."""
    n = math.ceil(fade / tile_size)
    k = np.arange(-n, n)
    grid = np.stack(np.meshgrid(k, k, k, indexing="ij"), axis=-1).reshape(-1, 3) * tile_size
    half = 0.5 * tile_size
    radius = half * math.sqrt(3.0)
    centres = grid + half
    keep = np.linalg.norm(centres, axis=1) - radius < fade
    # The frustum planes of view_proj (camera-relative), as in CameraView.sphere_visible, vectorised.
    m = view.view_proj
    for plane in (m[3] + m[0], m[3] - m[0], m[3] + m[1], m[3] - m[1], m[3] + m[2], m[3] - m[2]):
        length = float(np.linalg.norm(plane[:3]))
        if length > 0.0:
            keep &= (centres @ plane[:3] + plane[3]) / length >= -radius
    return grid[keep].astype(np.float64)


def tile_levels(tiles: np.ndarray, tile_size: float, lod_distance: float) -> np.ndarray:
    """LOD level per tile: 0 within r0 of the camera, l where the centre is in [r0 2^(l-1), r0 2^l)."""
    d = np.linalg.norm(tiles + 0.5 * tile_size, axis=1)
    return np.maximum(np.ceil(np.log2(np.maximum(d, 1e-9) / lod_distance)), 0).astype(int)


def particle_count(kind: str, rate: float, settings: PrecipSettings) -> int:
    """Particles per near tile before the cost cap: the visible drops in one cube over m."""
    return int(round(visible_number_density(kind, rate) * settings.tile_size**3 / settings.drops(kind)))


def _level_counts(n: int, tiles_per_level: np.ndarray) -> list[int]:
    return [max(1, int(round(n / 4**lvl))) if n > 0 else 0 for lvl in range(len(tiles_per_level))]


def particle_frame(scene: Scene, view: CameraView, settings: PrecipSettings, pool: ParticlePool) -> ParticleFrame:
    p = scene.weather.precipitation
    kind, rate, L = p.type, p.rate, settings.tile_size
    fade = settings.fade(kind)
    tiles = visible_tiles(view, L, fade)
    level = tile_levels(tiles, L, settings.lod_distance)
    order = np.argsort(level, kind="stable")
    tiles, level = tiles[order], level[order]
    per_level = np.bincount(level) if len(level) else np.zeros(0, int)
    n = particle_count(kind, rate, settings)
    counts = _level_counts(n, per_level)
    total = sum(int(t) * c for t, c in zip(per_level, counts))
    while total > settings.max_streaks and n > 1:  # the cost cap: fewer particles, more drops each
        n = max(1, int(n * settings.max_streaks / total * 0.98))
        counts = _level_counts(n, per_level)
        total = sum(int(t) * c for t, c in zip(per_level, counts))
    real = visible_number_density(kind, rate) * L**3
    levels, first = [], 0
    for t_count, count in zip(per_level, counts):
        if t_count and count:
            levels.append((first, int(t_count), count, real / count))
        first += int(t_count)
    c = pool.get(kind, L, n)

    d_mm = diameters(kind, rate, c["u_size"])
    v_fall = fall_speed(kind, d_mm) * c["speed_factor"]
    wind = wind_vector(scene)
    velocity = np.repeat(wind[None, :], n, axis=0)
    velocity[:, 2] -= v_fall
    t = scene.time.sim_time
    T = p.streak_time

    # float64 reductions: each term mod L before the sum, the flutter phase mod 1.
    travel = np.fmod(velocity * t, L)
    camera = np.fmod(view.position, L)
    phase_now = np.fmod(c["flutter_hz"] * t + c["flutter_phase"], 1.0)
    phase_then = phase_now - c["flutter_hz"] * T
    flutter_now = _flutter(c["flutter_radius"], phase_now)
    q = np.mod(c["p0"] + travel + flutter_now - camera, L)
    q = np.where(q >= L, 0.0, q)  # mod can round up to L itself
    streaks = velocity * T + flutter_now - _flutter(c["flutter_radius"], phase_then)
    return ParticleFrame(q, streaks, d_mm * 1e-3, c["brightness"], tiles, levels, real, L, fade)


def _flutter(radius: np.ndarray, phase: np.ndarray) -> np.ndarray:
    a = 2.0 * math.pi * phase
    return np.stack([radius * np.cos(a), radius * np.sin(a), np.zeros_like(radius)], axis=1)


__all__ = ["PrecipSettings", "ParticlePool", "ParticleFrame", "particle_frame", "particle_count",
           "visible_tiles", "tile_levels", "diameters", "DEFAULT_DROPS_PER_STREAK", "DEFAULT_FADE"]
