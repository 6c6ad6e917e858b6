"""Sea mesh level of detail: CDLOD (Strugar 2009), the camera-centred form of the paper's
geomipmapping (docs/design.md#water allows it), chosen because it meets the same requirements with one
draw call and no stitching index buffers.

- A quadtree of square blocks anchored to the world (a block of level l has side S·2^l; every block
  is one instanced G×G patch), so vertices do not swim as the camera moves.
- Level per block from a screen-space error: a level with vertex spacing Δ misrepresents wave i by
  about A_i·min(1, (k_iΔ)²/8) (linear interpolation of a sinusoid), bounded by the error sphere of
  radius Σ A_i. Seen at distance d that error covers ε·(H_px/2)/(d·tan(fov/2)) pixels; ranges[l] is
  the distance beyond which level l's error stays below ``lod_error`` pixels.
- Frustum culling of each block's bounding sphere (the block, raised and lowered by Σ A_i, dropped by
  the earth's curvature).
- Geomorphing: in the outer part of a level's range the odd vertices slide onto the next coarser
  grid (morph 0 → 1), so a block meets a coarser neighbour with exactly the coarser vertices (no
  cracks, no T-junctions) and nothing pops when a block changes level. This needs each level's range
  to reach past the shared border: ranges[l] ≥ 2·ranges[l−1] and ranges[l] ≥ margin·S_l. Why: a
  level-l block exists because its parent (side 2·S_l) came nearer than ranges[l], so its farthest
  point lies within ranges[l] + 2√2·S_l; its border with a level-(l+1) block lies beyond ranges[l]
  (fully morphed there), and the coarse block must not have started morphing at that border:
  ranges[l] + start·(ranges[l+1] − ranges[l]) ≥ ranges[l] + 2√2·S_l, i.e. with ranges doubling,
  start·margin ≥ 2√2. Two such pairs (``MESHES``): the default (morph over the outer half, rings of
  6 block sides) and a coarse one (outer quarter, 4 sides: 2.25× fewer vertices, shorter morphs).
- Flat blocks as fans: from the level whose vertex spacing has faded out every wave (k·Δ ≥ π for the
  longest, gerstner.glsl's fade; the morph only widens the spacing) the displaced mesh IS the mean
  sea sphere, so the G×G interior only interpolates smooth attributes. Such a block is drawn as a fan
  from its centre to its 4·G border vertices (``fan_indices``): the border is the full patch's (same
  vertices, same morph), so joins stay crack-free, and 4·G triangles replace 2·G² (128 → 32). From
  high cameras most blocks are flat (their rings lie near the horizon, where the G² grid made
  sub-pixel slivers: llvmpipe sets up and shades every one).
- Shared flat sides as one segment: two flat blocks of the same level side by side have the same
  corners and nothing between them to carry (no wave, no morph: corners and the fan's centre are even
  grid vertices), so both draw that side as one triangle from the centre instead of G (``coarse``:
  a 4-bit mask per block, ``fan_indices(mask)``). A side next to anything else (a finer or coarser
  block, a block with waves, a block culled away) keeps its G segments, so every join is made of the
  same vertices on both sides. From high cameras, where most blocks are flat, the fans' G-segment
  slivers near the horizon were most of the triangles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..camera import CameraView

PATCH_QUADS = 8  # G: quads per block side
SPACING_PER_WAVE = 8.0  # the finest vertex spacing: this fraction of the shortest mesh wave (see select)
SLOPE_SHOWN = 0.02  # k·A from which a wave tilts the surface by 1.1° and moves J by the foam's J edge (0.02)
MAX_LEVELS = 24
MORPH_START = 0.5  # morph over the outer half of each level's ring
MORPH_MARGIN = 6.0  # ranges[l] ≥ 6·S_l: the ring is wide enough for the neighbour rule (see above)
MESHES = {"default": (MORPH_START, MORPH_MARGIN), "coarse": (0.75, 4.0)}  # (start, margin) per mesh density
assert all(start * margin >= 2.0 * math.sqrt(2.0) for start, margin in MESHES.values())
EARTH_RADIUS = 6.371e6


@dataclass(frozen=True)
class LodSelection:
    nodes: np.ndarray  # (N, 4) float32: camera-relative x0, y0 of the block corner, side (m), level
    morph: np.ndarray  # (MAX_LEVELS, 2): morph start, end distance (m) per level
    ranges: np.ndarray  # per level, m
    finest_spacing: float  # m, vertex spacing of level 0
    error_bound_px: float  # the screen-space error each block satisfies (px)
    error_sphere: float  # m, Σ A_i
    reach: float  # m, horizontal distance the sea is drawn to (the horizon and the crests beyond it)
    flat_level: int = MAX_LEVELS  # blocks of this level and coarser carry no wave (drawn as fans)
    coarse: np.ndarray | None = None  # (N,) uint8: per flat block, sides drawn as one segment (SIDES bits)

    @property
    def flat(self) -> np.ndarray:
        """Per block: whether it carries no wave (its spacing faded them all out)."""
        return self.nodes[:, 3] >= self.flat_level - 0.5

    @property
    def coarse_sides(self) -> np.ndarray:
        """Per block, the mask of sides drawn as one segment (0 for blocks with waves)."""
        return self.coarse if self.coarse is not None else np.zeros(len(self.nodes), dtype=np.uint8)

    @property
    def triangles(self) -> int:
        flat = self.flat
        n_flat = int(np.count_nonzero(flat))
        one_segment = int(np.unpackbits(self.coarse_sides[flat]).sum())  # sides of 1 triangle instead of G
        fans = n_flat * FAN_TRIANGLES - one_segment * (PATCH_QUADS - 1)
        return (int(len(self.nodes)) - n_flat) * PATCH_QUADS * PATCH_QUADS * 2 + fans


FAN_TRIANGLES = 4 * PATCH_QUADS
# The sides of a block in the fan's ring order, as (bit, neighbour offset in blocks): bottom (y0),
# right (x0 + S), top (y0 + S), left (x0).
SIDES = ((1, (0, -1)), (2, (1, 0)), (4, (0, 1)), (8, (-1, 0)))


def fan_triangles(coarse: int = 0) -> int:
    """Triangles of a flat block's fan whose sides in ``coarse`` are one segment."""
    return sum(1 if coarse & bit else PATCH_QUADS for bit, _ in SIDES)


def patch_indices() -> np.ndarray:
    """Triangles of the full G×G patch over the (G+1)² grid vertices (vertex a·(G+1) + b is grid
    (i, j) = (a, b)), counter-clockwise seen from above."""
    g = PATCH_QUADS
    a, b = np.meshgrid(np.arange(g), np.arange(g), indexing="ij")
    v00 = (a * (g + 1) + b).ravel()
    v10, v01, v11 = v00 + g + 1, v00 + 1, v00 + g + 2
    return np.column_stack([v00, v10, v11, v00, v11, v01]).astype(np.int32).ravel()


def fan_indices(coarse: int = 0) -> np.ndarray:
    """Triangles of the fan patch of a flat block: the centre vertex (G/2, G/2) to each of the 4·G
    border segments of the full patch, or to the side's two corners for a side in ``coarse``
    (``SIDES`` bits), counter-clockwise seen from above."""
    g = PATCH_QUADS
    t = np.arange(g)
    sides = [np.column_stack([t, np.zeros(g, int)]),          # bottom, i rising
             np.column_stack([np.full(g, g), t]),            # right, j rising
             np.column_stack([g - t, np.full(g, g)]),        # top, i falling
             np.column_stack([np.zeros(g, int), g - t])]     # left, j falling
    ring = np.concatenate([side[:1] if coarse & bit else side for side, (bit, _) in zip(sides, SIDES)])
    v = ring[:, 0] * (g + 1) + ring[:, 1]
    centre = (g // 2) * (g + 1) + g // 2
    return np.column_stack([np.full(len(v), centre), v, np.roll(v, -1)]).astype(np.int32).ravel()


def shared_flat_sides(corners: np.ndarray, sizes: np.ndarray, flat: np.ndarray) -> np.ndarray:
    """Per block (world lower-left ``corners``, ``sizes`` in m), the ``SIDES`` bits of the sides a
    flat block shares whole with another flat block of the same size: the blocks the quadtree chose
    tile the plane, so a same-size block one side away covers exactly that side."""
    mask = np.zeros(len(corners), dtype=np.uint8)
    if not np.any(flat):
        return mask
    # One integer key per (size, column, row): corners are exact multiples of their block's size
    # (powers of two), and |column| < 2^27 for any camera the scene accepts (1e7 m, blocks >= 1 m).
    cells = np.round(corners / sizes[:, None]).astype(np.int64) + (1 << 27)
    size_id = np.unique(sizes, return_inverse=True)[1].astype(np.int64).reshape(-1)

    def key(cx, cy):
        return (size_id << 56) | (cx << 28) | cy

    flat_keys = key(cells[:, 0], cells[:, 1])[flat]
    for bit, (dx, dy) in SIDES:
        shared = flat & np.isin(key(cells[:, 0] + dx, cells[:, 1] + dy), flat_keys)
        mask[shared] |= np.uint8(bit)
    return mask


def first_flat_level(k: np.ndarray, spacing: float) -> int:
    """The first level whose vertex spacing (``spacing``·2^l at level l) fades out every wave:
    k·Δ ≥ π for the smallest k (gerstner.glsl: fade = 1 − smoothstep(π/2, π, kΔ), and the morph only
    widens Δ). Over a bathymetry the local k is never smaller than the deep-water k (tanh ≤ 1)."""
    if not len(k):
        return 0
    return max(0, int(math.ceil(math.log2(math.pi / (float(np.min(k)) * spacing)) - 1e-12)))


def level_error(k: np.ndarray, amplitude: np.ndarray, spacing: float) -> float:
    """World-space error (m) of a mesh with vertex ``spacing`` showing waves (k, A): linear
    interpolation misses a sinusoid by A·(kΔ)²/8. Waves the vertex shader fades out at this spacing
    (kΔ from π/2 to π, gerstner.glsl) leave the geometry for the shading (their slopes become
    roughness), so they count with their remaining weight only."""
    x = k * spacing
    kept = 1.0 - np.clip((x - 0.5 * math.pi) / (0.5 * math.pi), 0.0, 1.0)
    return float(np.sum(amplitude * kept * np.minimum(1.0, x * x / 8.0)))


def horizon_distance(height: float) -> float:
    h = max(height, 0.0)
    return math.sqrt(h * (2.0 * EARTH_RADIUS + h))


def select(view: CameraView, cam_height: float, k: np.ndarray, amplitude: np.ndarray, fov_y_deg: float,
           lod_error_px: float, max_distance: float, mesh: str = "default", fans: bool = True,
           coarse_sides: bool = True) -> LodSelection:
    """Blocks to draw this frame. ``cam_height``: camera height above the mean sea level (m);
    ``mesh``: the ring rule (``MESHES``); ``fans``: flat blocks drawn as fans (``flat_level``; off
    where per-vertex attributes vary without waves, e.g. depth over a bathymetry field);
    ``coarse_sides``: the sides two flat blocks share drawn as one segment."""
    morph_start, morph_margin = MESHES[mesh]
    sphere = float(np.sum(amplitude))
    h_abs = abs(cam_height)
    # Finest spacing: 1/SPACING_PER_WAVE of the shortest wave, but no finer than 4 pixels straight below
    # the camera (h·tan(fov/2)/(H_px/2) per pixel), and between 12.5 cm and 64 m. A sea that shows no
    # relief (significant height 4·√(Σ A²/2) under ``lod_error_px`` even straight below, where it is
    # nearest) made of gentle waves (every k·A under SLOPE_SHOWN) sets no spacing (64 m): the vertex
    # shader fades its waves and their slopes and compression go to the shading (roughness, foam
    # probability), as for distant waves. Shallow water shortens waves as it lowers them (over 1 cm:
    # 0.6 m waves, Hs 6 mm, k·A ≤ 0.013) and following them cost more as the depth fell.
    px = max(h_abs, 1.0) * math.tan(math.radians(fov_y_deg) / 2.0) / (view.height / 2.0)
    k, amplitude = np.asarray(k, dtype=np.float64), np.asarray(amplitude, dtype=np.float64)
    shown = (4.0 * math.sqrt(0.5 * float(np.sum(amplitude**2))) >= lod_error_px * px
             or bool(np.any(k * amplitude >= SLOPE_SHOWN)))
    kmax = float(np.max(k)) if len(k) and shown else 2.0 * math.pi / (64.0 * SPACING_PER_WAVE)
    # The 64 m cap bounds what the waves ask for, never the 4 pixels: from high above, 64 m blocks would be
    # sub-pixel and their number grow with the square of the height (222,000 blocks, 2.7 s, from 300 km)
    spacing = 2.0 ** round(math.log2(max(min(max(2.0 * math.pi / kmax / SPACING_PER_WAVE, 0.125), 64.0), 4.0 * px)))
    s0 = spacing * PATCH_QUADS
    pixels_per_rad = (view.height / 2.0) / math.tan(math.radians(fov_y_deg) / 2.0)
    # To the geometric horizon (reversed-Z depth has no far clip; ``max_distance`` only bounds a
    # camera so high that even the horizon is beyond it — never nearer than the horizon itself).
    reach = max(horizon_distance(h_abs) + 2.0 * sphere, 4.0 * s0)
    ranges = []
    for level in range(MAX_LEVELS):
        err = level_error(k, amplitude, spacing * 2**level)
        r = err * pixels_per_rad / lod_error_px
        r = max(r, morph_margin * s0 * 2**level, 2.0 * ranges[-1] if ranges else 0.0, h_abs * 1.05)
        ranges.append(r)
        if r >= reach * 1.5 and s0 * 2**level >= reach:
            break
    top = len(ranges) - 1
    morph = np.zeros((MAX_LEVELS, 2))
    for level, r in enumerate(ranges):
        lo = ranges[level - 1] if level else 0.0
        morph[level] = (lo + morph_start * (r - lo), r)
    morph[top] = (1e30, 2e30)  # the root level never morphs (there is nothing coarser)

    cam = view.position
    planes = np.array(_frustum_planes(view))  # (5, 5): a, b, c, w, |abc|
    root = s0 * 2**top
    # 3x3 (or more) root blocks around the camera, covering ``reach``.
    n_root = int(math.ceil((reach + root) / root))
    cz = float(cam_height)

    def dist2_to_block(xy: np.ndarray, size: float) -> np.ndarray:
        d = np.maximum(np.maximum(xy - cam[:2], 0.0), cam[:2] - (xy + size))
        return np.sum(d * d, axis=1) + cz * cz

    def visible(xy: np.ndarray, size: float) -> np.ndarray:
        c = xy + size / 2.0 - cam[:2]
        d = np.hypot(c[:, 0], c[:, 1])
        cz_block = -cz - d * d / (2.0 * EARTH_RADIUS)  # the sea's drop below the tangent plane
        radius = size * 0.7072 + sphere + 0.5 * size * d / EARTH_RADIUS + 1.0
        side = (planes[:, 0][None] * c[:, :1] + planes[:, 1][None] * c[:, 1:] + planes[:, 2][None] * cz_block[:, None]
                + planes[:, 3][None])
        return (d - size <= reach) & np.all(side >= -radius[:, None] * planes[:, 4][None], axis=1)

    # The quadtree walked a level at a time over arrays of blocks (lower-left corners, world m).
    i, j = np.meshgrid(np.arange(2 * n_root + 1), np.arange(2 * n_root + 1), indexing="ij")
    blocks = np.column_stack([(math.floor(cam[0] / root) - n_root + i.ravel()) * root,
                              (math.floor(cam[1] / root) - n_root + j.ravel()) * root])
    blocks = blocks[dist2_to_block(blocks, root) <= reach**2 + cz * cz]
    chosen = []
    for level in range(top, -1, -1):
        size = s0 * 2**level
        blocks = blocks[visible(blocks, size)]
        split = (dist2_to_block(blocks, size) < ranges[level - 1] ** 2) if level else np.zeros(len(blocks), bool)
        leaves = blocks[~split]
        chosen.append(np.column_stack([leaves, np.full(len(leaves), size), np.full(len(leaves), level)]))
        half = size / 2.0
        blocks = (blocks[split][:, None, :] + np.array([[0.0, 0.0], [0.0, half], [half, 0.0], [half, half]])[None]
                  ).reshape(-1, 2)
    nodes = np.concatenate(chosen) if chosen else np.zeros((0, 4))
    arr = nodes.astype(np.float64).reshape(-1, 4)
    flat_level = first_flat_level(k, spacing) if fans else MAX_LEVELS
    coarse = shared_flat_sides(arr[:, :2], arr[:, 2], arr[:, 3] >= flat_level - 0.5) if coarse_sides else None
    arr[:, 0] -= cam[0]
    arr[:, 1] -= cam[1]
    # Near blocks first: the depth test then rejects hidden far fragments before they are shaded.
    centre = arr[:, :2] + arr[:, 2:3] / 2.0
    order = np.argsort(np.hypot(centre[:, 0], centre[:, 1]) - arr[:, 2] * 0.7072, kind="stable")
    return LodSelection(arr[order].astype(np.float32), morph, np.asarray(ranges), spacing, lod_error_px, sphere,
                        reach, flat_level, coarse[order] if coarse is not None else None)


def _frustum_planes(view: CameraView) -> list[tuple[float, ...]]:
    m = view.view_proj
    planes = [m[3] + m[0], m[3] - m[0], m[3] + m[1], m[3] - m[1], m[3] - m[2]]  # no near-plane cull
    return [(*(float(x) for x in p), float(np.linalg.norm(p[:3]))) for p in planes]
