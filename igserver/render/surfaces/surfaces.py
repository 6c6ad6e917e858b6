"""Surfaces pass: the ground plane (when there is no sea) and the entities' meshes."""

from __future__ import annotations

import math

import moderngl
import numpy as np

from ...scene.model import Scene
from ..camera import CameraView, body_to_world, gl_matrix
from ..passes import RenderPass
from ..shaders import set_uniforms
from .models import MODELS, unit_cube


def entity_parts(scene: Scene, view: CameraView):
    """Yield (camera-relative model matrix, normal matrix, colour, metallic, roughness) per box."""
    for entity in scene.entities:
        rot = body_to_world(entity.heading, entity.pitch, entity.roll)
        scale = np.asarray(entity.scale)
        origin = view.relative(entity.position)  # float64 subtraction
        radius = float(np.linalg.norm(scale)) * 2.0
        if not view.sphere_visible(entity.position, radius):
            continue
        for centre, half, shade in MODELS[entity.model]:
            model = np.eye(4)
            model[:3, :3] = rot @ np.diag(scale * np.asarray(half))
            model[:3, 3] = origin + rot @ (scale * np.asarray(centre))
            normal = np.linalg.inv(model[:3, :3]).T
            colour = np.clip(np.asarray(entity.color) * shade, 0.0, 1.0)
            yield model, normal, colour, entity.metallic, entity.roughness


class SurfacesPass(RenderPass):
    name = "surfaces"

    def __init__(self, ctx, programs):
        super().__init__(ctx, programs)
        self._cube = None

    def needed(self, scene: Scene, view: CameraView) -> bool:
        return (scene.ground.enabled and not scene.ocean.enabled) or bool(scene.entities)

    def execute(self, frame, targets) -> None:
        scene, view = frame.scene, frame.view
        targets.scene_fbo.use()
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.disable(moderngl.BLEND | moderngl.CULL_FACE)
        if scene.ground.enabled and not scene.ocean.enabled:
            program = self.programs.program("common/fullscreen.vert.glsl", "surfaces/plane.glsl")
            set_uniforms(program, frame.uniforms)
            set_uniforms(program, {
                "u_plane_height": scene.ground.level - float(view.position[2]),
                "u_base_color": tuple(scene.ground.color),
                "u_roughness": scene.ground.roughness,
            })
            self.fullscreen(program)
        if scene.entities:
            self._draw_entities(frame)

    def _draw_entities(self, frame) -> None:
        program = self.programs.program("surfaces/mesh.vert.glsl", "surfaces/mesh.frag.glsl")
        set_uniforms(program, frame.uniforms)
        if self._cube is None:
            vbo = self.ctx.buffer(unit_cube().tobytes())
            self._cube = self.ctx.vertex_array(program, [(vbo, "3f 3f", "in_position", "in_normal")])
        for model, normal, colour, metallic, roughness in entity_parts(frame.scene, frame.view):
            program["u_model"].write(gl_matrix(model))
            program["u_normal_matrix"].write(gl_matrix(normal))
            set_uniforms(program, {"u_base_color": tuple(float(c) for c in colour),
                                   "u_metallic": metallic, "u_roughness": roughness})
            self._cube.render(moderngl.TRIANGLES)
