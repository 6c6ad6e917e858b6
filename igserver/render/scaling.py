"""Internal render scale: every pass draws at ``scale`` x the requested size and a last pass
upscales the LDR frame to the requested size (post/upscale.frag.glsl).

A frame's pixel work (llvmpipe's rasterisation and shading; a GPU's fill) grows with the pixel
count, so a scale s costs about ``s^2`` of it: 0.75 draws 56 % of the pixels, 0.5 a quarter. The
host work (world updates, uniforms, draw calls) does not shrink, which is why the controller
(render/overload.py) learns the real cost of each scale rather than assuming ``s^2``.

The scaled frame is the requested camera with fewer pixels: the same field of view (``fov_y`` or
the explicit frustum) and the requested aspect. Each side is rounded to whole pixels, which
changes the aspect by under half an internal pixel over the frame; the projection is then built
from the explicit frustum angles of the requested camera, so the picture covers exactly the
requested view and the upscale maps it back pixel for pixel (no stretch, no crop).

Scale 1.0 is the plain path: no scaled scene, no upscale pass, the frame bit-identical to a
renderer without scaling.
"""

from __future__ import annotations

from dataclasses import dataclass

import moderngl

from ..scene.model import Frustum, Scene
from .bindings import PASS_UNITS, use_texture
from .camera import frustum_half_angles
from .shaders import ProgramCache, set_uniforms

MIN_SCALE = 0.5  # below half resolution the upscaled picture loses thin lines (wires, masts) outright
MIN_SIDE = 16  # px: the scene model's smallest frame side
# The upscale filter, chosen with `igserver quality scaling` on the demo (320x180 and 640x360, scales
# 0.5 and 0.75): of the Mitchell-Netravali family (B, C) in {(0, 0.5), (0.2, 0.4), (1/3, 1/3),
# (0, 0.3), (0.5, 0.25)}, Catmull-Rom (0, 0.5) has the highest SSIM and PSNR; the softer members
# approach bilinear. With the sea's detail filtered by its footprint the reduced frame holds little
# detail between texels, and Catmull-Rom's PSNR equals bilinear's within 0.1 dB while its SSIM stays
# higher (+0.002 to +0.004 on the demo, Beaufort 5 and the harbour at scale 0.5). An unsharp mask on top raises SSIM slightly (+0.002 at 0.2) and lowers PSNR
# (-0.1 dB): the reduced frame's missing detail is aliased, and sharpening amplifies it. So none.
BC = (0.0, 0.5)
SHARPEN = 0.0


def internal_size(width: int, height: int, scale: float) -> tuple[int, int]:
    """The render targets' size at ``scale`` (each side rounded, at least MIN_SIDE)."""
    return max(MIN_SIDE, round(width * scale)), max(MIN_SIDE, round(height * scale))


def scaled_scene(scene: Scene, scale: float) -> Scene:
    """``scene`` with its camera drawn at ``scale``: fewer pixels, the same view (its frustum angles)."""
    cam = scene.camera
    width, height = internal_size(cam.width, cam.height, scale)
    if (width, height) == (cam.width, cam.height):
        return scene
    left, right, bottom, top = frustum_half_angles(cam)
    frustum = Frustum(left=left, right=right, bottom=bottom, top=top)
    # model_copy: the values are the requested camera's, validated once already
    camera = cam.model_copy(update={"width": width, "height": height, "frustum": frustum})
    return scene.model_copy(update={"camera": camera})


@dataclass
class UpscaledTarget:
    """The requested-size LDR output that the upscale writes (what the readback reads)."""

    texture: moderngl.Texture
    ldr_fbo: moderngl.Framebuffer

    @property
    def size(self) -> tuple[int, int]:
        return self.texture.size


class Upscaler:
    """The upscale pass: one full-screen triangle from the internal LDR target to the output size."""

    def __init__(self, ctx: moderngl.Context, programs: ProgramCache, sharpen: float = SHARPEN,
                 bilinear: bool = False):
        self.ctx = ctx
        self.programs = programs
        self.sharpen = sharpen
        self.bc = BC
        self.bilinear = bilinear  # the plain bilinear filter, the baseline the tests compare against
        self._out: UpscaledTarget | None = None
        self._vao: moderngl.VertexArray | None = None

    def output(self, size: tuple[int, int]) -> UpscaledTarget:
        """The output target of ``size``, made anew only when the size changes."""
        if self._out is None or self._out.size != tuple(size):
            self.release()
            tex = self.ctx.texture(tuple(size), 4)
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            tex.repeat_x = tex.repeat_y = False
            self._out = UpscaledTarget(tex, self.ctx.framebuffer([tex]))
        return self._out

    def execute(self, source: moderngl.Texture, size: tuple[int, int]) -> UpscaledTarget:
        """Queue the upscale of ``source`` (the internal LDR frame) to ``size``; return its target."""
        out = self.output(size)
        program = self.programs.program("common/fullscreen.vert.glsl", "post/upscale.frag.glsl",
                                        {"BILINEAR": 1} if self.bilinear else {})
        unit = PASS_UNITS["HDR"]  # pass-local: the post pass's unit, free again after it
        set_uniforms(program, {"u_source": unit, "u_sharpen": 0.0 if self.bilinear else self.sharpen,
                               "u_bc": self.bc,
                               "u_scale": (source.size[0] / size[0], source.size[1] / size[1])})
        use_texture(source, unit)
        out.ldr_fbo.use()
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
        if self._vao is None or self._vao.program is not program:
            if self._vao is not None:
                self._vao.release()
            self._vao = self.ctx.vertex_array(program, [])
        self._vao.render(moderngl.TRIANGLES, vertices=3)
        return out

    def dispose(self) -> None:
        """Release the output target and the pass's vertex array (the upscale is no longer used)."""
        self.release()
        if self._vao is not None:
            self._vao.release()
            self._vao = None

    def release(self) -> None:
        if self._out is not None:
            self._out.ldr_fbo.release()
            self._out.texture.release()
            self._out = None
