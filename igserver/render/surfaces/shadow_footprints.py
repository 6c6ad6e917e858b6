"""Where on the screen the casters' shadows can fall on the ground plane: rectangles that bound
each caster's shadow footprint, so the plane's shadow lookup runs only inside them (float64, no GL).
"""

from __future__ import annotations

import math

import numpy as np


def ground_shadow_rects(bounds: np.ndarray, direction: np.ndarray, level: float, margin: float, view,
                        size: tuple[int, int]) -> list[tuple[int, int, int, int]] | None:
    """Screen rectangles (x, y, w, h, GL's lower-left origin) holding every pixel of the ground
    (world height ``level``) a caster's shadow can touch: each caster's bounding sphere (world
    centre, radius; ``bounds`` (n, 4)), grown by ``margin``, swept along the light (unit
    ``direction`` toward it) down to the ground: the corners of its box projected along the light
    onto the ground, then onto the screen. None when that cannot bound them: the light within 2 deg
    of the horizon (the sweep runs to the horizon) or a footprint reaching behind the camera. The
    sweep of the box is the convex hull of its corners' (an affine map), so their projections bound
    it on the screen."""
    d = np.asarray(direction, dtype=np.float64)
    if d[2] < math.sin(math.radians(2.0)):
        return None
    w, h = size
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=np.float64)
    rects = []
    for c, r in zip(np.asarray(bounds, dtype=np.float64)[:, :3], np.asarray(bounds, dtype=np.float64)[:, 3]):
        box = c + (r + margin) * corners
        # Nothing under the ground shadows it (the light comes from above: what lies below a ground
        # point is behind it), so the box stops at the ground; each corner slid along the light onto
        # the ground, and the box's own footprint there.
        box[:, 2] = np.maximum(box[:, 2], level)
        ground = box - d * ((box[:, 2] - level) / d[2])[:, None]
        points = np.vstack([ground, np.column_stack([box[:, :2], np.full(8, level)])])
        rel = points - view.position
        clip = np.column_stack([rel, np.ones(len(rel))]) @ np.asarray(view.view_proj, dtype=np.float64).T
        if np.any(clip[:, 3] <= view.near):
            return None
        px = (clip[:, :2] / clip[:, 3:4] * 0.5 + 0.5) * np.array([w, h])
        x0, y0 = np.floor(px.min(axis=0)).astype(int) - 1
        x1, y1 = np.ceil(px.max(axis=0)).astype(int) + 1
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
        if x1 > x0 and y1 > y0:
            rects.append((int(x0), int(y0), int(x1 - x0), int(y1 - y0)))
    return rects
