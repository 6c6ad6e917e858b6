"""Camera maths in float64: orientation from heading/pitch/roll, asymmetric projection.

The GPU sees camera-relative coordinates only: world positions minus the camera position,
subtracted here in float64, so a camera 1e6 m from the origin renders like one at the origin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

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

    @property
    def forward(self) -> np.ndarray:
        return self.rotation[:, 1]

    @property
    def view_proj(self) -> np.ndarray:
        return self.projection @ self.view

    def relative(self, world_position) -> np.ndarray:
        """Camera-relative position (float64 subtraction, result small enough for float32)."""
        return np.asarray(world_position, dtype=np.float64) - self.position

    def sphere_visible(self, world_center, radius: float) -> bool:
        """Conservative frustum test of a bounding sphere (camera-relative planes from view_proj)."""
        c = self.relative(world_center)
        m = self.view_proj
        planes = (m[3] + m[0], m[3] - m[0], m[3] + m[1], m[3] - m[1], m[3] + m[2], m[3] - m[2])
        for plane in planes:
            n = plane[:3]
            length = float(np.linalg.norm(n))
            if length == 0.0:
                continue
            if (float(n @ c) + plane[3]) / length < -radius:
                return False
        return True


def gl_matrix(m: np.ndarray) -> bytes:
    """float32 column-major bytes for a GLSL mat4/mat3 uniform."""
    return np.ascontiguousarray(m.T, dtype=np.float32).tobytes()


def make_view(cam: Camera) -> CameraView:
    rot = body_to_world(cam.heading, cam.pitch, cam.roll)
    right, forward, up = rot[:, 0], rot[:, 1], rot[:, 2]
    view = np.eye(4)
    view[0, :3], view[1, :3], view[2, :3] = right, up, -forward
    left, right_a, bottom, top = (math.tan(math.radians(a)) * cam.near for a in frustum_half_angles(cam))
    n, f = cam.near, cam.far
    proj = np.zeros((4, 4))
    proj[0, 0] = 2 * n / (right_a - left)
    proj[0, 2] = (right_a + left) / (right_a - left)
    proj[1, 1] = 2 * n / (top - bottom)
    proj[1, 2] = (top + bottom) / (top - bottom)
    proj[2, 2] = -(f + n) / (f - n)
    proj[2, 3] = -2 * f * n / (f - n)
    proj[3, 2] = -1.0
    return CameraView(
        position=np.asarray(cam.position, dtype=np.float64), rotation=rot, view=view, projection=proj,
        near=n, far=f, width=cam.width, height=cam.height,
    )
