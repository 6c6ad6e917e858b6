"""Volumes pass: fire and smoke effects, modelled into 3D textures and ray-marched (docs/design.md#fire-and-smoke).

Per visible volume (effects.visible_volumes: active or fading, non-zero size, in the frustum):
  1. modelling: a compute shader writes the effect's 3D texture (rgba16f, colour + density) from
     its revolved profile and the turbulence; 2. rendering: the back faces of the container's slabs
     are drawn into the HDR colour with premultiplied blending (one instanced draw a volume, its
     constants one record of the march block: march.py MarchPlan, march_block.py); each fragment
     marches the texture (march.frag.glsl) and stops at the copied scene distance.

The modelling stage, and when it runs: modelling.py (VolumeModelling, a base of the pass); the knobs
and quality presets: settings.py.

Reduced-resolution march (``scale`` 2 or 4): the scene distance is reduced to the nearest of each
block (downsample.frag.glsl), the volumes are marched into a low-resolution premultiplied target,
and a depth-aware upsampling blends it into the frame (upsample.frag.glsl). When the scale changes
in a running stream (the auto preset moving a rung), the old and new marches are both drawn for
SCALE_FADE_FRAMES frames, each pixel showing one of them by a fixed dither against a weight going
from the old to the new (a dissolve), so the switch fades instead of popping.
"""

from __future__ import annotations

import math

import moderngl
import numpy as np

from ..bindings import BLOCKS, use_texture, write_buffer
from ...scene.model import Scene
from ..camera import CameraView
from ..memo import Memo, view_key
from ..passes import RenderPass
from ..post.exposure import MAX_STREAM_DT
from ..shaders import set_uniforms
from .effects import fade_level, visible_volumes
from . import march_block
from .fire_lights import flame_light
from .march import MarchPlan
from .modelling import VolumeModelling
from .settings import VolumeSettings

SCALE_FADE_FRAMES = 8  # frames over which a changed march resolution cross-fades (~0.27 s at 30 Hz)


def volumes_needed(scene: Scene, view: CameraView) -> bool:
    return bool(scene.effects) and bool(visible_volumes(scene, view))


def _unit_cube_corners() -> np.ndarray:
    """36 vertices of [0,1]^3, counter-clockwise seen from outside."""
    c = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], dtype=np.float32)
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    tris = [c[[a, b, cc, a, cc, d]] for a, b, cc, d in quads]
    return np.concatenate(tris).astype(np.float32)


class VolumesPass(VolumeModelling, RenderPass):
    name = "volumes"
    reads_scene_distance = True
    preset_pipeline = "volumes"
    view_state = ("_scale_state", "_fade")  # each view's march scale and its cross-fade (_layers)
    _scale_state = (None, None)
    _fade = None

    def __init__(self, ctx, programs):
        super().__init__(ctx, programs)
        self.memo = Memo()
        self.stats = {"modelled": 0, "drawn": 0, "voxels": 0}
        self._cube_vbo = None
        self._vaos: dict = {}
        self._frame = 0
        self._low: dict = {}  # size -> (colour, distance, colour fbo, distance fbo) of the reduced march
        self._low_last = None
        self._scale_state: tuple[int | None, float | None] = (None, None)  # last march scale, its sim_time
        self._fade: tuple[int, int] | None = None  # (old scale, frames left) of a running cross-fade
        self._programs: dict[tuple, object] = {}  # the pass's variants (_program)
        self._block = None  # the march plan's records (march_block.py), grown when a plan needs more
        self._block_align = int(ctx.info.get("GL_UNIFORM_BUFFER_OFFSET_ALIGNMENT", 256) or 256)

    def needed(self, scene: Scene, view: CameraView) -> bool:
        if not hasattr(self, "memo"):  # graph.plan_passes asks an instance made without a context
            return volumes_needed(scene, view)
        return bool(scene.effects) and bool(self._visible(scene, view)[1])

    def _visible(self, scene: Scene, view: CameraView) -> tuple[tuple, list]:
        """(key, visible_volumes): the volumes follow the effects, their fade levels now, the wind
        that bends them and the view; kept while those are the same (the frame graph asks before the
        pass draws)."""
        t = scene.time.sim_time
        key = (tuple(scene.effects), tuple(fade_level(e, t) for e in scene.effects), scene.weather.wind_speed,
               scene.weather.wind_direction, view_key(view))
        return key, self.memo.get("visible_volumes", key, lambda: visible_volumes(scene, view))

    # -- rendering ---------------------------------------------------------------------------

    def _vao(self, program):
        if self._cube_vbo is None:
            self._cube_vbo = self.ctx.buffer(_unit_cube_corners().tobytes())
        vao = self._vaos.get(id(program))
        if vao is None:
            vao = self.ctx.vertex_array(program, [(self._cube_vbo, "3f", "in_position")])
            self._vaos[id(program)] = vao
        return vao

    def _low_targets(self, size: tuple[int, int]):
        """Low-resolution colour + distance targets of the reduced-resolution march (one set per
        size: two are in use while the march resolution cross-fades)."""
        held = self._low.get(size)
        if held is None:
            for old in [k for k in self._low if k != self._low_last]:
                for obj in self._low.pop(old):
                    obj.release()
            color = self.ctx.texture(size, 4, dtype="f2")
            distance = self.ctx.texture(size, 1, dtype="f4")
            for tex in (color, distance):
                tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
                tex.repeat_x = tex.repeat_y = False
            color.filter = (moderngl.LINEAR, moderngl.LINEAR)  # the upsample's one filtered fetch
            held = self._low[size] = (color, distance, self.ctx.framebuffer([color]), self.ctx.framebuffer([distance]))
        self._low_last = size
        return held

    def _layers(self, scale: int, sim_time: float) -> list[tuple[int, tuple[float, float]]]:
        """(march scale, dither range) of this frame's layers. When the scale changes in a running
        stream (auto quality moving a rung), the old and the new march dissolve into each other
        over SCALE_FADE_FRAMES frames instead of popping (a pixel shows the new one when its
        dither value is below the weight w, else the old); a re-render or a jump shows the new one."""
        last_scale, last_time = self._scale_state
        self._scale_state = (scale, sim_time)
        dt = sim_time - last_time if last_time is not None else 0.0
        streaming = 0.0 < dt <= MAX_STREAM_DT
        if last_scale is not None and last_scale != scale and streaming:
            self._fade = (last_scale, SCALE_FADE_FRAMES)
        if self._fade is None or not streaming or self._fade[0] == scale:
            self._fade = None
            return [(scale, (0.0, 1.0))]
        old, left = self._fade
        w = 1.0 - left / (SCALE_FADE_FRAMES + 1)
        self._fade = (old, left - 1) if left > 1 else None
        return [(old, (w, 1.0)), (scale, (0.0, w))]

    def execute(self, frame, targets) -> None:
        scene, view = frame.scene, frame.view
        settings = self.knobs(frame)
        self._frame += 1
        self.stats = {"modelled": 0, "drawn": 0, "voxels": 0}
        if frame.resources.get("eye_under_water"):  # the water pass put the eye below the surface: fire and
            return  # smoke are in the air, the water hides them (docs/water.md#under-water)
        # The march's plan (texture sizes, boxes, constants) follows the visible volumes and the knobs.
        key, volumes = self._visible(scene, view)
        plan = self.memo.get("march_plan", (key, settings), lambda: MarchPlan(volumes, scene, view, settings).pack(
            scene, view, settings, self._block_align))
        textures = [self._models_for(plan, i, frame, settings) for i in range(len(volumes))]
        scale = max(max(int(settings.scale), 1), plan.lod_scale)
        self.stats["scale"] = scale
        self._write_block(plan, scene, textures)
        for scale, dither in self._layers(scale, scene.time.sim_time):
            self._draw_layer(frame, targets, plan, textures, settings, scale, dither)
        self._evict()

    def _write_block(self, plan: "MarchPlan", scene: Scene, textures) -> None:
        """The plan's records with this frame's values - the keyframe blend, the start jitter's
        shift, the glow intensities (flicker) - into the block's buffer (one write)."""
        if not textures:
            return
        records = np.frombuffer(plan.records, np.float32).reshape(len(textures), -1).copy()
        records[:, march_block.BLEND] = [blend for _, _, blend in textures]
        records[:, march_block.JITTER] = (scene.host_frame * 0.6180339887) % 1.0  # golden-ratio sequence per frame
        for i, effect, lit in plan.glows:
            light = flame_light(lit, effect, scene.time.sim_time)
            if light is not None:
                records[i, march_block.GLOW:march_block.GLOW + 3] = light.color
        data = records.tobytes()
        if self._block is None or self._block.size < len(data):
            if self._block is not None:
                self._block.release()
            self._block = self.ctx.buffer(reserve=max(len(data), plan.stride) * 2, dynamic=True)
        write_buffer(self._block, data)

    def _draw_layer(self, frame, targets, plan: "MarchPlan", textures, settings: VolumeSettings, scale: int,
                    dither: tuple[float, float]) -> None:
        """March at 1 / ``scale`` resolution and composite into the frame's pixels whose dither
        value is in ``dither`` (a cross-fade layer; [0, 1) otherwise)."""
        distance = frame.resources["scene_distance"]
        if scale > 1:
            width, height = targets.size
            low_size = (-(-width // scale), -(-height // scale))
            low_color, low_distance, color_fbo, distance_fbo = self._low_targets(low_size)
            # Full-resolution work only where the boxes are (the upsample reads one low-res texel
            # around each pixel: the low-resolution rectangle is padded by two).
            x, y, w, h = plan.screen_rect(frame.view, width, height, pad=2 * scale)
            low_rect = (x // scale, y // scale, -(-w // scale) + 2, -(-h // scale) + 2)
            self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
            distance_fbo.use()
            distance_fbo.scissor = low_rect
            down = self._program(("down", scale), lambda: self.programs.program(
                "common/fullscreen.vert.glsl", "volumes/downsample.frag.glsl", {"SCALE": scale}))
            set_uniforms(down, {"u_scene_distance": 1})
            use_texture(distance, 1)
            self.fullscreen(down)
            distance_fbo.scissor = None
            color_fbo.use()
            color_fbo.clear(0.0, 0.0, 0.0, 0.0)
            self._march(frame, plan, textures, settings, low_distance, low_size[1], (0.0, 1.0))
            targets.color_fbo.use()  # (blending as the march left it: ONE, ONE_MINUS_SRC_ALPHA)
            targets.color_fbo.scissor = (x, y, w, h)
            fade = tuple(dither) != (0.0, 1.0)
            up = self._program(("up", fade), lambda: self.programs.program(
                "common/fullscreen.vert.glsl", "volumes/upsample.frag.glsl", {"LAYER_FADE": 1} if fade else None))
            set_uniforms(up, {"u_volume_color": 0, "u_volume_distance": 2, "u_scene_distance": 1, "u_scale": scale,
                              "u_volumes_far": plan.far, "u_layer_range": dither})
            use_texture(low_color, 0)
            use_texture(distance, 1)
            use_texture(low_distance, 2)
            self.fullscreen(up)
            targets.color_fbo.scissor = None
            self.ctx.disable(moderngl.BLEND)
        else:
            targets.color_fbo.use()
            self.ctx.disable(moderngl.DEPTH_TEST)
            self._march(frame, plan, textures, settings, distance, targets.size[1], dither)
            self.ctx.disable(moderngl.BLEND)

    def _march(self, frame, plan: "MarchPlan", textures, settings: VolumeSettings, distance, march_height: int,
               dither: tuple[float, float]) -> None:
        """Draw every volume's slabs into the bound framebuffer (premultiplied, far to near) at the
        pixels whose dither value is in ``dither``; ``march_height``: its height in pixels (for
        the footprint of a pixel). A volume is one instanced draw of its slabs, its constants its
        record of the block (march_block.py). Depth testing off before; blending
        (ONE, ONE_MINUS_SRC_ALPHA) left on after."""
        view = frame.view
        self.ctx.enable(moderngl.BLEND | moderngl.CULL_FACE)
        self.ctx.front_face = "ccw"
        self.ctx.cull_face = "front"
        self.ctx.blend_func = moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA
        use_texture(distance, 1)
        _, _, bottom, top = view.tangents
        # The frame's aerial-perspective table when the surfaces filled it this frame: one lookup a
        # pixel instead of the atmosphere per pixel (a tenth of the close fire's march); else per pixel.
        table = frame.resources.get("aerial_table")
        aerial = None
        if table is not None:
            table.bind()
            aerial = table.uniforms()
        self.stats["aerial_table"] = aerial is not None
        per_frame = {
            "u_volume": 0, "u_volume_next": 2, "u_scene_distance": 1,
            "u_pixel_angle": (math.atan(top) - math.atan(bottom)) / max(march_height, 1),  # rad per march pixel
            "u_layer_range": dither,
        }
        programs = {}
        for i, (tex, tex_next, _) in enumerate(textures):
            smoke = plan.smoke[i]
            program = programs.get(smoke)
            if program is None:
                variant = (smoke, aerial is None, settings.model_hz > 0.0, tuple(dither) != (0.0, 1.0))
                program = programs[smoke] = self._program(("march", *variant), lambda: self._march_program(*variant))
                set_uniforms(program, frame.uniforms)
                set_uniforms(program, {**aerial, **per_frame} if aerial else per_frame)
            self._block.bind_to_uniform_block(BLOCKS["VOLUME"], offset=i * plan.stride, size=march_block.RECORD_BYTES)
            use_texture(tex, 0)
            use_texture(tex_next, 2)
            # The container as slabs (Volume.slabs), each marching its own stretch of the ray, drawn
            # farthest first (MarchPlan): the ONE, ONE_MINUS_SRC_ALPHA blend composes them as one
            # front-to-back march would.
            self._vao(program).render(moderngl.TRIANGLES, instances=plan.slab_counts[i])
            self.stats["drawn"] += 1
        self.stats["slabs"] = self.stats.get("slabs", 0) + sum(plan.slab_counts)
        self.ctx.disable(moderngl.CULL_FACE)
        self.ctx.cull_face = "back"

    def _march_program(self, smoke: bool, exact: bool, blend: bool, fade: bool):
        defines = {"SMOKE": 1} if smoke else {}
        if exact:
            defines["AERIAL_EXACT"] = 1
        if blend:
            defines["BLEND"] = 1
        if fade:
            defines["LAYER_FADE"] = 1  # a cross-fade layer: the per-pixel dither and discard
        return self.programs.program("volumes/march.vert.glsl", "volumes/march.frag.glsl", defines or None)

    def _program(self, variant: tuple, make):
        """The pass's program of ``variant`` (a few flags), from the program cache once."""
        program = self._programs.get(variant)
        if program is None:
            program = self._programs[variant] = make()
        return program


__all__ = ["VolumesPass", "volumes_needed"]
