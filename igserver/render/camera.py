"""Camera maths in float64: orientation from heading/pitch/roll, asymmetric projection.

Projection: reversed-Z with the far plane at infinity (render/depth.py): window depth = near / d
for a point at distance d along the view axis, so nothing is ever clipped far away and a float
depth buffer keeps the same relative precision at every distance. ``camera.far`` is the draw
distance of entities, lights and effects (culled by bounding sphere), not a clip plane: the sky and
the earth's surface are drawn to the horizon whatever its value.

The GPU sees camera-relative coordinates only: world positions minus the camera position,
subtracted here in float64, so a camera 1e6 m from the origin renders like one at the origin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..scene.model import Camera


def body_to_world(heading: float, pitch: float, roll: float) -> np.ndarray:
    """3x3 rotation, columns = right, forward, up in ENU, for CIGI angles in degrees.

    R = Rz(-heading) · Rx(pitch) · Ry(roll): roll about the forward axis (right wing down
    positive), then pitch about the right axis (nose up positive), then heading clockwise.
    """
    h, p, r = (math.radians(a) for a in (heading, pitch, roll))
    ch, sh, cp, sp, cr, sr = math.cos(h), math.sin(h), math.cos(p), math.sin(p), math.cos(r), math.sin(r)
    rz = np.array([[ch, sh, 0.0], [-sh, ch, 0.0], [0.0, 0.0, 1.0]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]])
    ry = np.array([[cr, 0.0, sr], [0.0, 1.0, 0.0], [-sr, 0.0, cr]])
    return rz @ rx @ ry


def frustum_half_angles(cam: Camera) -> tuple[float, float, float, float]:
    """(left, right, bottom, top) in degrees, signed from the view axis."""
    if cam.frustum is not None:
        f = cam.frustum
        return f.left, f.right, f.bottom, f.top
    half_v = cam.fov_y / 2.0
    half_h = math.degrees(math.atan(math.tan(math.radians(half_v)) * cam.width / cam.height))
    return -half_h, half_h, -half_v, half_v


@dataclass(frozen=True)
class CameraView:
    position: np.ndarray  # float64 ENU, m
    rotation: np.ndarray  # body -> world (columns right, forward, up)
    view: np.ndarray  # 4x4 world(camera-relative) -> view, float64
    projection: np.ndarray  # 4x4
    near: float
    far: float
    width: int
    height: int
    tangents: tuple[float, float, float, float] = (-1.0, 1.0, -1.0, 1.0)  # frustum (left, right, bottom, top)

    @property
    def forward(self) -> np.ndarray:
        return self.rotation[:, 1]

    @property
    def view_proj(self) -> np.ndarray:
        return self.projection @ self.view

    def relative(self, world_position) -> np.ndarray:
        """Camera-relative position (float64 subtraction, result small enough for float32)."""
        return np.asarray(world_position, dtype=np.float64) - self.position

    @cached_property
    def _cull_planes(self) -> tuple[np.ndarray, np.ndarray]:
        """The four side planes and the near plane of view_proj (camera-relative), unit normals."""
        m = self.view_proj
        planes = np.array([m[3] + m[0], m[3] - m[0], m[3] + m[1], m[3] - m[1], m[3] - m[2]])
        length = np.linalg.norm(planes[:, :3], axis=1)
        keep = length > 0.0
        return planes[keep, :3] / length[keep, None], planes[keep, 3] / length[keep]

    def pixel_rays(self) -> np.ndarray:
        """Unit world direction through each pixel's centre, (height, width, 3), top row first (as
        frames are read back)."""
        left, right, bottom, top = self.tangents
        x = left + (np.arange(self.width) + 0.5) / self.width * (right - left)
        y = top - (np.arange(self.height) + 0.5) / self.height * (top - bottom)
        r, f, u = self.rotation[:, 0], self.rotation[:, 1], self.rotation[:, 2]
        rays = x[None, :, None] * r + f + y[:, None, None] * u
        return rays / np.linalg.norm(rays, axis=-1, keepdims=True)

    def pixel_world(self, distance: np.ndarray, far: float = math.inf) -> np.ndarray:
        """World point (ENU, m) of each pixel from the distance target (``Renderer.read_distance``:
        m along the pixel's ray), NaN where it is farther than ``far`` (the sky: the far plane)."""
        world = self.position + self.pixel_rays() * np.asarray(distance, dtype=np.float64)[..., None]
        world[~(np.asarray(distance) <= far)] = np.nan
        return world

    def sphere_visible(self, world_center, radius: float) -> bool:
        """Conservative frustum test of a bounding sphere: the four side planes and the near plane
        (camera-relative, from view_proj; the same in both clip ranges), and the draw distance."""
        c = self.relative(world_center)
        if math.sqrt(float(c @ c)) - radius > self.far:
            return False
        normals, offsets = self._cull_planes
        return not bool(np.any(normals @ c + offsets < -radius))


# Directions around a cone's rim: the polygon they project to lies inside the rim's ellipse by at
# most 1 - cos(pi / CONE_RIM_POINTS) of its size, made up by CONE_RIM_GROWTH on the angle.
CONE_RIM_POINTS = 64
CONE_RIM_GROWTH = 1.0 / math.cos(math.pi / CONE_RIM_POINTS)
_RIM_COS = np.cos(np.linspace(0.0, 2.0 * math.pi, CONE_RIM_POINTS, endpoint=False))
_RIM_SIN = np.sin(np.linspace(0.0, 2.0 * math.pi, CONE_RIM_POINTS, endpoint=False))


def cone_on_screen(view: CameraView, direction: np.ndarray, half_angle: float) -> bool:
    """Whether any view ray of the frame lies within ``half_angle`` (rad) of the unit
    camera-relative ``direction``: the cone's rim projected on the image plane and its bounding box
    met with the frame's (conservative: a cone that crosses the camera's side plane counts as on
    screen; one wholly behind it does not)."""
    rot = np.asarray(view.rotation, dtype=np.float64)  # columns right, forward, up
    axis = rot.T @ np.asarray(direction, dtype=np.float64)  # (right, forward, up) components
    angle = half_angle * CONE_RIM_GROWTH
    off_axis = math.acos(min(max(axis[1], -1.0), 1.0))  # from the camera's forward direction
    if off_axis - angle >= 0.5 * math.pi:
        return False  # every ray of the cone points behind the camera
    if off_axis + angle >= 0.5 * math.pi - 1e-6:
        return True
    # Two unit vectors across the axis, then the rim.
    side = np.array([axis[1], -axis[0], 0.0]) if abs(axis[2]) < 0.9 else np.array([0.0, axis[2], -axis[1]])
    side /= math.sqrt(float(side @ side))
    other = np.array([axis[1] * side[2] - axis[2] * side[1], axis[2] * side[0] - axis[0] * side[2],
                      axis[0] * side[1] - axis[1] * side[0]])
    rim = math.cos(angle) * axis[None] + math.sin(angle) * (_RIM_COS[:, None] * side[None] + _RIM_SIN[:, None] * other[None])
    tan_x, tan_y = rim[:, 0] / rim[:, 1], rim[:, 2] / rim[:, 1]  # on the image plane, as view.tangents
    left, right, bottom, top = view.tangents
    return bool(tan_x.max() >= left and tan_x.min() <= right and tan_y.max() >= bottom and tan_y.min() <= top)


def gl_matrix(m: np.ndarray) -> bytes:
    """float32 column-major bytes for a GLSL mat4/mat3 uniform."""
    return np.ascontiguousarray(m.T, dtype=np.float32).tobytes()


def frustum_tangents(cam: Camera) -> tuple[float, float, float, float]:
    """(left, right, bottom, top) tangents of the frustum's half-angles (signed)."""
    return tuple(math.tan(math.radians(a)) for a in frustum_half_angles(cam))


def reversed_infinite_projection(cam: Camera, zero_to_one: bool = True) -> np.ndarray:
    """Asymmetric perspective with reversed-Z and no far plane (float64).

    View space looks down -z; d = -z_view. Clip w = d, and clip z is chosen so that
      zero_to_one (glClipControl on):  NDC z = near / d           (clip z = near)
      otherwise (clip range [-1, 1]):  NDC z = 2 near / d - 1     (clip z = 2 near - d)
    both giving window depth near / d: 1 at the near plane, 0 at infinity. A direction (w = 0)
    lands exactly at window depth 0, where the sky is.
    """
    left, right, bottom, top = frustum_tangents(cam)
    proj = np.zeros((4, 4))
    proj[0, 0] = 2.0 / (right - left)
    proj[0, 2] = (right + left) / (right - left)
    proj[1, 1] = 2.0 / (top - bottom)
    proj[1, 2] = (top + bottom) / (top - bottom)
    if zero_to_one:
        proj[2, 3] = cam.near
    else:
        proj[2, 2] = 1.0
        proj[2, 3] = 2.0 * cam.near
    proj[3, 2] = -1.0
    return proj


def make_view(cam: Camera, zero_to_one: bool = True) -> CameraView:
    """The camera's view for a context whose clip depth range is [0, 1] (``zero_to_one``) or not."""
    rot = body_to_world(cam.heading, cam.pitch, cam.roll)
    right, forward, up = rot[:, 0], rot[:, 1], rot[:, 2]
    view = np.eye(4)
    view[0, :3], view[1, :3], view[2, :3] = right, up, -forward
    return CameraView(
        position=np.asarray(cam.position, dtype=np.float64), rotation=rot, view=view,
        projection=reversed_infinite_projection(cam, zero_to_one),
        near=cam.near, far=cam.far, width=cam.width, height=cam.height, tangents=frustum_tangents(cam),
    )
