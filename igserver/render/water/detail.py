"""The sea's detail normal maps: the short waves of the detail band on three tiles of growing size,
as slope maps with their mip chains made on the GL for the frame's time (detail_synth.py), and what
each LOD block must read of them (the finer tiles are minified to their mean far enough away)."""

from __future__ import annotations

import functools
import math

import numpy as np

from ...water.spectrum import SPREADING_S, WaveSet
from ...water.surface import SeaSurface
from ..camera import CameraView
from . import lod
from .detail_synth import SynthTables, lattice_key, synth_tables, tile_pairs
from .foam import FOAM_FADE_CELL, FOAM_STREAK_FADE

DETAIL_MAPS = 3
# The detail band is split by wavelength into DETAIL_MAPS maps, each covering a ratio DETAIL_RATIO of
# wavelengths on a tile DETAIL_MIN_CYCLES times its longest wave: a wave snapped to the tile's lattice
# of (m, n) cycles (rounding moves it by ≤ √0.5 cycle) keeps its direction within asin(0.71 / 5) ≈ 8°
# and its wavelength within 14 % (a wave of 1–2 cycles snaps to 0°, 45° or 90°, and the map shows a
# square lattice), and the shortest spans 38.5 cycles, 3.3 texels each at the medium 128² maps. Not a
# whole ratio: the tiles never repeat in step. Waves shorter than the finest map's band go to the
# roughness (``detail_unresolved_var``).
DETAIL_MIN_CYCLES = 5.0
DETAIL_RATIO = 7.7
DETAIL_MIN_WAVES = 4
# Each map's tile is filled with every lattice wave of its band (a continuous spectrum sampled on the
# tile's lattice), not only with the detail waves snapped to it: a tile of a dozen waves shows their few
# directions as a diamond lattice wherever the map is resolved (the near water seen level from 2 m at
# 1280x720, its spectral peak 4.5x the frame's mean power). The map keeps its waves' slope variance,
# spread over the lattice points (m, n) of its band (DETAIL_MIN_CYCLES up to DETAIL_MIN_CYCLES x
# DETAIL_RATIO cycles a tile) as the short waves' saturation range spreads it, equal slope variance per
# ln k (Phillips 1985; a weight 1 / |(m, n)|² per point), and over directions by the wind sea's
# spreading cos^2s(Δθ / 2) (spectrum.py SPREADING_S), each point with a random phase (fixed per sea).
# Points weighted below DETAIL_FILL_FLOOR of the strongest are left out: the short waves far off the
# wind (~1,000 points a map remain; at 1e-3, 1,700 points cost 0.3 ms more a frame for no visible
# change; at 3e-2, 430 points drew the lattice again). False: the snapped detail waves only.
DETAIL_LATTICE_FILL = True
DETAIL_FILL_FLOOR = 1e-2


def _detail_bands(sea: SeaSurface) -> tuple[np.ndarray, np.ndarray]:
    """Per detail map, the longest wavelength of its band (m); per detail wave, its map (DETAIL_MAPS:
    roughness only). The finest bands holding fewer than DETAIL_MIN_WAVES waves go to the roughness:
    a tile of so few waves shows its period as a regular ripple, and costs a texture read per pixel
    for under 4/36 of the detail band's slope variance (its waves carry equal shares)."""
    return _bands(sea.detail.k)


def _bands(k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    wavelengths = 2.0 * math.pi / k
    tops = float(np.max(wavelengths)) * 1.0001 / DETAIL_RATIO ** np.arange(DETAIL_MAPS)
    band = np.minimum(np.floor(np.log(tops[0] / wavelengths) / math.log(DETAIL_RATIO)), DETAIL_MAPS).astype(int)
    for c in range(DETAIL_MAPS - 1, 0, -1):
        few = band == c
        if np.count_nonzero(few) >= DETAIL_MIN_WAVES:
            break
        band[few] = DETAIL_MAPS
    return tops, band


def detail_tiles(sea: SeaSurface, t: float) -> list[tuple[float, np.ndarray]]:
    """Per detail map: (tile side L in m, waves (m, n, A k, phase) snapped to that tile's lattice)."""
    d: WaveSet = sea.detail
    if d.n == 0:
        return [(1.0, np.zeros((0, 4)))] * DETAIL_MAPS
    tiles = []
    for size, fixed, omega, phase in _lattice_of(sea).tiles:
        waves = np.empty((len(fixed), 4))
        waves[:, 0:3] = fixed
        turned = np.mod(omega * t, 2.0 * math.pi)
        np.mod(np.subtract(phase, turned, out=turned), 2.0 * math.pi, out=waves[:, 3])
        tiles.append((size, waves))
    return tiles


def detail_fixed_tiles(sea: SeaSurface) -> list[tuple[float, np.ndarray]]:
    """Per detail map: (tile side L in m, waves (m, n, A k)): ``detail_tiles`` without the phases, which
    the GL computes for the frame's time (detail_synth.py). What the draw plan and the maps' sizes read;
    the same objects for every t of a sea state."""
    if sea.detail.n == 0:
        return [(1.0, np.zeros((0, 3)))] * DETAIL_MAPS
    return _lattice_of(sea).fixed_tiles


def detail_means_at(sea: SeaSurface, t: float) -> np.ndarray:
    """``detail_means`` of ``detail_tiles(sea, t)``, a map whose average does not follow t held."""
    if sea.detail.n == 0:
        return np.zeros((DETAIL_MAPS, 4))
    return _lattice_of(sea).means(t)


def _lattice_of(sea: SeaSurface) -> "DetailLattice":
    return detail_lattice(*_wave_key(sea.detail), sea.spectrum.azimuth_to, DETAIL_LATTICE_FILL)


def _wave_key(d: WaveSet) -> tuple[bytes, ...]:
    """The detail waves' (k, direction, amplitude, phase) as float64 bytes: ``detail_lattice``'s key."""
    return tuple(np.ascontiguousarray(a, dtype=np.float64).tobytes() for a in (d.k, d.direction, d.amplitude, d.phase))


class DetailLattice:
    """What the detail maps take from the detail waves, whatever the time: per map, the tile side L,
    the waves' (m, n, A k) on its lattice, their ω and phases at t = 0; and the mean-square slope of
    the waves shorter than every map's band."""

    def __init__(self, k: np.ndarray, direction: np.ndarray, amplitude: np.ndarray, phase: np.ndarray,
                 azimuth_to: float = 0.0, fill: bool = False):
        tops, band = _bands(k)
        self.tiles = []
        rng = np.random.default_rng(int(np.sum(phase) * 1e6) % 2**32)  # the fill's phases: fixed per sea
        for c, top in enumerate(tops):
            size = DETAIL_MIN_CYCLES * top
            pick = band == c
            cycles = np.rint(k[pick, None] * direction[pick] * size / (2.0 * math.pi))
            k_snap = np.linalg.norm(cycles, axis=1) * 2.0 * math.pi / size
            slope = amplitude[pick] * k_snap
            if fill and len(slope):
                cycles, slope = _lattice_fill(float(np.sum(slope**2) / 2.0), azimuth_to)
                k_snap = np.linalg.norm(cycles, axis=1) * 2.0 * math.pi / size
                wave_phase = rng.uniform(0.0, 2.0 * math.pi, len(slope))
            else:
                wave_phase = phase[pick]
            omega = np.sqrt(9.80665 * k_snap)
            self.tiles.append((size, np.column_stack([cycles, slope]), omega, wave_phase))
        lost = band >= DETAIL_MAPS
        self.unresolved_var = float(np.sum((amplitude[lost] * k[lost]) ** 2) / 2.0)
        self.fixed_tiles = [(size, fixed) for size, fixed, _, _ in self.tiles]
        self._pairs = [tile_pairs(lattice_key(fixed)) if len(fixed) else None for _, fixed, _, _ in self.tiles]
        self._still_means = dict.fromkeys(still_means(self.tiles, self._pairs))  # each computed at the first t asked

    def means(self, t: float) -> np.ndarray:
        """Per map, its average over the tile (sx, sy, sx², sy²) at time ``t`` (``detail_means``)."""
        means = np.zeros((DETAIL_MAPS, 4))
        for c, ((_, fixed, omega, phase), pairs) in enumerate(zip(self.tiles, self._pairs)):
            if pairs is None:
                continue
            held = self._still_means.get(c)
            if held is None:
                turned = np.mod(omega * t, 2.0 * math.pi)
                held = pairs.mean_square(np.mod(phase - turned, 2.0 * math.pi))
                if c in self._still_means:
                    self._still_means[c] = held
            means[c, 2:] = held
        return means


def still_means(tiles, pairs) -> list[int]:
    """The maps whose average is the same at every t: it follows t only through its pairs' weights
    (detail_synth.TilePairs.turning)."""
    return [c for c, ((_, _, omega, _), p) in enumerate(zip(tiles, pairs)) if p is not None and not np.any(p.turning(omega))]


def _lattice_fill(variance: float, azimuth_to: float) -> tuple[np.ndarray, np.ndarray]:
    """Every lattice point (m, n) of a map's band (DETAIL_LATTICE_FILL) and its slope amplitude A k,
    their mean-square slope Σ (A k)² / 2 = ``variance``; waves travel toward ``azimuth_to`` (deg) ±
    the wind sea's spreading."""
    r_lo, r_hi = DETAIL_MIN_CYCLES, DETAIL_MIN_CYCLES * DETAIL_RATIO
    side = np.arange(-math.ceil(r_hi), math.ceil(r_hi) + 1, dtype=np.float64)
    m, n = (a.ravel() for a in np.meshgrid(side, side, indexing="ij"))
    r = np.hypot(m, n)
    ring = (r >= r_lo) & (r < r_hi)
    m, n, r = m[ring], n[ring], r[ring]
    az = math.radians(azimuth_to)
    cos_off = (m * math.sin(az) + n * math.cos(az)) / r  # cos of the angle to the mean direction (ENU)
    weight = (0.5 * (1.0 + cos_off)) ** SPREADING_S / (r * r)  # cos^2s(Δθ / 2) per unit ln k
    keep = weight >= DETAIL_FILL_FLOOR * weight.max()
    weight = weight[keep]
    return np.column_stack([m[keep], n[keep]]), np.sqrt(2.0 * variance * weight / weight.sum())


@functools.lru_cache(maxsize=4)
def detail_lattice(k: bytes, direction: bytes, amplitude: bytes, phase: bytes, azimuth_to: float = 0.0,
                   fill: bool = False) -> DetailLattice:
    """The ``DetailLattice`` of the detail waves given as bytes (``_wave_key``), the wind sea's
    direction and the fill rule: the key is the whole input, so another sea state builds its own."""
    return DetailLattice(np.frombuffer(k), np.frombuffer(direction).reshape(-1, 2), np.frombuffer(amplitude),
                         np.frombuffer(phase), azimuth_to, fill)


def detail_synth_tables(sea: SeaSurface, resolution: int) -> SynthTables:
    """The tables from which the GL makes the detail maps' levels at ``resolution`` texels a side for any
    time (detail_synth.py), once per sea state and resolution.

    A map's level 0 (N² texels, N a power of two) holds at the texel (i, j) the slopes at its centre
    u = (i + ½) / N, v = (j + ½) / N of the tile's waves (m, n, A k, phase) (``detail_tiles``): s = Σ g
    cos θ, g = A k (m, n) / |(m, n)| the slope amplitude, θ = 2π (m u + n v) + phase = 2π (m i + n j) /
    N + ψ, ψ = phase + π (m + n) / N. Both components at once as sx + i sy = Σ (gx + i gy) (e^{iθ} +
    e^{−iθ}) / 2: an inverse DFT of N² coefficients (gx + i gy) e^{±iψ} / 2 placed at the bins ±(m, n)
    mod N — exact at the texel centres, in O(N² log N) whatever the wave count. Every level, level 0
    included, carries only the waves below half its Nyquist frequency, the others' slope variance in its
    (sx², sy²) (detail_mips.py: nothing folds onto a longer wave), so E[s²] − E[s]² of a level is the
    slope variance it no longer resolves (LEAN mapping). Texels (sx, sy, sx², sy²) in float32, rows
    along the tile's y."""
    return synth_tables(_lattice_of(sea), int(resolution))


def detail_unresolved_var(sea: SeaSurface) -> float:
    """Mean-square slope of the detail waves shorter than every map's band: roughness only."""
    d = sea.detail
    return _lattice_of(sea).unresolved_var if d.n else 0.0


def detail_means(tiles: list[tuple[float, np.ndarray]]) -> np.ndarray:
    """Per detail map, its average over the tile (sx, sy, sx², sy²): what the map's 1×1 mip level holds
    (float64 here; the map's is the float32 mean of its texels, within its rounding). Over the texel
    grid a lattice wave averages to zero, and a product of two averages to half the cosine of their
    phase difference when they share a lattice point (or of the phase sum for opposite points)."""
    means = np.zeros((DETAIL_MAPS, 4))
    for c, (_, waves) in enumerate(tiles):
        if not len(waves):
            continue
        means[c, 2:] = tile_pairs(lattice_key(waves)).mean_square(waves[:, 3])  # detail_synth.py
    return means


@functools.lru_cache(maxsize=16)
def _min_pixel_angle(tangents: tuple[float, float, float, float], w: int, h: int) -> float:
    left, right, bottom, top = tangents

    def ray(x: float, y: float) -> tuple[float, float, float]:
        r = (left + (x + 0.5) / w * (right - left), bottom + (y + 0.5) / h * (top - bottom), 1.0)
        n = math.sqrt(r[0] * r[0] + r[1] * r[1] + 1.0)
        return r[0] / n, r[1] / n, 1.0 / n

    def angle(a, b) -> float:
        c = (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])
        return math.atan2(math.sqrt(c[0] ** 2 + c[1] ** 2 + c[2] ** 2), a[0] * b[0] + a[1] * b[1] + a[2] * b[2])

    angles = []
    for x, dx in ((0, 1), (w - 1, -1)):
        for y, dy in ((0, 1), (h - 1, -1)):
            a = ray(x, y)
            angles += [angle(a, ray(x + dx, y)), angle(a, ray(x, y + dy))]
    return min(angles)


@functools.lru_cache(maxsize=16)
def _min_pixel_angle_any(tangents: tuple[float, float, float, float], w: int, h: int) -> float:
    left, right, bottom, top = tangents
    # A step of one pixel in any direction on the image plane turns the ray by at least the step in
    # tangent times 1 / (1 + t^2), t the tangent's length: the radial direction at the corner farthest
    # from the axis is the least. 0.99: the finite step against this derivative.
    t2 = max(abs(left), abs(right)) ** 2 + max(abs(bottom), abs(top)) ** 2
    return 0.99 * min((right - left) / w, (top - bottom) / h) / (1.0 + t2)


def min_pixel_angle(view: CameraView) -> float:
    """The smallest angle (rad) between the rays of two neighbouring pixels anywhere on the screen
    (at the frame's corners, where a pixel subtends the least)."""
    return _min_pixel_angle(tuple(float(t) for t in view.tangents), int(view.width), int(view.height))


def minified_maps_from(selection: lod.LodSelection, sea: SeaSurface, tiles, view: CameraView,
                       cam_height: float) -> np.ndarray:
    """Per block, how many detail maps (a prefix: the finer tiles come later) the shader must read;
    every later map is minified there to its tile average (``detail_means``) within a small residual,
    so it is replaced by that constant (a texture read a pixel fewer where it holds).

    Minified: the texel footprint ρ (texels per pixel, the larger of the two screen axes) is at least
    N/2, so the sampler reads the 2×2 level or coarser: a box of half a tile averages each of the
    tile's waves (≥ DETAIL_MIN_CYCLES = 5 cycles a tile) to at most 2/(5π) = 13 % of its slope, the
    variance channels keep the whole tile's (the roughness is the same). Measured against every map
    read (sea_beaufort5 at 2 m, 30 m, 1 km, 640x360): max 1 level, mean 0.0015 (the bound below is
    pessimistic: at a quarter tile it is still max 1, mean 0.003); at 2N (the exact 1×1 level, the
    rule before the tiles grew to 5 cycles) the blocks reading both maps from 1 km were 151 of 370,
    now 40. For a point of the block at distance ≥ d, two neighbouring
    pixels' rays (angle ≥ δ, ``min_pixel_angle``) meet the surface ≥ d·sin δ apart; a mesh of slope
    ≤ s moves that apart ≥ 1/√(1+s²) of it horizontally, the rest point (the maps' coordinate) moves
    ≥ 1/(1+s) of that (the Gerstner horizontal displacement's gradient is ≤ Σ b k ≤ s), and
    llvmpipe's ρ (largest derivative component) is ≥ 1/√2 of the length: ρ ≥ N/L · d sin δ /
    (√2 √(1+s²) (1+s)); d from the block's square, less the error sphere ΣA horizontally and
    vertically. s per block: the slope of the waves its level's spacing keeps (fades, gerstner.glsl)
    plus the earth's tilt at the reach. Only in uniform depth (over a field k, A and Q vary per
    point; every map is read there)."""
    n_blocks = len(selection.nodes)
    used = sum(1 for _, waves in tiles if len(waves))
    if sea.field is not None or n_blocks == 0:
        return np.full(n_blocks, used, dtype=int)
    footprint = rest_spacing(selection, sea, cam_height, min_pixel_angle(view)) / math.sqrt(2.0)
    count = np.zeros(n_blocks, dtype=int)
    for c, (size, waves) in enumerate(tiles):
        if len(waves):
            count = np.where(footprint / size < 0.5, c + 1, count)  # ρ/N = footprint / L < 1/2: still read
    return count


def rest_spacing(selection: lod.LodSelection, sea: SeaSurface, cam_height: float, pixel_angle: float) -> np.ndarray:
    """Per block, a lower bound (m) on the distance between the rest points (the detail maps' and the
    foam's coordinates) of two rays ``pixel_angle`` apart (``minified_maps_from`` has the argument;
    uniform depth only)."""
    nodes = selection.nodes.astype(np.float64)
    w = sea.waves
    level = nodes[:, 3].astype(int)
    spacing = selection.finest_spacing * 2.0 ** np.arange(int(level.max()) + 1)
    x = w.k[None] * spacing[:, None]
    fade = 1.0 - np.clip((x - 0.5 * math.pi) / (0.5 * math.pi), 0.0, 1.0) ** 2 * (
        3.0 - 2.0 * np.clip((x - 0.5 * math.pi) / (0.5 * math.pi), 0.0, 1.0))  # 1 − smoothstep(π/2, π, kΔ)
    slope = (np.sum(w.amplitude * w.k * fade, axis=1) + selection.reach / lod.EARTH_RADIUS)[level]
    sphere = selection.error_sphere
    gap = np.maximum(np.maximum(nodes[:, :2], -(nodes[:, :2] + nodes[:, 2:3])), 0.0)  # camera at (0, 0)
    d = np.hypot(np.maximum(np.hypot(gap[:, 0], gap[:, 1]) - sphere, 0.0), max(abs(cam_height) - sphere, 0.0))
    return d * math.sin(pixel_angle) / (np.sqrt(1.0 + slope**2) * (1.0 + slope))


def foam_streaks_needed(selection: lod.LodSelection, sea: SeaSurface, view: CameraView,
                        cam_height: float) -> np.ndarray:
    """Per block, whether the foam's streak noise can show there (water.frag.glsl foam_cover): the
    shader fades the streaks to their mean where a pixel spans FOAM_STREAK_FADE of a noise cell,
    contrast = clamp(1.5 - 2 |fwidth(q)|, 0, 1) with q the rest point in cells (each lookup's: foam.py
    FOAM_FADE_CELL, the largest least side c). |fwidth(q)| >= its part along that side, >= sigma_min / c, sigma_min
    the least stretch of the pixel -> rest-point map in any direction, which ``rest_spacing`` bounds
    with the least angle a one-pixel step in any direction turns a ray (``_min_pixel_angle_any``).
    Where that bound reaches 0.75 cells the contrast is exactly 0: the block is drawn without the
    noise's fetch (the frame is the same). Over a bathymetry field every block keeps it."""
    if sea.field is not None or len(selection.nodes) == 0:
        return np.ones(len(selection.nodes), dtype=bool)
    angle = _min_pixel_angle_any(tuple(float(t) for t in view.tangents), int(view.width), int(view.height))
    return rest_spacing(selection, sea, cam_height, angle) < FOAM_STREAK_FADE * FOAM_FADE_CELL
