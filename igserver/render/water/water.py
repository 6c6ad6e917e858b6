"""Water pass: the sea surface at the ocean level, reflecting the sky (Fresnel, R0 = 0.02037).

Flat for now: the wave pipeline (Gerstner, depth effects, LOD) replaces the surface shape.
"""

from __future__ import annotations

import moderngl

from ...scene.model import Scene
from ..camera import CameraView
from ..passes import RenderPass
from ..shaders import set_uniforms

# Deep-water body colour (linear albedo of light scattered back out of the water column).
WATER_BODY_COLOR = (0.004, 0.016, 0.022)


class WaterPass(RenderPass):
    name = "water"

    def needed(self, scene: Scene, view: CameraView) -> bool:
        return scene.ocean.enabled

    def execute(self, frame, targets) -> None:
        program = self.programs.program("common/fullscreen.vert.glsl", "surfaces/plane.glsl", {"WATER": 1})
        set_uniforms(program, frame.uniforms)
        set_uniforms(program, {
            "u_plane_height": frame.scene.ocean.level - float(frame.view.position[2]),
            "u_base_color": WATER_BODY_COLOR,
        })
        targets.scene_fbo.use()
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.fullscreen(program)
