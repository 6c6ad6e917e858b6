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
    # Attributes that hold what the pass keeps for one view between frames (a view-keyed table, a LOD
    # selection, what a later pass of the same view reads): a frame of channels gives each channel its
    # own (render/multiview.py swap_view_state; an attribute a view has not set yet is absent, so the
    # class's default or the code's getattr default applies). ``view_counters``: version numbers
    # that keys are made of, unique to each view.
    view_state: tuple[str, ...] = ()
    view_counters: tuple[str, ...] = ()

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

    def held_target(self, key: str, size: tuple[int, int], dtype: str = "f2") -> tuple[moderngl.Texture, moderngl.Framebuffer]:
        """A linear-filtered, edge-clamped RGBA colour target of ``size`` that the pass keeps under
        ``key`` between frames (reduced-resolution layers: fog halos, the cirrus table), made anew
        only when the size changes."""
        held = getattr(self, "_held_targets", {})
        self._held_targets = held
        target = held.get(key)
        if target is None or target[0].size != tuple(size) or target[0].dtype != dtype:
            if target is not None:
                target[1].release()
                target[0].release()
            tex = self.ctx.texture(tuple(size), 4, dtype=dtype)
            tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
            tex.repeat_x = tex.repeat_y = False
            target = held[key] = (tex, self.ctx.framebuffer([tex]))
        return target


class DepthCopyPass(RenderPass):
    """Copy the view distance so that volume passes can read it while drawing into the colour."""

    name = "depth_copy"

    def execute(self, frame, targets: Targets) -> None:
        self.ctx.copy_framebuffer(targets.distance_copy_fbo, targets.distance_fbo)
        frame.resources["scene_distance"] = targets.distance_copy
