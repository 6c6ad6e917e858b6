"""Sky pass: per-pixel sky radiance, sun disk and halo into the pixels no surface covered."""

from __future__ import annotations

import moderngl

from ..passes import RenderPass
from ..shaders import set_uniforms


class SkyPass(RenderPass):
    name = "sky"

    def execute(self, frame, targets) -> None:
        program = self.programs.program("common/fullscreen.vert.glsl", "sky/sky.glsl",
                                        {"SKY_" + frame.scene.atmosphere.model.upper(): 1})
        set_uniforms(program, frame.uniforms)
        targets.scene_fbo.use()
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.depth_func = "<="
        self.fullscreen(program)
        self.ctx.depth_func = "<"
