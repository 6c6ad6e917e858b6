"""Sky pass: per-pixel sky radiance, sun, moon and cirrus into the pixels no surface covered, then
the bright stars as points (only when they could show: sun below -2 deg)."""

from __future__ import annotations

import math

import moderngl
import numpy as np

from ...astro import star_field
from .. import depth
from ..passes import RenderPass
from ..shaders import set_uniforms

STAR_POINT_PX = 2.0
# The cirrus layer is evaluated once per frame on a grid this many times coarser per axis than the
# frame (cirrus_table.glsl), 1 = per pixel in the sky pass (the reference for the picture error).
CIRRUS_TABLE_SCALE = 2
CIRRUS_TABLE_UNIT = 7
CIRRUS_TABLE_MIN_WIDTH = 320  # px, the narrowest table
STARS_BELOW_SUN_ELEVATION = -2.0  # deg; above this the day sky hides even Sirius


# Angular half-size of the boxes the disks are drawn in: the disk (sun 0.27 deg, moon 0.26 deg)
# plus the sun's 1.5-pixel footprint tent is added in pixels by disk_box().
SUN_BOX_RAD = math.radians(0.3)
MOON_BOX_RAD = math.radians(0.3)


def disk_box(frame, direction, radius_rad: float) -> tuple[int, int, int, int] | None:
    """Scissor box (x, y, w, h, pixels, origin bottom-left) around a disk of angular radius
    ``radius_rad`` centred on ``direction``; None when it is off screen or behind the camera."""
    view = frame.view
    d = np.asarray(direction, dtype=np.float64)
    clip = np.asarray(view.view_proj, dtype=np.float64) @ np.array([d[0], d[1], d[2], 0.0])
    if clip[3] <= 1e-9:
        return None
    w, h = view.width, view.height
    x = (clip[0] / clip[3] * 0.5 + 0.5) * w
    y = (clip[1] / clip[3] * 0.5 + 0.5) * h
    pixel = 2.0 * math.tan(math.radians(frame.scene.camera.fov_y) / 2.0) / h  # rad per px at the centre
    # Off the axis a radian spans more pixels (1/cos^2 of the angle off the axis): take the box
    # twice the disk (up to 60 deg off-axis) plus the 1.5-px footprint and a pixel of filtering.
    r = 2.0 * radius_rad / pixel + 3.0
    x0, y0 = int(math.floor(x - r)), int(math.floor(y - r))
    x1, y1 = int(math.ceil(x + r)), int(math.ceil(y + r))
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    if x1 <= x0 or y1 <= y0:
        return None
    return (x0, y0, x1 - x0, y1 - y0)


def surface_below(scene) -> bool:
    """The sea or the ground is drawn below the camera (sky pixels are then above its horizon)."""
    z = scene.camera.position[2]
    if scene.ocean.enabled:
        return z > scene.ocean.level
    return scene.ground.enabled and z > scene.ground.level


class SkyPass(RenderPass):
    name = "sky"

    def execute(self, frame, targets) -> None:
        model = frame.scene.atmosphere.model
        defines = {"SKY_" + model.upper(): 1}
        if frame.scene.weather.cirrus_coverage > 0.0:
            defines["CIRRUS"] = 1  # compiled in only when drawn: llvmpipe pays for it even when skipped
            # Frames narrower than 2 x CIRRUS_TABLE_MIN_WIDTH keep the per-pixel layer: on a coarse
            # table the streaks near the horizon fall under a texel (256 px wide: 32 dB) and the
            # noise costs little there anyway.
            if self.cirrus_scale <= 1 or targets.size[0] // self.cirrus_scale < CIRRUS_TABLE_MIN_WIDTH:
                defines["CIRRUS_PER_PIXEL"] = 1
            else:
                self._cirrus_table(frame, model, targets)
        if surface_below(frame.scene):
            defines["SURFACE_BELOW"] = 1
        program = self.programs.program("common/fullscreen.vert.glsl", "sky/sky.glsl", defines)
        set_uniforms(program, frame.uniforms)
        targets.scene_fbo.use()
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.depth_func = depth.AT_INFINITY  # only where nothing nearer was drawn
        self.fullscreen(program)
        self._disks(frame, defines, targets)
        if frame.celestial.sun_elevation < STARS_BELOW_SUN_ELEVATION:
            self._stars(frame, model)
        self.ctx.depth_func = depth.NEAREST_WINS

    cirrus_scale = CIRRUS_TABLE_SCALE

    def _disks(self, frame, defines: dict, targets) -> None:
        """The sun's and the moon's disks, added inside a scissor box around each (sky.glsl SKY_DISKS)."""
        boxes = [b for b in (disk_box(frame, frame.celestial.sun_dir, SUN_BOX_RAD),
                             disk_box(frame, frame.celestial.moon_dir, MOON_BOX_RAD)) if b is not None]
        if not boxes:
            return
        program = self.programs.program("common/fullscreen.vert.glsl", "sky/sky.glsl", {**defines, "SKY_DISKS": 1})
        set_uniforms(program, frame.uniforms)
        self.ctx.enable(moderngl.BLEND)
        self.ctx.blend_func = moderngl.ONE, moderngl.ONE
        fbo = targets.scene_fbo
        try:
            for box in boxes:
                fbo.scissor = box
                self.fullscreen(program)
        finally:
            fbo.scissor = None
            self.ctx.disable(moderngl.BLEND)

    def _cirrus_table(self, frame, model: str, targets) -> None:
        """Draw the cirrus layer at 1/cirrus_scale resolution into a float texture on unit 7."""
        w, h = targets.size
        size = (max(w // self.cirrus_scale, 1), max(h // self.cirrus_scale, 1))
        table = self.held_target("cirrus", size, "f4")
        program = self.programs.program("common/fullscreen.vert.glsl", "sky/cirrus_table.glsl",
                                        {"SKY_" + model.upper(): 1})
        set_uniforms(program, frame.uniforms)
        self.ctx.disable(moderngl.DEPTH_TEST)
        table[1].use()
        self.fullscreen(program)
        table[0].use(location=CIRRUS_TABLE_UNIT)

    def _stars(self, frame, model: str) -> None:
        scene = frame.scene
        stars = star_field(scene.time.utc, scene.location.lat, scene.location.lon)
        program = self.programs.program("sky/stars.glsl", "sky/stars.glsl", {"SKY_" + model.upper(): 1})
        view = frame.view
        pixel = 2.0 * math.tan(math.radians(scene.camera.fov_y) / 2.0) / view.height  # rad per px
        set_uniforms(program, {**frame.uniforms, "u_star_pixel_solid_angle": pixel * pixel * STAR_POINT_PX**2})
        data = np.hstack([stars.directions, stars.illuminance[:, None]]).astype("f4")
        if getattr(self, "_star_vbo", None) is None or self._star_vbo.size != data.nbytes:
            self._star_vbo = self.ctx.buffer(reserve=data.nbytes)
            self._star_vaos: dict = {}
        if id(program) not in self._star_vaos:
            self._star_vaos[id(program)] = self.ctx.vertex_array(
                program, [(self._star_vbo, "3f 1f", "in_dir", "in_lux")])
        self._star_vao = self._star_vaos[id(program)]
        self._star_vbo.write(data.tobytes())
        self.ctx.point_size = STAR_POINT_PX
        self.ctx.enable(moderngl.BLEND)
        self.ctx.blend_func = moderngl.ONE, moderngl.ONE
        self._star_vao.render(moderngl.POINTS, vertices=len(data))
        self.ctx.disable(moderngl.BLEND)
