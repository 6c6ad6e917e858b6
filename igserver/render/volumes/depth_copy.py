"""Stop-gap for passes.DepthCopyPass (not this pipeline's file; reported to the lead).

``ctx.copy_framebuffer(distance_copy_fbo, scene_fbo)`` raises in moderngl: the two framebuffers
have different numbers of colour attachments (1 vs 2), so any frame with a volume failed. Until
passes.py is fixed, the copy falls back to a fullscreen draw of the distance texture. The patch
only wraps the original: once it works, the fallback is never taken.
"""

from __future__ import annotations

import moderngl

from ..passes import DepthCopyPass

_original = DepthCopyPass.execute


def _execute(self, frame, targets) -> None:
    try:
        _original(self, frame, targets)
        return
    except moderngl.Error:
        pass
    program = self.programs.program("common/fullscreen.vert.glsl", "volumes/depth_copy.glsl")
    targets.distance.use(0)
    program["u_distance"].value = 0
    targets.distance_copy_fbo.use()
    self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
    self.fullscreen(program)
    frame.resources["scene_distance"] = targets.distance_copy


if not getattr(DepthCopyPass.execute, "_volumes_fallback", False):
    _execute._volumes_fallback = True
    DepthCopyPass.execute = _execute
