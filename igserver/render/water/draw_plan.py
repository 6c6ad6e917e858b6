"""The water pass's draw plan: per LOD block, which program variant draws it (the hull test, the detail
maps read, the foam's streak noise, the shore's land) and its index shape, grouped into one instanced
draw per group. Each variant leaves out code a block cannot need: llvmpipe runs every branch of a
fragment shader on every pixel, so a lookup or a land colour compiled in costs the whole block."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...scene.model import Scene
from ...water.surface import SeaSurface
from ..camera import CameraView
from . import lod
from .detail import foam_streaks_needed, minified_maps_from
from .hulls import blocks_near_hulls
from .shore import blocks_reaching_land


@dataclass
class PlanSwitches:
    """What the plan may leave out (each False: the tests' reference, every block draws it)."""

    skip_minified_maps: bool = True  # False: every block reads every detail map
    skip_faded_streaks: bool = True  # False: every block reads the foam's streak noise
    skip_offshore_land: bool = True  # False: every block over a field draws the swash and the land


def draw_plan(sea: SeaSurface, selection: lod.LodSelection, hulls, tiles, scene: Scene, view: CameraView, level_z: float,
              used_maps: int, switches: "PlanSwitches") -> tuple:
    """Per block of the selection: near a hull, detail maps read, foam streaks, the shore's land; and the
    draw groups they make: (near_hull, maps, streaks, flat, groups, stats). ``level_z``: the sea level
    relative to the eye (m); ``used_maps``: the detail maps holding waves."""
    # Blocks whose footprint (grown by the waves' reach) touches no hull are drawn by the program
    # without the per-fragment hull test (and its discard, which also turns off early depth tests).
    near_hull = blocks_near_hulls(selection.nodes, hulls, 2.0 * selection.error_sphere + 1.0)
    flat = selection.flat  # blocks carrying no wave: drawn as fans (lod.fan_indices)
    # Detail maps read per block: the later (finer) ones are fully minified far enough away.
    maps = (minified_maps_from(selection, sea, tiles, view, -level_z) if switches.skip_minified_maps
            else np.full(len(selection.nodes), used_maps, dtype=int))
    # The foam's streak noise only where a pixel is small enough to show it.
    streaks = (foam_streaks_needed(selection, sea, view, -level_z) if switches.skip_faded_streaks
               else np.ones(len(selection.nodes), dtype=bool))
    # The swash and the land only where a block reaches above the water (over a field).
    land = (blocks_reaching_land(selection.nodes, scene, view, sea) if switches.skip_offshore_land
            else np.full(len(selection.nodes), sea.field is not None))
    # Draw groups: program (hull test, maps read, streaks, land) x index shape (the full patch, or a
    # fan with its shared flat sides as one segment: lod.fan_indices), in the order hulls, shape
    # (full patches first: the near blocks), maps, streaks, land; one instanced draw each.
    shape = np.where(flat, selection.coarse_sides.astype(int), -1) + 1  # 0: full patch, 1 + mask: fan
    group = (((near_hull.astype(int) * (len(lod.SIDES) ** 2 + 1) + shape) * (used_maps + 1) + maps) * 2
             + streaks) * 2 + land
    groups = []  # (program key, fan mask or -1, blocks, slot: the group's id, so a slot keeps its shape,
    #            the blocks as the instance buffer's bytes)
    for g in np.unique(group):
        first = int(np.argmax(group == g))
        key = (bool(near_hull[first]), int(maps[first]), bool(streaks[first]), bool(land[first]))
        nodes = selection.nodes[group == g]
        data = np.ascontiguousarray(nodes, np.float32).tobytes()
        groups.append((key, int(shape[first]) - 1, nodes, int(g), data))
    stats = {"hull_blocks": int(np.count_nonzero(near_hull)), "fan_blocks": int(np.count_nonzero(flat)),
             "one_segment_sides": int(np.unpackbits(selection.coarse_sides).sum()),
             "blocks_by_detail_maps": np.bincount(maps, minlength=used_maps + 1).tolist(),
             "foam_streak_blocks": int(np.count_nonzero(streaks)), "land_blocks": int(np.count_nonzero(land))}
    return near_hull, maps, streaks, flat, groups, stats
