"""The precipitation particles on the CPU (docs/design.md#precipitation), no GL.

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

Level of detail: a tile whose centre lies in [r0 2^(l-1), r0 2^l) from the camera (``lod_distance``
r0; level 0 within r0) belongs to level l, which has its own cube (side L 2^floor(l/2)) and its own
particles at a quarter of the density of level l - 1: each streak of level l stands for 4^l m drops.
The solid angle of a shell grows like r^2 while its streaks shrink like 1/r, so every level shows
about as many streaks per steradian as the first, and the drawn count falls ~9x at a 30 m fade
against tiling the near density everywhere. Larger cubes further out keep more distinct particles
per tile, so far tiles do not line up into rows of a few repeated particles. The tiles form a
hierarchy (a cube of level 2 is 8 cubes of level 1 where it is near enough to be split), so the
levels fill space exactly once: no overlap, no gap.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...scene.model import Scene
from ...weather import (
    FLAKE_OVER_MELTED, VISIBLE_DIAMETER, fall_speed, size_distribution, visible_number_density, wind_vector,
)
from .. import presets
from ..camera import CameraView
from ..memo import Memo

BLOCK = 4096  # particles per random block: the pool grows in blocks, so a prefix never changes
SNOW_SPEED_SCATTER = (0.75, 1.2)  # per-flake factor on the Locatelli-Hobbs speed (riming, shape)
SNOW_FLUTTER_RADIUS = (0.02, 0.08)  # m, radius of a flake's horizontal flutter circle (a few cm)
SNOW_FLUTTER_HZ = (0.4, 1.2)  # Hz: flutter speeds 0.05-0.6 m/s, below the fall speed


@dataclass(frozen=True)
class PrecipSettings:
    """The particle knobs (scalars, so the quality ladder can step one at a time)."""

    tile_size: float = 4.0  # m, side of the wrapped cube
    rain_drops: float = 64.0  # real drops per drawn streak, rain (the quality knob)
    snow_drops: float = 128.0  # real flakes per drawn streak, snow
    max_streaks: int = 32768  # cost cap: drawn streaks per frame (tiles x particles per tile)
    rain_fade: float = 30.0  # m, streaks fade out by here; beyond, the extinction carries the rain
    snow_fade: float = 40.0
    lod_distance: float = 8.0  # m, r0: level l holds tiles r0 2^(l-1) .. r0 2^l away

    def drops(self, kind: str) -> float:
        return self.rain_drops if kind == "rain" else self.snow_drops

    def fade(self, kind: str) -> float:
        return self.rain_fade if kind == "rain" else self.snow_fade


# Quality presets (igserver/render/presets.py). medium: chosen with igserver quality weather - the
# lowest image error within 16 000 streaks at 640x360 in the rain_harbour and snow scenes (rain 64,
# snow 128 drops per streak, 4 m cubes); low and high halve and double the drawn count (error
# ~1/sqrt(count), cost ~count). A 2 mm drop at 30 m is 1/40 px at 640x360: beyond the fade only the
# sum shows, which the visibility's extinction carries.
PRESETS = {
    "low": PrecipSettings(rain_drops=128.0, snow_drops=256.0),
    "medium": PrecipSettings(),
    "high": PrecipSettings(rain_drops=32.0, snow_drops=64.0),
}
presets.register("precip", PRESETS)


def _block(kind: str, level: int, index: int, tile_size: float) -> dict[str, np.ndarray]:
    rng = np.random.default_rng([0x5EED, 1 if kind == "rain" else 2, level, index])
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

    def get(self, kind: str, tile_size: float, n: int, level: int = 0) -> dict[str, np.ndarray]:
        key = (kind, tile_size, level)
        pool = self._pools.get(key)
        have = 0 if pool is None else len(pool["p0"])
        if pool is None or have < n:
            blocks = [_block(kind, level, i, tile_size)
                      for i in range(have // BLOCK, math.ceil(max(n, 1) / BLOCK))]
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


@dataclass(frozen=True)
class Level:
    """One shell of the level of detail, drawn with one instanced draw."""

    index: int
    tile_size: float  # m, L 2^floor(l/2)
    first_tile: int  # into ParticleFrame.tiles
    tile_count: int
    first_particle: int  # into ParticleFrame.positions etc.
    particles: int  # per tile
    drops_per_streak: float  # m 4^l (rounding aside), or more where the cap binds

    @property
    def streaks(self) -> int:
        return self.tile_count * self.particles


@dataclass
class ParticleFrame:
    """What the GPU draws this frame: every level's particles and tiles, concatenated."""

    positions: np.ndarray  # (n, 3) float64, camera-relative, wrapped into [0, L_l) per level
    streaks: np.ndarray  # (n, 3) m, p(t) - p(t - T)
    diameters: np.ndarray  # (n,) m
    brightness: np.ndarray  # (n,)
    tiles: np.ndarray  # (k, 3) m, camera-relative offsets of the visible tiles of every level
    levels: list[Level]
    fade: float

    @property
    def streak_count(self) -> int:
        return sum(level.streaks for level in self.levels)

    @property
    def drops_per_streak(self) -> float:
        """m of the nearest level drawn (the knob, or more where the cap binds)."""
        return self.levels[0].drops_per_streak if self.levels else 0.0

    def level_slice(self, level: Level) -> slice:
        return slice(level.first_particle, level.first_particle + level.particles)


def level_tile_size(tile_size: float, level: int) -> float:
    """Cube side of level l: L 2^floor(l/2). Doubling it every level would give far tiles more
    distinct particles still, but tiles far larger than their level's shell would put the level
    boundaries far from where the density should change."""
    return tile_size * 2.0 ** (level // 2)


def level_count(lod_distance: float, fade: float) -> int:
    """Levels out to the fade: level l reaches r0 2^l."""
    return max(1, math.ceil(math.log2(max(fade / lod_distance, 1.0))) + 1)


def level_tiles(view: CameraView, tile_size: float, lod_distance: float, fade: float) -> list[np.ndarray]:
    """Camera-relative offsets of the visible tiles of every level (index = level).

    Start from cubes of the largest level's size over the fade sphere; a cube whose centre's level
    wants smaller cubes is split into 8, recursively; the others are emitted at their size, so the
    tiles of all levels partition space. Kept: cubes that reach within ``fade`` of the camera and
    meet the frustum (bounding-sphere tests)."""
    levels = level_count(lod_distance, fade)
    sizes = [level_tile_size(tile_size, lvl) for lvl in range(levels)]
    planes = []
    m = view.view_proj
    for plane in (m[3] + m[0], m[3] - m[0], m[3] + m[1], m[3] - m[1], m[3] + m[2], m[3] - m[2]):
        length = float(np.linalg.norm(plane[:3]))
        if length > 0.0:  # the frustum planes of view_proj, as in CameraView.sphere_visible, vectorised
            planes.append(plane / length)
    size = sizes[-1]
    n = math.ceil(fade / size)
    k = np.arange(-n, n)
    cells = np.stack(np.meshgrid(k, k, k, indexing="ij"), axis=-1).reshape(-1, 3) * size
    out: list[list[np.ndarray]] = [[] for _ in range(levels)]
    children = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=np.float64)
    while len(cells):
        centres = cells + 0.5 * size
        radius = 0.5 * size * math.sqrt(3.0)
        distance = np.linalg.norm(centres, axis=1)
        keep = distance - radius < fade
        for plane in planes:
            keep &= centres @ plane[:3] + plane[3] >= -radius
        cells, distance = cells[keep], distance[keep]
        level = np.minimum(np.ceil(np.log2(np.maximum(distance, 1e-9) / lod_distance)), levels - 1)
        level = np.maximum(level, 0).astype(int)
        wanted = np.array(sizes)[level]
        same = [lvl for lvl in range(levels) if sizes[lvl] == size]
        emit = wanted >= size
        for cell, lvl in zip(cells[emit], np.clip(level[emit], same[0], same[-1])):
            out[lvl].append(cell)
        half = 0.5 * size
        cells = (cells[~emit][:, None, :] + children[None] * half).reshape(-1, 3)
        size = half
    return [np.array(t, dtype=np.float64).reshape(-1, 3) for t in out]


def particle_count(kind: str, rate: float, settings: PrecipSettings) -> int:
    """Particles per tile of the nearest level before the cost cap: the visible drops in one cube
    over m."""
    return int(round(visible_number_density(kind, rate) * settings.tile_size**3 / settings.drops(kind)))


def _level_counts(n0: float, sizes: list[float]) -> list[int]:
    """Particles per tile of level l: a quarter of the density per level in cubes of side L_l."""
    return [int(round(n0 * (size / sizes[0]) ** 3 / 4.0**lvl)) for lvl, size in enumerate(sizes)]


TILES = Memo()  # the last view's tiles and particle layout (each keyed on every one of its inputs)
MAX_LEVELS = 16  # levels of detail the GPU's level table holds (precip_common.glsl)


def _read_only(arrays: list[np.ndarray]) -> list[np.ndarray]:
    for a in arrays:
        a.flags.writeable = False
    return arrays


@dataclass
class ParticleLayout:
    """What a frame's particles are made of apart from the time and the camera's position, made
    once per change of its inputs (particle_layout): the visible tiles of every level, the levels,
    the particles' constants of every level one after the other (a row per particle, its level's
    cube side in ``size``: one numpy operation moves every level), and the GPU's (particle, 8)
    float32 rows with the constant columns filled (``pack`` fills the rest)."""

    tiles: np.ndarray  # (k, 3) m, camera-relative offsets of the visible tiles of every level
    levels: list[Level]
    fade: float
    size: np.ndarray  # (n, 1) m, the cube side of each particle's level
    p0: np.ndarray  # (n, 3) m, start positions in the cube
    velocity: np.ndarray  # (n, 3) m/s, the air's plus the particle's fall
    d_mm: np.ndarray  # (n,) mm
    brightness: np.ndarray  # (n,)
    flutter: tuple | None  # snow: (radius m, hz, phase) arrays; rain: None (radius 0: no flutter terms)
    streak_time: float  # s, T
    rows: np.ndarray  # (n, 8) float32: position xyz, diameter m, streak xyz, brightness

    def __post_init__(self):
        self.streaks = self.velocity * self.streak_time  # m, the streak without flutter (rain's whole streak)
        _read_only([self.streaks])

    def motion(self, t: float, camera_position: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Every particle's wrapped camera-relative position in [0, size)^3 and streak at ``t``."""
        size = self.size
        # float64 reductions: each term mod the cube before the sum, the flutter phase mod 1.
        q = np.fmod(self.velocity * t, size)  # the travel
        camera = np.fmod(camera_position, size)
        q += self.p0
        if self.flutter is None:
            streaks = self.streaks
        else:
            # A flake's horizontal circle of radius a at hz: (a cos 2 pi phase, a sin 2 pi phase, 0),
            # now and T earlier (the phase reduced mod 1 first), in one pass for both times.
            radius, hz, phase0 = self.flutter
            phase_now = np.fmod(hz * t + phase0, 1.0)
            angle = 2.0 * math.pi * np.stack([phase_now, phase_now - hz * self.streak_time])
            x, y = radius * np.cos(angle), radius * np.sin(angle)
            q[:, 0] += x[0]
            q[:, 1] += y[0]
            streaks = self.streaks.copy()
            streaks[:, 0] += x[0]
            streaks[:, 0] -= x[1]
            streaks[:, 1] += y[0]
            streaks[:, 1] -= y[1]
        q -= camera
        q = np.mod(q, size, out=q)
        q[q >= size] = 0.0  # mod can round up to the size itself
        return q, streaks

    def pack(self, t: float, camera_position: np.ndarray) -> np.ndarray:
        """The rows at time ``t`` (float32; reused: valid until the next call)."""
        q, streaks = self.motion(t, camera_position)
        self.rows[:, 0:3] = q
        if self.flutter is not None:
            self.rows[:, 4:7] = streaks
        return self.rows


def particle_layout(scene: Scene, view: CameraView, settings: PrecipSettings, pool: ParticlePool) -> ParticleLayout:
    """The frame's ParticleLayout, made again only when an input changes: the precipitation's type,
    rate and streak time, the knobs, the wind, and the view's orientation and frustum (the tiles are
    camera-relative: a camera that moves without turning keeps them)."""
    p, w = scene.weather.precipitation, scene.weather
    key = (p.type, p.rate, p.streak_time, settings, w.wind_speed, w.wind_direction, view.view_proj.tobytes())
    return TILES.get("particle_layout", key, lambda: _layout(scene, view, settings, pool))


def _layout(scene: Scene, view: CameraView, settings: PrecipSettings, pool: ParticlePool) -> ParticleLayout:
    p = scene.weather.precipitation
    kind, rate, L = p.type, p.rate, settings.tile_size
    fade = settings.fade(kind)
    rho = visible_number_density(kind, rate)  # drops per m^3
    # The tiles are camera-relative: they follow the view's orientation and frustum, not its position.
    tiles = TILES.get("level_tiles", (view.view_proj.tobytes(), L, settings.lod_distance, fade),
                      lambda: _read_only(level_tiles(view, L, settings.lod_distance, fade)))
    sizes = [level_tile_size(L, lvl) for lvl in range(len(tiles))]
    n0 = float(particle_count(kind, rate, settings))
    counts = _level_counts(n0, sizes)
    total = sum(len(t) * c for t, c in zip(tiles, counts))
    while total > settings.max_streaks and n0 > 0.0:  # the cost cap: fewer particles, more drops each
        n0 *= settings.max_streaks / total * 0.98
        counts = _level_counts(n0, sizes)
        total = sum(len(t) * c for t, c in zip(tiles, counts))

    levels: list[Level] = []
    parts: list[dict] = []
    tile_arrays: list[np.ndarray] = []
    first_tile = first_particle = 0
    for lvl, (size, tile_list, n) in enumerate(zip(sizes, tiles, counts)):
        if n == 0 or len(tile_list) == 0:
            continue
        parts.append({**pool.get(kind, size, n, lvl), "size": np.full((n, 1), size)})
        levels.append(Level(lvl, size, first_tile, len(tile_list), first_particle, n, rho * size**3 / n))
        tile_arrays.append(tile_list)
        first_tile += len(tile_list)
        first_particle += n
    if len(levels) > MAX_LEVELS:
        raise ValueError(f"{len(levels)} precipitation levels of detail, at most {MAX_LEVELS} (lod_distance, fade)")
    c = {k: np.concatenate([part[k] for part in parts]) if parts else np.zeros((0, 3) if k in ("p0", "size") else 0)
         for k in ("p0", "u_size", "speed_factor", "flutter_radius", "flutter_hz", "flutter_phase", "brightness", "size")}
    d_mm = diameters(kind, rate, c["u_size"])
    v_fall = fall_speed(kind, d_mm) * c["speed_factor"]
    velocity = np.repeat(wind_vector(scene)[None, :], len(d_mm), axis=0)
    velocity[:, 2] -= v_fall
    # Rain does not flutter (radius 0): its flutter terms are exact zeros and are left out.
    flutter = (c["flutter_radius"], c["flutter_hz"], c["flutter_phase"]) if np.any(c["flutter_radius"]) else None
    rows = np.zeros((first_particle, 8), np.float32)
    rows[:, 3] = d_mm * 1e-3
    rows[:, 4:7] = velocity * p.streak_time
    rows[:, 7] = c["brightness"]
    all_tiles = np.concatenate(tile_arrays) if tile_arrays else np.zeros((0, 3))
    arrays = _read_only([all_tiles, c["size"], c["p0"], velocity, d_mm, c["brightness"]])
    return ParticleLayout(arrays[0], levels, fade, *arrays[1:], flutter, p.streak_time, rows)


def particle_frame(scene: Scene, view: CameraView, settings: PrecipSettings, pool: ParticlePool) -> ParticleFrame:
    layout = particle_layout(scene, view, settings, pool)
    q, streaks = layout.motion(scene.time.sim_time, view.position)
    return ParticleFrame(q, streaks, layout.d_mm * 1e-3, layout.brightness, layout.tiles, layout.levels, layout.fade)


__all__ = ["PrecipSettings", "ParticlePool", "ParticleFrame", "ParticleLayout", "Level", "particle_frame",
           "particle_layout", "particle_count",
           "level_tiles", "level_tile_size", "level_count", "diameters", "PRESETS"]
