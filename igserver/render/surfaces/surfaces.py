"""Surfaces pass: shadow maps, the ground plane (when there is no sea) and the entities' models.

Per frame: the visible entities become instances (one camera-relative matrix per entity and glTF
node, articulated parts posed by name); the key light (sun, or moon when brighter) and the
brightest spot light render depth-only shadow maps of the casters, but only when something casts
and the light is up (FrameGraph philosophy: no casters, no shadow pass); then the ground plane and
every primitive are drawn once, instanced, opaque and masked first, blended last. A shadow map is
redrawn only when its projection or its casters changed (a still camera over still casters under
the same sun reuses it).
"""

from __future__ import annotations

import hashlib

import moderngl
import numpy as np

from ...scene.model import Entity, Scene
from .. import depth
from ..bindings import FRAME_UNITS, use_texture
from ..camera import CameraView, gl_matrix
from ..memo import Memo, view_key
from ..common.aerial_table import frame_aerial_table
from ..passes import RenderPass
from ..shaders import set_uniforms
from .gpu_models import SAMPLER_UNITS, ModelCache
from .instances import Batch, model_instances
from .shadow_fit import ShadowProjection, fit_directional, fit_spot
from .shadow_footprints import ground_shadow_rects

SHADOW_UNIT_KEY = FRAME_UNITS["SHADOW_KEY"]  # the shadow maps' units (read by common/shadows.glsl)
SHADOW_UNIT_SPOT = FRAME_UNITS["SHADOW_SPOT"]
SPOT_SHADOW_RESOLUTION = 1024
DEFAULT_SHADOW_TAPS = 4  # from `igserver quality surfaces`: 8 and 16 taps lower the error by < 1 % (docs/quality.md)
SUN_LIGHT, MOON_LIGHT = -1, -2
# Slope-scaled depth offset in the shadow pass (factor x max depth slope + units x depth ulp):
# removes acne on surfaces at a grazing light without a large constant bias (peter-panning).
# Negative: depth is reversed (render/depth.py), so "away from the light" is smaller.
POLYGON_OFFSET = (-2.0, -4.0)
# The ground is drawn in parts only when the casters' shadow footprints cover less than this share
# of the frame (their rectangles are drawn twice).
GROUND_SPLIT_MAX_AREA = 0.5


class SurfacesPass(RenderPass):
    name = "surfaces"

    def __init__(self, ctx, programs):
        super().__init__(ctx, programs)
        self.models = ModelCache(ctx)
        self._shadow_maps: dict[str, tuple[moderngl.Texture, moderngl.Framebuffer]] = {}
        self.last_shadow_passes: list[str] = []  # which shadow maps the last frame drew
        self.shadow_taps = DEFAULT_SHADOW_TAPS  # PCF taps per lookup (quality knob: igserver quality surfaces)
        self._shadow_signatures: dict[str, tuple] = {}  # what each map holds (skip redrawing it)
        self.shadow_maps_reused = 0
        self.ground_parts = 0  # draws of the ground plane last frame (1 + shadow footprints when split)
        # Study setting: aerial perspective per pixel (the reference) instead of the frame's table,
        # set by the table's error studies and tests on this pass; off in production.
        self.aerial_exact = False
        self._aerial_exact_frame = False  # this frame fell back to the per-pixel function
        self.memo = Memo()

    def needed(self, scene: Scene, view: CameraView) -> bool:
        return (scene.ground.enabled and not scene.ocean.enabled) or any(e.visible for e in scene.entities)

    # what the blended pass of the same view reads (render/multiview.py runs the views' passes interleaved)
    view_state = ("_key_shadow", "_bound_shadow_maps", "_aerial_exact_frame", "last_shadow_passes")

    # --- instances --------------------------------------------------------------------------
    def _instances(self, scene: Scene, view: CameraView) -> dict[str, Batch]:
        """The frame's batches, recomputed only when an input changes: the visible entities, the
        models they draw (a reloaded file is another model object), the view and the shadow range."""
        visible = tuple(e for e in scene.entities if e.visible)
        models = tuple((name, id(self.models.get(name))) for name in sorted({e.model for e in visible}))
        key = (visible, models, view_key(view), scene.shadows.distance)
        return self.memo.get("batches", key, lambda: self._batches(scene, view))

    def _batches(self, scene: Scene, view: CameraView) -> dict[str, Batch]:
        groups: dict[str, list[Entity]] = {}
        for entity in scene.entities:
            if entity.visible:
                groups.setdefault(entity.model, []).append(entity)
        batches: dict[str, Batch] = {}
        for name, entities in groups.items():
            model = self.models.get(name)
            if model is None or not model.primitives:
                continue
            rows, centres, radii = model_instances(entities, model, view)
            in_view = np.array([view.sphere_visible(c, r) for c, r in zip(centres, radii)])
            casts = np.linalg.norm(centres - view.position, axis=1) - radii < scene.shadows.distance
            batches[name] = Batch(model, {"view": rows[in_view], "shadow": rows[casts]},
                                  np.column_stack([centres[casts], radii[casts]]))
        return batches

    # --- shadows ----------------------------------------------------------------------------
    def _shadow_target(self, key: str, size: int):
        held = self._shadow_maps.get(key)
        if held is None or held[0].size != (size, size):
            if held is not None:
                held[1].release()
                held[0].release()
            self._shadow_signatures.pop(key, None)
            tex, _ = depth.float_depth_texture(self.ctx, (size, size))
            tex.compare_func = ">="  # lit where the receiver is at least as near the light (reversed depth)
            tex.filter = (moderngl.LINEAR, moderngl.LINEAR)  # hardware 2x2 PCF per tap
            tex.repeat_x = tex.repeat_y = False
            self._shadow_maps[key] = (tex, self.ctx.framebuffer(depth_attachment=tex))
        return self._shadow_maps[key]

    def _render_shadow_map(self, key: str, size: int, projection: ShadowProjection, batches,
                           fit_key=None) -> moderngl.Texture:
        """Draw the casters into the map, unless it already holds exactly this: same projection,
        same caster instances (camera-relative rows, so a moved camera redraws) and materials.
        ``fit_key``: the inputs of the projection and the batches, when they name them all (the
        signature is then computed once per change of them)."""
        tex, fbo = self._shadow_target(key, size)

        def signature_of():
            digest = hashlib.blake2b(np.asarray(projection.view_proj, dtype=np.float64).tobytes(), digest_size=16)
            for name, batch in sorted(batches.items()):
                digest.update(name.encode())
                digest.update(np.ascontiguousarray(batch.rows["shadow"]).tobytes())
            return (size, digest.digest())

        signature = signature_of() if fit_key is None else self.memo.get(f"{key}_shadow_signature", fit_key, signature_of)
        if self._shadow_signatures.get(key) == signature:
            self.shadow_maps_reused += 1
            return tex
        self._shadow_signatures[key] = signature
        fbo.use()
        fbo.clear(depth=depth.CLEAR_DEPTH)
        opaque = self.programs.program("surfaces/mesh.vert.glsl", "surfaces/mesh.frag.glsl", {"SHADOW_PASS": 1})
        tested = self.programs.program("surfaces/mesh.vert.glsl", "surfaces/mesh.frag.glsl",
                                       {"SHADOW_PASS": 1, "ALPHA_TEST": 1})
        for program in (opaque, tested):
            set_uniforms(program, {"u_light_view_proj": gl_matrix(projection.view_proj)})
            self._set_samplers(program)
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)
        # Same depth convention as the view (reversed, the renderer's NEAREST_WINS stays set).
        self.ctx.polygon_offset = POLYGON_OFFSET
        try:
            self._draw_batches(opaque, batches, "shadow", alpha_tested=False)
            self._draw_batches(tested, batches, "shadow", alpha_tested=True)
        finally:
            self.ctx.polygon_offset = (0.0, 0.0)
        return tex

    def _shadows(self, frame, batches, scene: Scene) -> dict:
        """Render the shadow maps this frame needs; return the receivers' uniforms."""
        uniforms = {"u_key_shadow_light": 0, "u_spot_shadow_light": -1,
                    "u_shadow_density": scene.shadows.density, "u_shadow_color": tuple(scene.shadows.color),
                    "u_shadow_softness": scene.shadows.softness,
                    "u_key_shadow_map": SHADOW_UNIT_KEY, "u_spot_shadow_map": SHADOW_UNIT_SPOT}
        self.last_shadow_passes = []
        self._key_shadow = None  # (direction toward the light, texel m, caster bounds) when drawn
        self._bound_shadow_maps = []  # (texture, unit): bound again for the late blended pass
        held = getattr(self, "_caster_bounds", None)  # kept with the batches object they come from
        if held is None or held[0] is not batches:
            held = self._caster_bounds = (batches, np.concatenate([b.caster_bounds for b in batches.values()]
                                                                  or [np.zeros((0, 4))]))
        bounds = held[1]
        if not scene.shadows.enabled or len(bounds) == 0:
            return uniforms
        view = frame.view
        key = self._key_light(frame)
        if key is not None:
            which, direction = key
            # The fit and what the map holds follow the casters (one batches value per change), the
            # light's direction, the camera's position and the map's size.
            fit_key = (self.memo.computed["batches"], tuple(np.asarray(direction, np.float64)),
                       view.position.tobytes(), scene.shadows.resolution)
            projection = self.memo.get("key_shadow_fit", fit_key, lambda: fit_directional(
                bounds[:, :3], bounds[:, 3], direction, view.position, scene.shadows.resolution,
                depth.zero_to_one(self.ctx)))
            tex = self._render_shadow_map("key", scene.shadows.resolution, projection, batches, fit_key)
            use_texture(tex, SHADOW_UNIT_KEY)
            self._bound_shadow_maps.append((tex, SHADOW_UNIT_KEY))
            uniforms.update({"u_key_shadow_light": which, "u_key_shadow_texel": projection.texel})
            uniforms["u_key_shadow_matrix"] = self.memo.get("key_shadow_matrix", fit_key,
                                                            lambda: gl_matrix(projection.map_matrix()))
            self._key_shadow = (np.asarray(direction, dtype=np.float64), projection.texel, bounds)
            self.last_shadow_passes.append("sun" if which == SUN_LIGHT else "moon")
        spot = self._shadow_spot(frame)
        if spot is not None:
            index, light = spot
            projection = fit_spot(view.relative(light.position), light.spot_dir, light.cos_outer, light.range,
                                  SPOT_SHADOW_RESOLUTION, depth.zero_to_one(self.ctx))
            tex = self._render_shadow_map("spot", SPOT_SHADOW_RESOLUTION, projection, batches, None)
            use_texture(tex, SHADOW_UNIT_SPOT)
            self._bound_shadow_maps.append((tex, SHADOW_UNIT_SPOT))
            uniforms.update({"u_spot_shadow_light": index, "u_spot_shadow_texel": projection.texel,
                             "u_spot_shadow_matrix": gl_matrix(projection.map_matrix())})
            self.last_shadow_passes.append("spot")
        return uniforms

    @staticmethod
    def _key_light(frame):
        """The directional light worth a shadow map: the sun by day, the moon on a moonlit night."""
        sun = float(np.max(frame.light.sun_illuminance))
        moon = float(np.max(frame.light.moon_illuminance))
        if sun > 0.0 and sun >= moon and frame.celestial.sun_elevation > -1.0:
            return SUN_LIGHT, frame.celestial.sun_dir
        if moon > 0.0 and frame.celestial.moon_elevation > -1.0:
            return MOON_LIGHT, frame.celestial.moon_dir
        return None

    @staticmethod
    def _shadow_spot(frame):
        """The brightest spot light (lights arrive brightest-at-the-camera first)."""
        for index, light in enumerate(frame.lights):
            if light.spot_dir is not None:
                return index, light
        return None

    # --- drawing ----------------------------------------------------------------------------
    @staticmethod
    def _set_samplers(program) -> None:
        set_uniforms(program, SAMPLER_UNITS)

    def _draw_batches(self, program, batches: dict[str, Batch], use: str, blended: bool | None = None,
                      alpha_tested: bool | None = None) -> None:
        """Draw the ``use`` instances of every primitive; ``blended`` / ``alpha_tested`` select
        primitives by alpha mode (BLEND; MASK or BLEND) when not None. A material's uniforms are
        set once for a run of draws with the same values, its textures once for a run with the same
        textures (draw_list groups them)."""
        values = textures = None
        for prim, mat, rows, count in self._draw_list(batches, use, blended, alpha_tested):
            if mat.uniform_state != values:
                set_uniforms(program, mat.uniforms)
                values = mat.uniform_state
            if mat.texture_set != textures:
                mat.bind()
                textures = mat.texture_set
            prim.draw_rows(program, use, rows, count)

    def _draw_list(self, batches: dict[str, Batch], use: str, blended, alpha_tested) -> list:
        """(primitive, material, instance rows as bytes, instance count) of the draws, kept with the batches object they
        were made from (batches are made anew when any of their inputs changes). Opaque draws are
        grouped by their material's textures (first-seen order, stable within a group), so a
        run of primitives with the same textures binds them once; blended ones keep the models'
        order (their blending order)."""
        held = getattr(self, "_draw_lists", None)
        if held is None or held[0] is not batches:
            held = self._draw_lists = (batches, {})
        key = (use, blended, alpha_tested)
        if key in held[1]:
            return held[1][key]
        draws = []
        for batch in batches.values():
            if len(batch.rows[use]) == 0:
                continue
            for p, prim in enumerate(batch.model.primitives):
                mode = prim.material.data.alpha_mode
                if blended is not None and (mode == 2) != blended:
                    continue
                if alpha_tested is not None and (mode != 0) != alpha_tested:
                    continue
                rows = batch.primitive_rows(use, p)
                draws.append((prim, prim.material, rows.tobytes(), len(rows)))
        if not blended:
            groups: dict[tuple, int] = {}
            for _, mat, _, _ in draws:
                groups.setdefault(mat.texture_set, len(groups))
            draws.sort(key=lambda d: groups[d[1].texture_set])  # stable: the models' order within a group
        held[1][key] = draws
        return draws

    def _receiver_defines(self, frame) -> dict:
        """The frame's light terms, and shadow lookups only for the maps this frame drew."""
        defines = dict(frame.defines)
        if self.aerial_exact or self._aerial_exact_frame:
            defines["AERIAL_EXACT"] = 1
        if self.last_shadow_passes:
            defines.update({"SURFACE_SHADOWS": 1, "SHADOW_TAPS": self.shadow_taps})
            if any(p in ("sun", "moon") for p in self.last_shadow_passes):
                defines["KEY_SHADOW_MAP"] = 1
            if "spot" in self.last_shadow_passes:
                defines["SPOT_SHADOW_MAP"] = 1
        return defines

    def execute(self, frame, targets) -> None:
        scene, view = frame.scene, frame.view
        batches = self._instances(scene, view)
        receiver_uniforms = self._shadows(frame, batches, scene)
        aerial = None if self.aerial_exact else frame_aerial_table(frame)
        self._aerial_exact_frame = aerial is None  # a camera high over the ground: per pixel
        receiver_uniforms.update(aerial or {})
        targets.scene_fbo.use()
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.ctx.disable(moderngl.BLEND | moderngl.CULL_FACE)
        if scene.ground.enabled and not scene.ocean.enabled:
            self._draw_ground(frame, targets, receiver_uniforms)
        if not any(len(batch.rows["view"]) for batch in batches.values()):
            return
        program = self.programs.program("surfaces/mesh.vert.glsl", "surfaces/mesh.frag.glsl", self._receiver_defines(frame))
        set_uniforms(program, frame.uniforms)
        set_uniforms(program, receiver_uniforms)
        self._set_samplers(program)
        self._draw_batches(program, batches, "view", blended=False)
        if self._draw_list(batches, "view", True, None):
            # Blended surfaces come later, over the water and the sky (BlendedSurfacesPass).
            frame.resources["blended_surfaces"] = lambda: self._draw_blended(frame, targets, program, batches)

    def _draw_ground(self, frame, targets, receiver_uniforms: dict) -> None:
        """The ground plane (surfaces/plane.glsl), a full-screen pass. The key light's shadows fall on
        it only within the casters' footprints (``ground_shadow_rects``); when those cover little of
        the frame, the plane is drawn without the key map's lookup and then again, with it, inside
        them (the same depth, drawn over). The lookup's percentage-closer taps were about half of the
        plane's CPU (the snow scene); on llvmpipe a run-time test would still pay for them."""
        scene, view = frame.scene, frame.view
        defines = self._receiver_defines(frame)
        parts = [(defines, [None])]  # (program defines, the scissor boxes it is drawn in)
        if "KEY_SHADOW_MAP" in defines and self._key_shadow is not None:
            direction, texel, bounds = self._key_shadow
            # The lookup reaches the PCF disk (softness, at least half a texel), the normal offset
            # (2 texels) and the bilinear compare (1) past the caster's own shadow.
            margin = max(scene.shadows.softness, 0.5 * texel) + 3.0 * texel
            rects = ground_shadow_rects(bounds, direction, scene.ground.level, margin, view, targets.size)
            width, height = targets.size
            if rects is not None and sum(w * h for _, _, w, h in rects) < GROUND_SPLIT_MAX_AREA * width * height:
                plain = {k: v for k, v in defines.items() if k != "KEY_SHADOW_MAP"}
                if "SPOT_SHADOW_MAP" not in plain:
                    plain = {k: v for k, v in plain.items() if k not in ("SURFACE_SHADOWS", "SHADOW_TAPS")}
                parts = [(plain, [None]), (defines, rects)]
        fbo = targets.scene_fbo
        try:
            for i, (part_defines, scissors) in enumerate(parts):
                program = self.programs.program("common/fullscreen.vert.glsl", "surfaces/plane.glsl", part_defines)
                set_uniforms(program, frame.uniforms)
                set_uniforms(program, receiver_uniforms)
                set_uniforms(program, {"u_plane_height": scene.ground.level - float(view.position[2]),
                                       "u_base_color": tuple(scene.ground.color), "u_roughness": scene.ground.roughness})
                if i == 1:
                    self.ctx.depth_func = depth.SAME_OR_NEARER
                for scissor in scissors:
                    fbo.scissor = scissor
                    self.fullscreen(program)
        finally:
            fbo.scissor = None
            self.ctx.depth_func = depth.NEAREST_WINS
        self.ground_parts = sum(len(scissors) for _, scissors in parts)

    def _draw_blended(self, frame, targets, program, batches) -> None:
        """The blended primitives over everything opaque, the water and the sky: colour only, depth
        tested but not written (moderngl keeps the depth mask on the framebuffer: the context
        attribute once set here was ignored, and the panes wrote depth)."""
        for tex, unit in self._bound_shadow_maps:
            use_texture(tex, unit)
        table = frame.resources.get("aerial_table")
        if table is not None and not self._aerial_exact_frame:
            table.bind()
        targets.color_fbo.depth_mask = False
        targets.color_fbo.use()
        self.ctx.enable(moderngl.DEPTH_TEST | moderngl.BLEND)
        self.ctx.disable(moderngl.CULL_FACE)
        self.ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
        try:
            self._draw_batches(program, batches, "view", blended=True)
        finally:
            targets.color_fbo.depth_mask = True
            self.ctx.disable(moderngl.BLEND)
            targets.scene_fbo.use()
