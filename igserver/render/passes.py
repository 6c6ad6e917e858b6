"""Base class of a render pass. One small class per pipeline (pygfx style); the FrameGraph asks
each pass whether the scene needs it and runs only those."""

from __future__ import annotations

import moderngl

from ..scene.model import Scene
from . import presets
from .camera import CameraView
from .shaders import ProgramCache
from .targets import Targets


class RenderPass:
    name: str = "?"
    reads_scene_distance: bool = False  # needs the depth copy before it runs

    preset_pipeline: str | None = None  # the name its knobs are registered under in render/presets.py

    def __init__(self, ctx: moderngl.Context, programs: ProgramCache):
        self.ctx = ctx
        self.programs = programs
        self.settings = None  # fixed knobs (quality studies, tests); None = the scene's quality preset

    def knobs(self, frame):
        """This frame's knobs: the fixed settings if any, else those of the frame's quality rung."""
        return self.settings or presets.knobs(self.preset_pipeline, frame.quality)

    def needed(self, scene: Scene, view: CameraView) -> bool:
        return True

    def execute(self, frame, targets: Targets) -> None:  # frame: FrameContext
        raise NotImplementedError

    def fullscreen(self, program: moderngl.Program) -> None:
        """Draw one viewport-covering triangle with ``program`` (no vertex buffers)."""
        vao = self._vaos.get(id(program)) if hasattr(self, "_vaos") else None
        if vao is None:
            self._vaos = getattr(self, "_vaos", {})
            vao = self.ctx.vertex_array(program, [])
            self._vaos[id(program)] = vao
        vao.render(moderngl.TRIANGLES, vertices=3)


class DepthCopyPass(RenderPass):
    """Copy the view distance so that volume passes can read it while drawing into the colour."""

    name = "depth_copy"

    def execute(self, frame, targets: Targets) -> None:
        self.ctx.copy_framebuffer(targets.distance_copy_fbo, targets.distance_fbo)
        frame.resources["scene_distance"] = targets.distance_copy
