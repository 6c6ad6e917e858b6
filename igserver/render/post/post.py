"""Post pass: tone mapping, sRGB encoding and dithering into the 8-bit output target."""

from __future__ import annotations

import moderngl

from ..passes import RenderPass
from ..shaders import set_uniforms


class PostPass(RenderPass):
    name = "post"

    def execute(self, frame, targets) -> None:
        program = self.programs.program("common/fullscreen.vert.glsl", "post/tonemap.glsl")
        set_uniforms(program, frame.uniforms)
        program["u_hdr"].value = 0
        targets.hdr.use(0)
        targets.ldr_fbo.use()
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
        self.fullscreen(program)
