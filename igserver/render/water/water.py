"""Water pass (docs/design.md#water): the wind-driven Gerstner sea on a CDLOD mesh, shaded with the sky.

CPU side per frame: the wave set and its bathymetry field come from igserver.water (cached per
state: integrated once per bathymetry + wave set); phases are reduced in float64 (sim_time 1e9 s is
as good as 100 s); the LOD selection picks the blocks (lod.py); the detail normal maps are rendered
for the frame's time (three tiles, summed in the water shader).

Hulls keep the sea out: every entity's hull boxes (one per connected piece of the glTF nodes named
``*hull*``, ``*pile*`` or ``*float*``, or the whole built-in box) are passed as inverse box matrices and the
water fragment shader discards fragments inside them — a few multiply-adds per hull and fragment, 32 hulls
at most, no extra pass or buffer; only the blocks near a hull are drawn with that test (the others with
the program without it: a discard also turns off early depth tests). A box is conservative for a
tapered bow (a little sea is cut beside it, none is drawn inside).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import moderngl
import numpy as np

from ...scene.model import Scene
from ...water import sea_surface
from ...water.spectrum import WaveSet
from ...water.surface import SeaSurface, whitecap_coverage
from ..bindings import FRAME_UNITS, PASS_UNITS, use_texture, write_buffer
from ..memo import Memo
from ..camera import CameraView, body_to_world
from ..frame import local_light_defines
from .. import presets
from ..passes import RenderPass
from ..shaders import assemble, set_uniforms
from . import lod

MAX_WAVES = 64
MAX_HULLS = 32  # a pier's piles count one each
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
# Texture units bound for the water draw (the frame keeps 8..15: haze table, sky-view table, 4D tables).
DETAIL_UNIT0 = PASS_UNITS["SEA_DETAIL0"]  # and the next two
FIELD_UNIT = PASS_UNITS["SEA_FIELD"]
FIELD_SCALAR_UNIT = PASS_UNITS["SEA_FIELD_SCALAR"]
SKY_REFLECT_UNIT = PASS_UNITS["SEA_SKY_REFLECT"]
AIR_T_UNIT = PASS_UNITS["SEA_AIR_T"]
AIR_S_UNIT = PASS_UNITS["SEA_AIR_S"]
SKY_REFLECT_SIZE = (128, 128)  # the upper hemisphere on a disk (sea_tables.glsl): 0.45 deg per texel at the horizon
AIR_SIZE = (64, 96)  # azimuth x log distance: 5.6 deg, ~10 % distance steps past AIR_D0
AIR_D0 = 10.0  # m


@dataclass(frozen=True)
class WaterKnobs:
    """Per quality level, relative to the scene's own ``ocean`` settings (medium = exactly those, so a
    scene or the quality study that sets them gets what it set). The wave count is NOT a knob: it
    defines the sea itself, which the host's height queries (hulls placed on it) must describe
    whatever the picture quality."""

    detail_scale: float  # × ocean.detail_resolution (texels per side of each detail map)
    lod_error_scale: float  # × ocean.lod_error (px)
    mesh: str = "default"  # the LOD ring rule (lod.MESHES): "coarse" draws 2.25× fewer vertices


# From `igserver quality water`: the detail-map resolution costs its re-rendering each frame and moves
# the picture by < 0.2 levels between 64² and 256²; the LOD error bound does not bind at 640x360
# (the crack-free range rule decides the mesh there), it does on large frames and high seas.
PRESETS = {
    "low": WaterKnobs(detail_scale=0.5, lod_error_scale=2.0, mesh="coarse"),
    "medium": WaterKnobs(detail_scale=1.0, lod_error_scale=1.0),
    "high": WaterKnobs(detail_scale=2.0, lod_error_scale=0.5),
}
presets.register("water", PRESETS)


_HULL_CACHE: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}


HULL_PARTS = ("hull", "pile", "float")  # glTF node names (substrings) of the parts that stand or float in the sea


def model_hulls(name: str) -> list[tuple[np.ndarray, np.ndarray]]:
    """(centre, half extent) in the entity frame of a model's hull boxes: one axis-aligned box per
    connected piece of the glTF nodes named ``*hull*``, ``*pile*`` or ``*float*`` (a pier's piles are
    one node but many pieces: the sea shows between them), or the whole built-in box. Other parts
    (decks, superstructure) let the sea show under and around them."""
    if name not in _HULL_CACHE:
        from ..surfaces.loader import load_model
        from ..surfaces.models import BUILTIN, box_model

        try:
            model = box_model() if name in BUILTIN else load_model(name)
        except Exception:  # noqa: BLE001 - a model the surfaces pass cannot draw has no hull either
            _HULL_CACHE[name] = []
            return []
        matrices = model.node_matrices()
        boxes = []
        for prim in model.primitives:
            if name not in BUILTIN and not any(part in model.nodes[prim.node].name.lower() for part in HULL_PARTS):
                continue
            p = np.c_[prim.vertices[:, :3].astype(np.float64), np.ones(len(prim.vertices))] @ matrices[prim.node].T
            p = p[:, :3][np.asarray(prim.indices).reshape(-1)] if prim.indices is not None else p[:, :3]
            for piece in _pieces(p):
                lo, hi = piece.min(axis=0), piece.max(axis=0)
                boxes.append((0.5 * (lo + hi), 0.5 * (hi - lo)))
        _HULL_CACHE[name] = boxes
    return _HULL_CACHE[name]


def _pieces(corners: np.ndarray) -> list[np.ndarray]:
    """The connected pieces of a triangle list (corners (3T, 3)): triangles sharing a vertex position
    (to 0.1 mm) belong to one piece; labels spread by min over each triangle until stable."""
    _, vid = np.unique(np.round(corners / 1e-4).astype(np.int64), axis=0, return_inverse=True)
    tri = vid.reshape(-1, 3)
    label = np.arange(int(vid.max()) + 1 if len(vid) else 0)
    while True:
        low = label[tri].min(axis=1)
        new = label.copy()
        for c in range(3):
            np.minimum.at(new, tri[:, c], low)
        new = new[new]  # follow the chains
        if np.array_equal(new, label):
            break
        label = new
    piece = label[vid]
    return [corners[piece == k] for k in np.unique(piece)]


_HULL_BOXES_MEMO: dict[tuple, list[np.ndarray]] = {}


def hull_boxes(scene: Scene, view: CameraView) -> list[np.ndarray]:
    """Inverse 4x4 matrices (camera-relative world → [-1, 1]³) of the hulls standing or floating in the sea.
    Memoised on exactly what they depend on (each visible entity's model and pose, the camera position,
    the sea level): a still scene pays it once, not per frame."""
    key = (tuple((e.model, tuple(e.position), e.heading, e.pitch, e.roll, tuple(e.scale))
                 for e in scene.entities if e.visible), tuple(float(x) for x in view.position), scene.ocean.level)
    if key not in _HULL_BOXES_MEMO:
        if len(_HULL_BOXES_MEMO) >= 8:
            _HULL_BOXES_MEMO.clear()
        _HULL_BOXES_MEMO[key] = _hull_boxes(scene, view)
    return list(_HULL_BOXES_MEMO[key])


def _hull_boxes(scene: Scene, view: CameraView) -> list[np.ndarray]:
    boxes = []
    for entity in scene.entities:
        if not entity.visible:
            continue
        rot = body_to_world(entity.heading, entity.pitch, entity.roll)
        scale = np.asarray(entity.scale)
        for centre, half in model_hulls(entity.model):
            m = np.eye(4)
            m[:3, :3] = rot @ np.diag(scale * half)
            m[:3, 3] = view.relative(entity.position) + rot @ (scale * centre)
            lowest = m[2, 3] - np.sum(np.abs(m[2, :3]))
            if lowest + view.position[2] > scene.ocean.level + 30.0:  # well above any sea: not in it
                continue
            boxes.append((float(np.linalg.norm(m[:3, 3])), np.linalg.inv(m)))
    # The nearest first: beyond MAX_HULLS the farthest go (they cover the fewest pixels).
    return [inv for _, inv in sorted(boxes, key=lambda b: b[0])[:MAX_HULLS]]


def blocks_near_hulls(nodes: np.ndarray, hulls: list[np.ndarray], margin: float) -> np.ndarray:
    """Which LOD blocks (rows of camera-relative x0, y0, side, level) come within ``margin`` (m) of a
    hull box's horizontal footprint: only those need the fragment hull test. All hulls at once: a
    box's footprint is its centre ± the sum of |column| of its matrix (the extreme corners)."""
    if not hulls or not len(nodes):
        return np.zeros(len(nodes), dtype=bool)
    m = np.linalg.inv(np.asarray(hulls))  # (H, 4, 4) box → camera-relative
    reach = np.sum(np.abs(m[:, :2, :3]), axis=2)  # (H, 2)
    lo, hi = m[:, :2, 3] - reach - margin, m[:, :2, 3] + reach + margin
    x0, y0, side = (nodes[:, c, None].astype(np.float64) for c in range(3))
    return np.any((x0 <= hi[None, :, 0]) & (x0 + side >= lo[None, :, 0]) & (y0 <= hi[None, :, 1])
                  & (y0 + side >= lo[None, :, 1]), axis=1)


def _detail_bands(sea: SeaSurface) -> tuple[np.ndarray, np.ndarray]:
    """Per detail map, the longest wavelength of its band (m); per detail wave, its map (DETAIL_MAPS:
    roughness only). The finest bands holding fewer than DETAIL_MIN_WAVES waves go to the roughness:
    a tile of so few waves shows its period as a regular ripple, and costs a texture read per pixel
    for under 4/36 of the detail band's slope variance (its waves carry equal shares)."""
    wavelengths = 2.0 * math.pi / sea.detail.k
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
    tops, band = _detail_bands(sea)
    tiles = []
    for c, top in enumerate(tops):
        size = DETAIL_MIN_CYCLES * top
        pick = band == c
        cycles = np.rint(d.k[pick, None] * d.direction[pick] * size / (2.0 * math.pi))
        k_snap = np.linalg.norm(cycles, axis=1) * 2.0 * math.pi / size
        omega = np.sqrt(9.80665 * k_snap)
        phase = np.mod(d.phase[pick] - np.mod(omega * t, 2.0 * math.pi), 2.0 * math.pi)
        tiles.append((size, np.column_stack([cycles, d.amplitude[pick] * k_snap, phase])))
    return tiles


def detail_map_levels(waves: np.ndarray, resolution: int) -> list[np.ndarray]:
    """One detail map and its mip chain, level 0 (``resolution``² texels, a power of two) first:
    (sx, sy, sx², sy²) per texel, float32 (numpy has no fast float16 conversion: 3 ms a 128² map),
    rows along the tile's y.

    The texel (i, j) holds the slopes at its centre u = (i + ½) / N, v = (j + ½) / N of the tile's
    waves (m, n, A k, phase) (``detail_tiles``): s = Σ g cos θ, g = A k (m, n) / |(m, n)| the slope
    amplitude, θ = 2π (m u + n v) + phase = 2π (m i + n j) / N + ψ, ψ = phase + π (m + n) / N.
    Both components at once as sx + i sy = Σ (gx + i gy) (e^{iθ} + e^{−iθ}) / 2: an inverse DFT of
    N² coefficients (gx + i gy) e^{±iψ} / 2 placed at the bins ±(m, n) mod N — exact at the texel
    centres, aliasing included, in O(N² log N) whatever the wave count. Each mip level is the mean of
    2×2 texels of the one above (float32): what the sampler's trilinear filter reads,
    and E[s²] − E[s]² of a level is the slope variance it no longer resolves (LEAN mapping)."""
    n_side = int(resolution)
    mn = waves[:, 0:2]
    g = waves[:, 2:3] * mn / np.linalg.norm(mn, axis=1, keepdims=True)
    half = 0.5 * (g[:, 0] + 1j * g[:, 1])
    psi = waves[:, 3] + math.pi * (mn[:, 0] + mn[:, 1]) / n_side
    m, n = mn[:, 0].astype(int), mn[:, 1].astype(int)
    spectrum = np.zeros((n_side, n_side), dtype=complex)
    np.add.at(spectrum, (n % n_side, m % n_side), half * np.exp(1j * psi))
    np.add.at(spectrum, (-n % n_side, -m % n_side), half * np.exp(-1j * psi))
    s = np.fft.ifft2(spectrum, norm="forward")  # Σ X e^{+2πi (m i + n j) / N}, no 1/N² factor
    level = np.stack([s.real, s.imag, s.real * s.real, s.imag * s.imag], axis=-1).astype(np.float32)
    levels = [level]
    while level.shape[0] > 1:
        level = 0.25 * (level[0::2, 0::2] + level[0::2, 1::2] + level[1::2, 0::2] + level[1::2, 1::2])
        levels.append(level)
    return levels


def detail_unresolved_var(sea: SeaSurface) -> float:
    """Mean-square slope of the detail waves shorter than every map's band: roughness only."""
    if sea.detail.n == 0:
        return 0.0
    _, band = _detail_bands(sea)
    lost = band >= DETAIL_MAPS
    return float(np.sum((sea.detail.amplitude[lost] * sea.detail.k[lost]) ** 2) / 2.0)


def detail_means(tiles: list[tuple[float, np.ndarray]]) -> np.ndarray:
    """Per detail map, its average over the tile (sx, sy, sx², sy²): what the map's 1×1 mip level holds
    (float64 here; the map's is the float32 mean of its texels, within its rounding). Over the texel
    grid a lattice wave averages to zero, and a product of two averages to half the cosine of their
    phase difference when they share a lattice point (or of the phase sum for opposite points)."""
    means = np.zeros((DETAIL_MAPS, 4))
    for c, (_, waves) in enumerate(tiles):
        if not len(waves):
            continue
        mn = waves[:, 0:2]
        g = waves[:, 2:3] * mn / np.linalg.norm(mn, axis=1, keepdims=True)  # slope amplitude vectors
        phi = waves[:, 3]
        same = np.all(mn[:, None] == mn[None], axis=2)
        opposite = np.all(mn[:, None] == -mn[None], axis=2)
        w = 0.5 * (same * np.cos(phi[:, None] - phi[None]) + opposite * np.cos(phi[:, None] + phi[None]))
        means[c, 2] = g[:, 0] @ w @ g[:, 0]
        means[c, 3] = g[:, 1] @ w @ g[:, 1]
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
    contrast = clamp(1.5 - 2 |fwidth(q)|, 0, 1) with q the rest point in cells (24 m along the wind,
    3 m across). |fwidth(q)| >= its across-wind part (|a.dx| + |a.dy|) / 3 >= sigma_min / 3, sigma_min
    the least stretch of the pixel -> rest-point map in any direction, which ``rest_spacing`` bounds
    with the least angle a one-pixel step in any direction turns a ray (``_min_pixel_angle_any``).
    Where that bound reaches 0.75 cells the contrast is exactly 0: the block is drawn without the
    noise's fetch (the frame is the same). Over a bathymetry field every block keeps it."""
    if sea.field is not None or len(selection.nodes) == 0:
        return np.ones(len(selection.nodes), dtype=bool)
    angle = _min_pixel_angle_any(tuple(float(t) for t in view.tangents), int(view.width), int(view.height))
    return rest_spacing(selection, sea, cam_height, angle) < FOAM_STREAK_FADE * FOAM_STREAK_SIZE[1]


def glint_light(uniforms: dict) -> dict:
    """The sun or the moon, whichever gives more light: the one glitter the water shader draws."""
    sun, moon = np.asarray(uniforms["u_sun_illuminance"]), np.asarray(uniforms["u_moon_illuminance"])
    use_sun = float(np.sum(sun)) >= float(np.sum(moon))
    return {"u_glint_dir": tuple(uniforms["u_sun_dir" if use_sun else "u_moon_dir"]),
            "u_glint_illuminance": tuple(float(x) for x in (sun if use_sun else moon))}


# The foam water.frag.glsl draws: a fraction f rising from 0 at J = threshold + FOAM_EDGE[0] to 1 at
# threshold − FOAM_EDGE[1] (smoothstep), dithered into streaks by noise through a ramp of width
# FOAM_SOFT (its mean over the noise: foam_mean).
FOAM_EDGE = (0.02, 0.06)
FOAM_SOFT = 0.25


def foam_mean(f: np.ndarray) -> np.ndarray:
    """The drawn foam's mean over the dither noise (u uniform on [0, 1]) at foam fraction f:
    E[clamp((f − (1 − w) u) / w, 0, 1)], w = FOAM_SOFT, in closed form (water.frag.glsl foam_mean)."""
    w = FOAM_SOFT
    covered = np.where(f < w, f * f / (2.0 * w), np.where(
        f <= 1.0 - w, f - 0.5 * w, (f - w) + (w * w - (f - 1.0 + w) ** 2) / (2.0 * w)))
    return covered / (1.0 - w)


FOAM_STREAK_SIZE = (24.0, 3.0)  # m along and across the wind: a noise cell of the streaks
FOAM_STREAK_FADE = 0.75  # cells a pixel spans where the streaks have faded to their mean (water.frag.glsl)
FOAM_DRIFT = 0.03  # × wind speed: the surface drift that carries the streaks downwind
FOAM_PERIOD = 64.0  # noise cells per side of the tabulated noise: 1.5 km along the wind, 192 m across
FOAM_NOISE_SIZE = 256  # texels per side: 4 per noise cell (bilinear; the shader fades the streaks before it minifies)
FOAM_NOISE_UNIT = FRAME_UNITS["FOAM_NOISE"]


def foam_frame(scene: Scene, view: CameraView) -> dict:
    """The streak noise's frame (water.frag.glsl foam_cover): downwind axis and cell sizes, and the
    camera's noise coordinates, drifted downwind by the time, reduced mod the period in float64 so
    the streaks stay put on the sea at any distance from the origin and any sim_time."""
    to = math.radians(scene.weather.wind_direction + 180.0)  # the wind blows from wind_direction
    axis = np.array([math.sin(to), math.cos(to)])
    across = np.array([-axis[1], axis[0]])
    cam = np.asarray(view.position[:2], dtype=np.float64)
    drift = FOAM_DRIFT * scene.weather.wind_speed * scene.time.sim_time  # m downwind
    offset = np.mod([(float(cam @ axis) - drift) / FOAM_STREAK_SIZE[0], float(cam @ across) / FOAM_STREAK_SIZE[1]],
                    FOAM_PERIOD)
    return {"u_foam_frame": (*axis, 1.0 / FOAM_STREAK_SIZE[0], 1.0 / FOAM_STREAK_SIZE[1]),
            "u_foam_offset": tuple(float(x) for x in offset), "u_foam_period": FOAM_PERIOD,
            "u_foam_noise": FOAM_NOISE_UNIT}


_FOAM_CACHE: dict[tuple, tuple[SeaSurface, float]] = {}


def drawn_foam_threshold(sea: SeaSurface, wind: float) -> float:
    """The J threshold at which the foam the shader draws covers Monahan's whitecap fraction W of the
    sea on average. Its soft edge and its dither thin the foam out, so the threshold is set on the
    drawn foam's mean (``foam_mean``) over the sea's J samples — weighted by J, the displaced area each
    rest point stands for — not on the J quantile at W (which, softened and then halved by the old
    streak texture, drew foam over 3 % of the sea at Beaufort 9 instead of W = 16 %, and 0.02 % at
    Beaufort 5 instead of 0.8 %)."""
    key = id(sea), float(wind)
    held = _FOAM_CACHE.get(key)
    if held is not None and held[0] is sea:  # the sea is held with it: its id cannot be reused meanwhile
        return held[1]
    if len(_FOAM_CACHE) > 16:
        _FOAM_CACHE.clear()
    coverage = whitecap_coverage(wind)
    threshold = -1.0
    if coverage > 0.0 and sea.n > 0:
        j = sea.jacobian_samples
        area = np.maximum(j, 0.0)
        edge = FOAM_EDGE[0] + FOAM_EDGE[1]

        def drawn(t: float) -> float:
            x = np.clip((t + FOAM_EDGE[0] - j) / edge, 0.0, 1.0)
            return float(np.average(foam_mean(x * x * (3.0 - 2.0 * x)), weights=area))

        lo, hi = float(j.min()) - FOAM_EDGE[0], float(j.max()) + FOAM_EDGE[1]  # drawn 0 .. 1
        for _ in range(40):  # bisection: the drawn mean rises with the threshold
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if drawn(mid) < coverage else (lo, mid)
        threshold = 0.5 * (lo + hi)
    _FOAM_CACHE[key] = (sea, threshold)
    return threshold


class SeaTables:
    """The per-frame sky reflection and aerial perspective tables of the sea (sea_tables.glsl), filled
    from the shared atmosphere functions; the sky-view table (sky/sky_view.py) underneath them is the
    atmosphere's per-frame evaluation, these two only add the fog layer and the sea's geometry."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self.sky = ctx.texture(SKY_REFLECT_SIZE, 4, dtype="f4")
        self.air = [ctx.texture(AIR_SIZE, 4, dtype="f4") for _ in range(2)]
        for tex in (self.sky, *self.air):
            tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
            tex.repeat_x, tex.repeat_y = True, False  # azimuth wraps, the other axis clamps
        self.sky.repeat_x = False  # the stereographic disk: clamped
        self.sky_fbo = ctx.framebuffer(color_attachments=[self.sky])
        self.air_fbo = ctx.framebuffer(color_attachments=self.air)
        self._key = None
        self.fills = 0

    # Frame uniforms the tables do not depend on (the view, the display, local lights, the cirrus):
    # everything else (sun, moon, fog, the atmosphere's parameters and tier, the camera's altitude) is
    # part of the key, so a state the tables could depend on refills them.
    VIEW_ONLY = ("u_camera_", "u_frustum_tangents", "u_view_proj", "u_inv_view_proj", "u_resolution", "u_exposure",
                 "u_view_pixel_angle", "u_light_", "u_cirrus_", "u_adaptation_")

    def key(self, frame, level_z: float, air_map: tuple[float, float]) -> tuple:
        sky_view, tables = frame.resources.get("sky_view"), frame.resources.get("atmosphere_tables")
        state = tuple(sorted((k, v.tobytes() if isinstance(v, np.ndarray) else v)  # arrays compare as bytes
                             for k, v in frame.uniforms.items() if not k.startswith(self.VIEW_ONLY)))
        return (state, level_z, air_map, id(tables), getattr(tables, "key", None), id(sky_view),
                getattr(sky_view, "fills", None))

    @staticmethod
    def air_map(reach: float) -> tuple[float, float]:
        """(d0, 1 / log(1 + d_max / d0)) of the distance axis for sea out to ``reach`` m."""
        return AIR_D0, 1.0 / math.log1p(max(reach, 10.0 * AIR_D0) / AIR_D0)

    def fill(self, water: "WaterPass", frame, level_z: float, reach: float) -> dict:
        """Fill both tables for this frame (unless nothing they depend on changed since the last
        fill); returns the sampler/map uniforms of sea_tables.glsl."""
        # The distance axis in 1/8 octaves of the reach, so a moving camera does not refill for it.
        air_map = self.air_map(2.0 ** (math.ceil(8.0 * math.log2(max(reach, 1.0))) / 8.0))
        key = self.key(frame, round(level_z, 2), air_map)
        if key != self._key:
            sky_view = frame.resources.get("sky_view")
            if sky_view is not None:  # units 9..11 may have been taken by an earlier pass this frame
                sky_view.bind()
            self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
            for fbo, defines in ((self.sky_fbo, {"SEA_TABLE_SKY": 1}), (self.air_fbo, {})):
                program = water.programs.program("common/fullscreen.vert.glsl", "water/sea_tables.frag.glsl", defines)
                set_uniforms(program, frame.uniforms)
                set_uniforms(program, {"u_sea_air_map": air_map, "u_level_z": level_z})
                fbo.use()
                water.fullscreen(program)
            self._key = key
            self.fills += 1
        use_texture(self.sky, SKY_REFLECT_UNIT)
        use_texture(self.air[0], AIR_T_UNIT)
        use_texture(self.air[1], AIR_S_UNIT)
        return {"u_sky_reflect": SKY_REFLECT_UNIT, "u_sea_air_t": AIR_T_UNIT, "u_sea_air_s": AIR_S_UNIT,
                "u_sea_air_map": air_map}


class WaterPass(RenderPass):
    name = "water"
    preset_pipeline = "water"

    def __init__(self, ctx, programs):
        super().__init__(ctx, programs)
        self._patch = None
        self._field_key = None
        self._field_tex = None
        self._detail = None
        self._detail_key = [None] * DETAIL_MAPS
        self._instances = None
        self._tables: SeaTables | None = None
        self._selection = None  # (key, sea, LodSelection) of the last select()
        self._selection_version = 0  # counts select()'s recomputations: a key part for what follows it
        self.memo = Memo()
        self.exact_atmosphere = False  # the atmosphere per pixel/vertex instead of the tables (quality study)
        self.skip_minified_maps = True  # False: every block reads every detail map (tests' reference)
        self.skip_faded_streaks = True  # False: every block reads the foam's streak noise (tests' reference)
        self.coarse_flat_sides = True  # False: every fan keeps its G segments a side (tests' reference)
        self.foam_threshold: float | None = None  # tests: a J threshold instead of the calibrated one
        self._foam_noise_tex: moderngl.Texture | None = None
        self.stats: dict = {}

    def needed(self, scene: Scene, view: CameraView) -> bool:
        return scene.ocean.enabled

    # ---- resources ------------------------------------------------------------------------------
    def _program(self, field: bool, hulls: bool = False, detail_maps: int = DETAIL_MAPS,
                 lights: dict | None = None, foam_streaks: bool = True) -> moderngl.Program:
        """``lights``: frame.local_light_defines (None: every light term compiled)."""
        defines = {"MAX_WAVES": MAX_WAVES, "MAX_HULLS": MAX_HULLS, "WATER_DETAIL_MAPS": detail_maps,
                   **(lights or {}), "WATER_FOAM_STREAKS": int(foam_streaks), **self._atmosphere_define()}
        if field:
            defines["WATER_FIELD"] = 1
        if hulls:
            defines["WATER_HULLS"] = 1
        return self.programs.program("water/water.vert.glsl", "water/water.frag.glsl", defines)

    def _atmosphere_define(self) -> dict:
        return {"WATER_EXACT_ATMOSPHERE": 1} if self.exact_atmosphere else {}

    def capture_program(self, field: bool) -> moderngl.Program:
        """The water vertex shader alone, capturing v_rel by transform feedback (tests, quality)."""
        key = ("water-capture", field)
        cache = self.programs._programs
        if key not in cache:
            defines = {"MAX_WAVES": MAX_WAVES, "MAX_HULLS": MAX_HULLS, **({"WATER_FIELD": 1} if field else {})}
            cache[key] = self.ctx.program(vertex_shader=assemble("water/water.vert.glsl", "VERTEX", defines),
                                          varyings=["v_rel"])
        return cache[key]

    def _patch_buffer(self, fan: int = -1) -> tuple[moderngl.Buffer, moderngl.Buffer]:
        """The patch's (G+1)² grid vertices and an index buffer: the full G×G patch (``fan`` -1), or
        the fan of a flat block whose sides in the mask ``fan`` are one segment (lod.fan_indices: the
        same border vertices as the full patch on every other side)."""
        if self._patch is None:
            g = lod.PATCH_QUADS
            i, j = np.meshgrid(np.arange(g + 1), np.arange(g + 1), indexing="ij")
            verts = np.column_stack([i.ravel(), j.ravel()]).astype(np.float32)
            self._patch = (self.ctx.buffer(verts.tobytes()), {-1: self.ctx.buffer(lod.patch_indices().tobytes())})
        verts, indices = self._patch
        if fan not in indices:
            indices[fan] = self.ctx.buffer(lod.fan_indices(fan).tobytes())
        return verts, indices[fan]

    def _upload_field(self, sea: SeaSurface) -> None:
        if self._field_key is sea:
            return
        if self._field_tex is not None:
            for tex in self._field_tex:
                tex.release()
            self._field_tex = None
        self._field_key = sea
        f = sea.field
        if f is None:
            return
        n, nu, nv = f.residual.shape
        data = np.stack([f.residual, f.factor, f.kvec[..., 0], f.kvec[..., 1]], axis=-1)  # (n, nu, nv, 4)
        data = np.ascontiguousarray(np.transpose(data, (0, 2, 1, 3)), dtype=np.float32)  # rows = v
        field = self.ctx.texture_array((nu, nv, n), 4, data.tobytes(), dtype="f4")
        scalar = np.stack([f.steepness, f.depth, f.breaking, np.zeros_like(f.depth)], axis=-1)
        scalar = np.ascontiguousarray(scalar.transpose(1, 0, 2), dtype=np.float32)
        scalar_tex = self.ctx.texture((nu, nv), 4, scalar.tobytes(), dtype="f4")
        for tex in (field, scalar_tex):  # bilinear between nodes, edges clamped (gerstner.glsl)
            tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
            tex.repeat_x = tex.repeat_y = False
        self._field_tex = (field, scalar_tex)

    def _foam_noise(self) -> moderngl.Texture:
        """The foam's streak noise (water/foam_noise.frag.glsl), tabulated once per context."""
        if self._foam_noise_tex is None:
            tex = self.ctx.texture((FOAM_NOISE_SIZE, FOAM_NOISE_SIZE), 1, dtype="f1")
            fbo = self.ctx.framebuffer(color_attachments=[tex])
            program = self.programs.program("common/fullscreen.vert.glsl", "water/foam_noise.frag.glsl")
            set_uniforms(program, {"u_period": FOAM_PERIOD})
            fbo.use()
            self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
            self.fullscreen(program)
            fbo.release()
            tex.repeat_x = tex.repeat_y = True
            tex.filter = (moderngl.LINEAR, moderngl.LINEAR)  # no mipmaps: a trilinear fetch costs 2x
            self._foam_noise_tex = tex
        return self._foam_noise_tex

    def _update_detail(self, sea: SeaSurface, t: float, resolution: int, tiles, read: int) -> None:
        """Write the first ``read`` detail maps of ``tiles`` (those some block reads; the others are
        empty or fully minified everywhere this frame) for time ``t``, with their mip chains
        (``detail_map_levels``: an inverse FFT on the CPU; drawing the maps and building their mips on
        llvmpipe cost 2-3 ms a map, most of it waiting for the rasteriser before the mipmap blit)."""
        if self._detail is None or self._detail[0].size[0] != resolution:
            if self._detail is not None:
                for tex in self._detail:
                    tex.release()
            self._detail_key = [None] * DETAIL_MAPS
            self._detail = [self.ctx.texture((resolution, resolution), 4, dtype="f4") for _ in range(DETAIL_MAPS)]
            for tex in self._detail:
                tex.build_mipmaps()  # allocates the chain that _update_detail overwrites level by level
                tex.repeat_x = tex.repeat_y = True
                tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
        for c, ((size, waves), tex) in enumerate(zip(tiles[:read], self._detail)):
            # A map depends on the sea state and the time only: a frame at the same time (another
            # view, a re-render of a paused scene) reuses it. (The sea is cached per state by
            # igserver.water, so identity is the state; a resolution change above clears the keys.)
            if len(waves) == 0 or (self._detail_key[c] is not None and self._detail_key[c][0] is sea
                                   and self._detail_key[c][1] == float(t)):
                continue
            self._detail_key[c] = (sea, float(t))
            for level, texels in enumerate(detail_map_levels(waves, resolution)):
                tex.write(texels.tobytes(), level=level)

    # ---- per frame ------------------------------------------------------------------------------
    def wave_uniforms(self, sea: SeaSurface, scene: Scene, view: CameraView) -> dict:
        t = scene.time.sim_time
        cam_xy = view.position[:2]
        w = sea.waves
        table = np.zeros((MAX_WAVES, 4), dtype=np.float32)
        n = min(w.n, MAX_WAVES)
        table[:n, 0:2] = (w.k[:, None] * w.direction)[:n]
        table[:n, 2] = w.amplitude[:n]
        table[:n, 3] = w.omega[:n]
        phases = np.zeros(MAX_WAVES, dtype=np.float32)
        phases[:n] = sea.phase_offsets(t, cam_xy)[:n]
        u = {"u_wave_count": n, "u_wave_norm": float(max(n, 1)), "u_steepness": sea.steepness,
             "u_second_order": sea.second_order, "u_sea_depth": sea.reference_depth,
             "u_cam_height": float(view.position[2] - scene.ocean.level),
             "u_level_z": float(scene.ocean.level - view.position[2]),
             "u_patch_quads": float(lod.PATCH_QUADS)}
        if sea.field is not None:
            g = sea.field.grid
            u.update({"u_field_origin": tuple(float(x) for x in g.origin - cam_xy),
                      "u_field_u": tuple(float(x) for x in g.u), "u_field_v": tuple(float(x) for x in g.v),
                      "u_field_cell": (float(g.du), float(g.dv)), "u_field_size": (g.nu, g.nv),
                      "u_field": FIELD_UNIT, "u_field_scalar": FIELD_SCALAR_UNIT})
        return {"uniforms": u, "table": table.tobytes(), "phases": phases.tobytes()}

    def _wave_values(self, sea, wu: dict) -> dict:
        """The wave set's uniform values (``wave_uniforms``), with a bathymetry's field textures bound."""
        if sea.field is not None:
            self._upload_field(sea)
            use_texture(self._field_tex[0], FIELD_UNIT)
            use_texture(self._field_tex[1], FIELD_SCALAR_UNIT)
        return {**wu["uniforms"], "u_wave": wu["table"], "u_wave_phase": wu["phases"]}

    def select(self, sea: SeaSurface, scene: Scene, view: CameraView, lod_error_scale: float = 1.0,
               mesh: str = "default") -> lod.LodSelection:
        cam = scene.camera
        fov = cam.fov_y if cam.frustum is None else cam.frustum.top - cam.frustum.bottom
        # The selection depends on the view, the sea (its wave set and field: one object per state,
        # igserver.water's cache) and the knobs, not on the time: a still camera selects once.
        key = (view.position.tobytes(), view.view_proj.tobytes(), int(view.height), view.far, id(sea),
               scene.ocean.level, fov, scene.ocean.lod_error * lod_error_scale, mesh, lod.PATCH_QUADS,
               lod.SPACING_PER_WAVE, self.coarse_flat_sides)
        if self._selection is not None and self._selection[0] == key and self._selection[1] is sea:
            return self._selection[2]
        selection = lod.select(view, float(view.position[2] - scene.ocean.level), sea.waves.k, sea.waves.amplitude
                               * (np.max(sea.field.factor, axis=(1, 2)) if sea.field is not None else 1.0),
                               fov, min(scene.ocean.lod_error * lod_error_scale, 16.0), view.far, mesh,
                               fans=sea.field is None,  # a field's depth and surf vary per vertex even where flat
                               coarse_sides=self.coarse_flat_sides)
        self._selection = (key, sea, selection)
        self._selection_version += 1
        return selection

    def _draw_plan(self, sea, selection, hulls, tiles, view, level_z: float, used_maps: int):
        """Per block: near a hull, detail maps read, foam streaks; the draw groups they make."""
        # Blocks whose footprint (grown by the waves' reach) touches no hull are drawn by the program
        # without the per-fragment hull test (and its discard, which also turns off early depth tests).
        near_hull = blocks_near_hulls(selection.nodes, hulls, 2.0 * selection.error_sphere + 1.0)
        flat = selection.flat  # blocks carrying no wave: drawn as fans (lod.fan_indices)
        # Detail maps read per block: the later (finer) ones are fully minified far enough away.
        maps = (minified_maps_from(selection, sea, tiles, view, -level_z) if self.skip_minified_maps
                else np.full(len(selection.nodes), used_maps, dtype=int))
        # The foam's streak noise only where a pixel is small enough to show it.
        streaks = (foam_streaks_needed(selection, sea, view, -level_z) if self.skip_faded_streaks
                   else np.ones(len(selection.nodes), dtype=bool))
        # Draw groups: program (hull test, maps read, streaks) x index shape (the full patch, or a fan
        # with its shared flat sides as one segment: lod.fan_indices), in the order hulls, shape (full
        # patches first: the near blocks), maps, streaks; one instanced draw each.
        shape = np.where(flat, selection.coarse_sides.astype(int), -1) + 1  # 0: full patch, 1 + mask: fan
        group = ((near_hull.astype(int) * (len(lod.SIDES) ** 2 + 1) + shape) * (used_maps + 1) + maps) * 2 + streaks
        groups = []  # (program key, fan mask or -1, blocks, slot: the group's id, so a slot keeps its shape)
        for g in np.unique(group):
            first = int(np.argmax(group == g))
            key = (bool(near_hull[first]), int(maps[first]), bool(streaks[first]))
            groups.append((key, int(shape[first]) - 1, selection.nodes[group == g], int(g)))
        return near_hull, maps, streaks, flat, groups

    def execute(self, frame, targets) -> None:
        scene, view = frame.scene, frame.view
        sea = sea_surface(scene.ocean, scene.weather)
        t = scene.time.sim_time
        knobs = self.knobs(frame)
        # A power of two (each mip level halves it exactly): the nearest to the scene's × the preset's scale.
        resolution = 2 ** min(max(round(math.log2(scene.ocean.detail_resolution * knobs.detail_scale)), 5), 9)
        tiles = detail_tiles(sea, t)
        selection = self.select(sea, scene, view, knobs.lod_error_scale, knobs.mesh)
        hulls = hull_boxes(scene, view)
        if self._tables is None:
            self._tables = SeaTables(self.ctx)
        level_z = float(scene.ocean.level - view.position[2])
        table_uniforms = self._tables.fill(self, frame, level_z, 1.5 * float(selection.reach) + abs(level_z))
        used_maps = sum(1 for _, waves in tiles if len(waves))
        waves = self.wave_uniforms(sea, scene, view)  # once per frame, for each program drawn
        # The draw plan follows the selection (one object per view and sea state), the hulls, the
        # tiles' sizes (not their phases), the view's pixel size and the knobs: a still camera over
        # an animating sea plans once.
        plan_key = (self._selection_version, b"".join(h.tobytes() for h in hulls),
                    tuple((size, len(w)) for size, w in tiles), view.tangents, view.width, view.height, level_z,
                    self.skip_minified_maps, self.skip_faded_streaks)
        near_hull, maps, streaks, flat, groups = self.memo.get(
            "draw_plan", plan_key, lambda: self._draw_plan(sea, selection, hulls, tiles, view, level_z, used_maps))
        # Tile averages of the maps some block does not read (empty maps average 0).
        means = detail_means(tiles) if np.any(maps < used_maps) else np.zeros((DETAIL_MAPS, 4))
        self._update_detail(sea, t, resolution, tiles, int(maps.max()) if len(maps) else 0)
        shared = self._frame_uniforms(frame, sea, waves, tiles, selection, hulls, table_uniforms) if groups else None
        programs = {}
        for key, _, nodes, _ in groups:
            if key not in programs:
                with_hulls, m, streak = key
                programs[key] = self._configured_program(frame, sea, shared, m, means, with_hulls and bool(hulls),
                                                         streak)
        self.stats = {"blocks": int(len(selection.nodes)), "triangles": selection.triangles,
                      "lod_error_px": selection.error_bound_px, "error_sphere_m": selection.error_sphere,
                      "finest_spacing_m": selection.finest_spacing, "waves": sea.n,
                      "detail_resolution": resolution, "hull_blocks": int(np.count_nonzero(near_hull)),
                      "fan_blocks": int(np.count_nonzero(flat)),
                      "one_segment_sides": int(np.unpackbits(selection.coarse_sides).sum()),
                      "blocks_by_detail_maps": np.bincount(maps, minlength=used_maps + 1).tolist(),
                      "foam_streak_blocks": int(np.count_nonzero(streaks))}
        if len(selection.nodes) == 0:
            return
        targets.scene_fbo.use()
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.disable(moderngl.BLEND)
        under = self._sees_under_mesh(frame, sea, selection)
        if under:
            self.ctx.disable(moderngl.CULL_FACE)
        else:
            # Seen from above, the first surface a ray meets faces the camera (the sea is a height
            # field): back faces (the far slopes of waves) are always hidden, so they are not drawn.
            self.ctx.enable(moderngl.CULL_FACE)
            self.ctx.front_face = "ccw"  # the patch's triangles wind counter-clockwise seen from above
        for key, fan, nodes, slot in groups:
            self._vao(programs[key], nodes, slot, fan).render(moderngl.TRIANGLES, instances=len(nodes))
        self.ctx.disable(moderngl.CULL_FACE)
        self.stats["culled_back_faces"] = not under
        if under:
            self._fill_under_crests(frame, selection, table_uniforms)

    def _frame_uniforms(self, frame, sea, waves: dict, tiles, selection, hulls, table_uniforms) -> dict:
        """This frame's values for every water program (computed once, set on each program drawn), with
        the detail maps, the foam noise and a field's textures bound to their units."""
        scene, view = frame.scene, frame.view
        morph = np.zeros((24, 2), dtype=np.float32)
        morph[:] = np.minimum(selection.morph, 1e30)
        detail_map = np.zeros((3, 3), dtype=np.float32)
        units = {}
        for c, (size, _) in enumerate(tiles):
            detail_map[c] = (1.0 / size, *(np.mod(view.position[:2], size) / size))
            use_texture(self._detail[c], DETAIL_UNIT0 + c)
            units[f"u_detail{c}"] = DETAIL_UNIT0 + c
        wind = scene.weather.wind_speed if scene.ocean.sea_state is None else sea.spectrum.wind
        threshold = drawn_foam_threshold(sea, wind) if self.foam_threshold is None else self.foam_threshold
        use_texture(self._foam_noise(), FOAM_NOISE_UNIT)
        values = {**frame.uniforms, **table_uniforms, **glint_light(frame.uniforms), **self._wave_values(sea, waves),
                  "u_morph": morph.tobytes(), **units,
                  "u_min_slope_var": 2e-4 + detail_unresolved_var(sea), "u_foam_jacobian": threshold,
                  "u_foam_edge": FOAM_EDGE, **foam_frame(scene, view), "u_hull_count": len(hulls)}
        if hulls:
            mats = np.zeros((MAX_HULLS, 4, 4), dtype=np.float32)
            mats[: len(hulls)] = np.transpose(np.asarray(hulls), (0, 2, 1))
            values["u_hull_inv"] = mats.tobytes()
        return {"values": values, "detail_map": detail_map}

    def _configured_program(self, frame, sea, shared: dict, read_maps: int, means: np.ndarray, with_hulls: bool,
                            foam_streaks: bool) -> moderngl.Program:
        """The water program (with or without the hull test, reading the first ``read_maps`` detail
        maps and the tile means of the others, with or without the foam's streak noise) with this
        frame's uniforms (``_frame_uniforms``) set."""
        program = self._program(sea.field is not None, with_hulls, read_maps, local_light_defines(frame.lights), foam_streaks)
        set_uniforms(program, shared["values"])
        set_uniforms(program, {"u_detail_map": shared["detail_map"][: max(read_maps, 1)].tobytes()})
        mean = program.get("u_detail_mean", None)
        if mean is not None:
            set_uniforms(program, {"u_detail_mean": means[read_maps:read_maps + mean.array_length].astype(np.float32).tobytes()})
        return program

    @staticmethod
    def _sees_under_mesh(frame, sea: SeaSurface, selection: lod.LodSelection) -> bool:
        """Whether the camera may see the underside of the mesh or past it: when it is below the
        surface (a crest over it) or nearer to it than the near plane. A camera above the surface
        right below it (the host's height query at its xy, less what the finest mesh level leaves out)
        by more than the near distance cannot: the sea is a height field out to the horizon, so every
        ray going down meets its top side before passing beneath it."""
        sphere = selection.error_sphere
        height = float(frame.view.position[2]) - frame.scene.ocean.level
        if height > 1.05 * sphere + frame.view.near:
            return False
        w = sea.waves
        x = w.k * selection.finest_spacing  # mesh deviation near the camera: interpolation + faded waves
        mesh_error = float(np.sum(w.amplitude * np.minimum(1.0, x * x / 8.0))) * (
            float(np.max(sea.field.factor)) if sea.field is not None else 1.0)
        surface = float(sea.query(np.asarray(frame.view.position[:2])[None], frame.scene.time.sim_time)["height"][0])
        return height - surface <= frame.view.near + mesh_error + 0.05

    def _fill_under_crests(self, frame, selection: lod.LodSelection, table_uniforms: dict) -> None:
        """Rays that pass under the mesh (``_sees_under_mesh``) meet the water body: draw the sphere
        below every trough (level − ΣA, no near clip) in deep-water colour; the depth test keeps the
        mesh wherever it is nearer. Only then: it costs a full-screen pass."""
        sphere = selection.error_sphere
        height = float(frame.view.position[2]) - frame.scene.ocean.level
        program = self.programs.program("common/fullscreen.vert.glsl", "water/body.frag.glsl",
                                        {**local_light_defines(frame.lights), **self._atmosphere_define()})
        set_uniforms(program, frame.uniforms)
        set_uniforms(program, table_uniforms)
        set_uniforms(program, {"u_plane_height": -height - 1.05 * sphere})
        self.fullscreen(program)

    def capture(self, scene: Scene, mesh: str = "default") -> tuple[lod.LodSelection, np.ndarray]:
        """The displaced mesh the GPU would draw for ``scene``: the water vertex shader run by transform
        feedback on every selected block. Returns (selection, camera-relative positions (N, G+1, G+1, 3))."""
        from ..camera import make_view

        view = make_view(scene.camera)
        sea = sea_surface(scene.ocean, scene.weather)
        selection = self.select(sea, scene, view, mesh=mesh)
        program = self.capture_program(sea.field is not None)
        set_uniforms(program, self._wave_values(sea, self.wave_uniforms(sea, scene, view)))
        morph = np.minimum(selection.morph, 1e30).astype(np.float32)
        set_uniforms(program, {"u_morph": morph.tobytes()})
        verts, _ = self._patch_buffer()
        g1 = lod.PATCH_QUADS + 1
        nodes = np.ascontiguousarray(selection.nodes, dtype=np.float32)
        inst = self.ctx.buffer(nodes.tobytes())
        out = self.ctx.buffer(reserve=len(nodes) * g1 * g1 * 12)
        vao = self.ctx.vertex_array(program, [(verts, "2f", "in_grid"), (inst, "4f/i", "in_node")])
        # A draw needs a complete framebuffer even with the rasterizer off (the headless default has none).
        target = self.ctx.simple_framebuffer((1, 1))
        target.use()
        vao.transform(out, mode=moderngl.POINTS, vertices=g1 * g1, instances=len(nodes))
        positions = np.frombuffer(out.read(), dtype=np.float32).reshape(len(nodes), g1, g1, 3).copy()
        for obj in (vao, inst, out, target):
            obj.release()
        return selection, positions

    def _vao(self, program, nodes: np.ndarray, slot: int = 0, fan: int = -1) -> moderngl.VertexArray:
        """The patch (or a fan of flat blocks, ``_patch_buffer``) drawn once per block of ``nodes``;
        each slot (block group drawn in one frame) has its own instance buffer."""
        verts, index = self._patch_buffer(fan)
        data = np.ascontiguousarray(nodes, dtype=np.float32).tobytes()
        buffers = self._instances if self._instances is not None else {}
        self._instances = buffers
        if slot not in buffers or buffers[slot].size < len(data):
            if slot in buffers:
                buffers[slot].release()
            buffers[slot] = self.ctx.buffer(reserve=max(len(data), 4096), dynamic=True)
            self._vaos_water = {k: v for k, v in getattr(self, "_vaos_water", {}).items() if k[1] != slot}
        write_buffer(buffers[slot], data)
        key = (id(program), slot, fan)
        vaos = getattr(self, "_vaos_water", {})
        if key not in vaos:
            vaos[key] = self.ctx.vertex_array(program, [(verts, "2f", "in_grid"), (buffers[slot], "4f/i", "in_node")],
                                              index_buffer=index)
            self._vaos_water = vaos
        return vaos[key]
