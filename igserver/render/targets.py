"""Render targets: HDR colour (RGBA16F) + view distance (R32F, m) + depth (float32, reversed-Z:
render/depth.py); LDR output (RGBA8)."""

from __future__ import annotations

import moderngl

from .depth import float_depth_texture


class Targets:
    def __init__(self, ctx: moderngl.Context, width: int, height: int):
        self.size = (width, height)
        self.hdr = ctx.texture(self.size, 4, dtype="f2")
        self.distance = ctx.texture(self.size, 1, dtype="f4")  # m along the view ray; 1e30 = sky
        self.depth, self.float_depth = float_depth_texture(ctx, self.size)
        self.scene_fbo = ctx.framebuffer([self.hdr, self.distance], self.depth)
        # Passes that blend into the colour while sampling scene distance draw here (no distance target).
        self.color_fbo = ctx.framebuffer([self.hdr], self.depth)
        self.distance_fbo = ctx.framebuffer([self.distance])  # read side of the depth copy (one attachment)
        self.distance_copy = ctx.texture(self.size, 1, dtype="f4")
        self.distance_copy_fbo = ctx.framebuffer([self.distance_copy])
        self.ldr = ctx.texture(self.size, 4)
        self.ldr_fbo = ctx.framebuffer([self.ldr])
        for tex in (self.hdr, self.distance, self.distance_copy, self.ldr):
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            tex.repeat_x = tex.repeat_y = False

    def release(self) -> None:
        for obj in (self.scene_fbo, self.color_fbo, self.distance_fbo, self.distance_copy_fbo, self.ldr_fbo,
                    self.hdr, self.distance, self.depth, self.distance_copy, self.ldr):
            obj.release()
