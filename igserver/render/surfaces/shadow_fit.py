"""Shadow-map projections, fitted to the shadow casters (float64, no GL).

Key light (sun or moon): an orthographic map fitted around the bounding spheres of the casters
near the camera. The fit depends on the casters only, not on the camera, and its width is rounded
up to a power of two metres and its centre snapped to whole texels in light space: moving or
turning the camera leaves every texel where it was, so shadow edges cannot shimmer.
Spot light: a perspective map along the spot's axis covering its outer cone out to its range.

Matrices map camera-relative positions (what the GPU sees) to light clip space; the camera offset
is folded in here in float64, so a scene 1e6 m from the origin is as exact as one at the origin.
Depth follows the project's convention (render/depth.py): reversed (window depth 1 nearest the
light, 0 farthest, cleared to 0, nearest wins with ">"), for clip depth [0, 1] (``zero_to_one``,
glClipControl on) or the conventional [-1, 1].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

MIN_EXTENT = 8.0  # m: the narrowest key-light map (one small caster)


@dataclass(frozen=True)
class ShadowProjection:
    view_proj: np.ndarray  # 4x4: camera-relative world -> light clip
    texel: float           # m per texel (key light), or per texel at 1 m (spot light)
    zero_to_one: bool = True

    def map_matrix(self) -> np.ndarray:
        """Camera-relative world -> shadow-map coordinates (homogeneous): xy in [0,1], z the window
        depth the map stores (1 nearest the light)."""
        z_row = [0, 0, 1.0, 0] if self.zero_to_one else [0, 0, 0.5, 0.5]
        bias = np.array([[0.5, 0, 0, 0.5], [0, 0.5, 0, 0.5], z_row, [0, 0, 0, 1.0]])
        return bias @ self.view_proj


def light_basis(direction: np.ndarray) -> np.ndarray:
    """Rows x, y, z of a light frame whose z points toward the light (unit ``direction``)."""
    z = np.asarray(direction, float) / np.linalg.norm(direction)
    helper = np.array([0.0, 1.0, 0.0]) if abs(z[2]) > 0.9 else np.array([0.0, 0.0, 1.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z])


def fit_directional(centers: np.ndarray, radii: np.ndarray, direction: np.ndarray, camera: np.ndarray,
                    resolution: int, zero_to_one: bool = True) -> ShadowProjection:
    """Orthographic map around spheres (world ``centers`` (n,3) float64, ``radii`` (n,)) for a light
    from unit ``direction``; ``camera`` is the world camera position the matrix is relative to."""
    basis = light_basis(direction)
    local = np.asarray(centers, float) @ basis.T  # light-space coordinates, float64
    r = np.asarray(radii, float)
    lo_xy = np.min(local[:, :2] - r[:, None], axis=0)
    hi_xy = np.max(local[:, :2] + r[:, None], axis=0)
    extent = 2.0 ** math.ceil(math.log2(max(float(np.max(hi_xy - lo_xy)), MIN_EXTENT)))
    texel = extent / resolution
    centre_xy = np.round(0.5 * (lo_xy + hi_xy) / texel) * texel  # whole texels: no sub-texel drift
    near_z = float(np.max(local[:, 2] + r)) + 1.0    # toward the light
    far_z = float(np.min(local[:, 2] - r)) - 1.0
    # view: light-space coordinates relative to the map centre; camera folded in (float64)
    origin = np.array([centre_xy[0], centre_xy[1], near_z])
    view = np.eye(4)
    view[:3, :3] = basis
    view[:3, 3] = basis @ camera - origin          # p_light = B (p_rel + camera) - origin
    half = extent / 2.0
    depth = near_z - far_z
    # z_light in [-depth, 0] -> window depth 1 + z / depth in [0, 1] (reversed: nearer the light = larger)
    proj = np.diag([1.0 / half, 1.0 / half, 1.0 / depth if zero_to_one else 2.0 / depth, 1.0])
    proj[2, 3] = 1.0
    return ShadowProjection(proj @ view, texel, zero_to_one)


def fit_spot(position_rel: np.ndarray, axis: np.ndarray, cos_outer: float, light_range: float,
             resolution: int, zero_to_one: bool = True, near: float = 0.1) -> ShadowProjection:
    """Perspective map from a spot light at camera-relative ``position_rel`` along unit ``axis``."""
    half_angle = min(math.acos(max(min(cos_outer, 1.0), -1.0)) + math.radians(2.0), math.radians(80.0))
    basis = light_basis(-np.asarray(axis, float))  # z toward the light = against the beam
    view = np.eye(4)
    view[:3, :3] = basis
    view[:3, 3] = -basis @ np.asarray(position_rel, float)
    f = 1.0 / math.tan(half_angle)
    # reversed, infinite far plane: window depth = near / d (d: distance along the spot's axis)
    proj = np.zeros((4, 4))
    proj[0, 0] = proj[1, 1] = f
    if zero_to_one:
        proj[2, 3] = near                     # clip z = near, w = d
    else:
        proj[2, 2], proj[2, 3] = 1.0, 2.0 * near  # NDC z = 2 near / d - 1
    proj[3, 2] = -1.0
    return ShadowProjection(proj @ view, 2.0 * math.tan(half_angle) / resolution, zero_to_one)
