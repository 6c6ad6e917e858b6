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
STARS_BELOW_SUN_ELEVATION = -2.0  # deg; above this the day sky hides even Sirius


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
        if surface_below(frame.scene):
            defines["SURFACE_BELOW"] = 1
        program = self.programs.program("common/fullscreen.vert.glsl", "sky/sky.glsl", defines)
        set_uniforms(program, frame.uniforms)
        targets.scene_fbo.use()
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.depth_func = depth.AT_INFINITY  # only where nothing nearer was drawn
        self.fullscreen(program)
        if frame.celestial.sun_elevation < STARS_BELOW_SUN_ELEVATION:
            self._stars(frame, model)
        self.ctx.depth_func = depth.NEAREST_WINS

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
