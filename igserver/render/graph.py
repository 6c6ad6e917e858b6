"""FrameGraph: per frame, the list of passes this scene needs, in order (docs/design.md#frame-graph).

Order: opaque surfaces (ground/entities), water, sky (fills what nothing covered), blended surfaces
(glTF alphaMode BLEND, over all of those), depth copy (only when a later pass reads scene distance),
volumes, precipitation, post.
"""

from __future__ import annotations

import moderngl

from ..scene.model import Scene
from .camera import CameraView, make_view
from .passes import DepthCopyPass, RenderPass
from .post.post import PostPass
from .precip.precip import PrecipPass
from .shaders import ProgramCache
from .sky.sky import SkyPass
from .surfaces.blended import BlendedSurfacesPass
from .surfaces.surfaces import SurfacesPass
from .volumes.volumes import VolumesPass
from .water.water import WaterPass

# The pipelines in drawing order (a new one is one entry here); DepthCopyPass is inserted before the
# first reader.
PASS_TYPES: list[type[RenderPass]] = [SurfacesPass, WaterPass, SkyPass, BlendedSurfacesPass, VolumesPass, PrecipPass,
                                      PostPass]


class FrameGraph:
    def __init__(self, ctx: moderngl.Context, programs: ProgramCache):
        self.passes: dict[str, RenderPass] = {}
        for pass_type in [DepthCopyPass, *PASS_TYPES]:
            self.passes[pass_type.name] = pass_type(ctx, programs)

    def plan(self, scene: Scene, view: CameraView | None = None) -> list[str]:
        view = view or make_view(scene.camera)
        names: list[str] = []
        for pass_type in PASS_TYPES:
            render_pass = self.passes[pass_type.name]
            if not render_pass.needed(scene, view):
                continue
            if render_pass.reads_scene_distance and "depth_copy" not in names:
                names.append("depth_copy")
            names.append(render_pass.name)
        return names


def plan_passes(scene: Scene) -> list[str]:
    """Pass list without a GL context (tests, tools): uses the passes' class-level logic."""
    view = make_view(scene.camera)
    names: list[str] = []
    for pass_type in PASS_TYPES:
        if not pass_type.needed(pass_type.__new__(pass_type), scene, view):
            continue
        if pass_type.reads_scene_distance and "depth_copy" not in names:
            names.append("depth_copy")
        names.append(pass_type.name)
    return names
