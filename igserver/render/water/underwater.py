"""The sea from under its surface (docs/water.md#under-water): when the eye is below the local surface
(the host's height query at its xy, the same sum of waves the mesh draws), the water program is
compiled with WATER_UNDERWATER (water/underwater.glsl: Snell's window, total internal reflection,
Jerlov type II attenuation and scattering, the bed) and a full-screen pass (water/underwater.frag.glsl)
fills what the mesh leaves: the column, the bed with the sun's caustics, the surface missed by the near
plane; before the sea, two blended passes show the objects the surfaces pass drew through the water
(water/underwater_objects.frag.glsl). With the eye in the air only one thing here may run: an eye close
to the surface may see past the mesh's underside, where the water body is filled in (_fill_under_crests)."""

from __future__ import annotations

import moderngl
import numpy as np

from ...scene.model import Scene
from ...water.bathymetry import depth_at
from ...water.surface import SeaSurface
from ..bindings import use_texture
from ..frame import local_light_defines
from ..shaders import set_uniforms
from .lod import LodSelection
from .sea_inputs import FIELD_UNIT  # the objects' pass borrows it for the frame's distance (then the field again)

BED_SLOPE_STEP = 10.0  # m: the bed's plane is fitted to the depths this far either side of the eye
DEEP_BED = 1e4  # m below the eye: no bed seen (the water is opaque past ~110 m)


def eye_depth(scene: Scene, sea: SeaSurface, eye) -> float:
    """Metres of water above the eye (< 0: the eye is in the air): the surface height at the eye's xy
    (``SeaSurface.query``) less the eye's height above the mean level."""
    surface = float(sea.query(np.asarray(eye[:2], dtype=np.float64)[None], scene.time.sim_time)["height"][0])
    return surface - (float(eye[2]) - scene.ocean.level)


def bed_plane(scene: Scene, eye) -> tuple[float, float, float]:
    """The bed near the eye as the plane z = a + b x + c y in camera-relative metres: the bathymetry's
    depth at the eye and its slope over ±BED_SLOPE_STEP (exact for the plane beach, uniform depth
    gives a level bed; deeper than DEEP_BED is no bed)."""
    bathy = scene.ocean.bathymetry
    x, y, z = (float(v) for v in eye)
    s = BED_SLOPE_STEP
    pts = np.array([[x, y], [x + s, y], [x - s, y], [x, y + s], [x, y - s]])
    d = depth_at(bathy, pts)
    level_z = scene.ocean.level - z
    depth0 = float(d[0])
    if depth0 > DEEP_BED:
        return (level_z - 2.0 * DEEP_BED, 0.0, 0.0)
    # the bed's height is -depth: its slope is minus the depth's
    return (level_z - depth0, -float(d[1] - d[2]) / (2.0 * s), -float(d[3] - d[4]) / (2.0 * s))


def underwater_uniforms(scene: Scene, eye, reach: float) -> dict:
    """The values of water/underwater.glsl's uniforms (and the fill's highest-crest reach, m)."""
    return {"u_uw_bed": bed_plane(scene, eye), "u_uw_level_z": float(scene.ocean.level - float(eye[2])),
            "u_uw_reach": float(reach)}


class UnderwaterDraws:
    """The water pass's draws with the eye below the surface or close above it (a mixin of
    water.WaterPass: its programs, context, atmosphere define, field textures and this frame's
    ``_underwater`` uniforms)."""

    @staticmethod
    def _submerged(frame, sea: SeaSurface, selection: LodSelection) -> bool:
        """Whether the eye is below the sea's surface at its xy (underwater.eye_depth); an eye higher
        above the mean level than every crest is not (no query)."""
        height = float(frame.view.position[2]) - frame.scene.ocean.level
        if height > 1.05 * selection.error_sphere:
            return False
        return eye_depth(frame.scene, sea, frame.view.position) > 0.0

    def _fill_underwater(self, table_uniforms: dict) -> None:
        """Under water: what the mesh does not cover (water/underwater.frag.glsl), after the mesh."""
        program = self.programs.program("common/fullscreen.vert.glsl", "water/underwater.frag.glsl",
                                        self._atmosphere_define())
        if not self.caustics:  # the bed evenly lit (the tests' reference)
            program = self.programs.program("common/fullscreen.vert.glsl", "water/underwater.frag.glsl",
                                            {**self._atmosphere_define(), "UW_EVEN_BED": 1})
        set_uniforms(program, self._underwater)
        set_uniforms(program, table_uniforms)
        set_uniforms(program, {"u_detail_map": self._detail_map_values,
                               "u_uw_caustic_maps": min(self._maps_written, 2)})
        self.fullscreen(program)

    def _objects_under_water(self, targets, table_uniforms: dict, sea: SeaSurface) -> None:
        """Under water, before the sea is drawn: what the surfaces pass drew seen through the water
        (water/underwater_objects.frag.glsl), the colour times the transmittance, then plus the light
        scattered in (two blended full-screen passes over the colour alone, reading the distance)."""
        program = self.programs.program("common/fullscreen.vert.glsl", "water/underwater_objects.frag.glsl",
                                        self._atmosphere_define())
        set_uniforms(program, self._underwater)
        set_uniforms(program, table_uniforms)
        use_texture(targets.distance, FIELD_UNIT)
        set_uniforms(program, {"u_uw_distance": FIELD_UNIT})
        targets.color_fbo.use()
        self.ctx.disable(moderngl.DEPTH_TEST)
        self.ctx.enable(moderngl.BLEND)
        for step, func in ((0, (moderngl.ZERO, moderngl.SRC_COLOR)), (1, (moderngl.ONE, moderngl.ONE))):
            self.ctx.blend_func = func
            set_uniforms(program, {"u_uw_pass": step})
            self.fullscreen(program)
        self.ctx.blend_func = moderngl.DEFAULT_BLENDING
        self.ctx.disable(moderngl.BLEND)
        if sea.field is not None:  # the distance borrowed the field's unit
            use_texture(self._field_tex[0], FIELD_UNIT)

    @staticmethod
    def _sees_under_mesh(frame, sea: SeaSurface, selection: LodSelection) -> bool:
        """Whether the camera may see the underside of the mesh or past it: when it is below the
        surface (a crest over it) or nearer to it than the near plane. A camera above the surface
        right below it (the host's height query at its xy, less what the finest mesh level leaves out)
        by more than the near distance cannot: the sea is a height field out to the horizon, so every
        ray going down meets its top side before passing beneath it."""
        sphere = selection.error_sphere
        height = float(frame.view.position[2]) - frame.scene.ocean.level
        if height > 1.05 * sphere + frame.view.near:
            return False
        w = sea.waves
        x = w.k * selection.finest_spacing  # mesh deviation near the camera: interpolation + faded waves
        mesh_error = float(np.sum(w.amplitude * np.minimum(1.0, x * x / 8.0))) * (
            float(np.max(sea.field.factor)) if sea.field is not None else 1.0)
        surface = float(sea.query(np.asarray(frame.view.position[:2])[None], frame.scene.time.sim_time)["height"][0])
        return height - surface <= frame.view.near + mesh_error + 0.05

    def _fill_under_crests(self, frame, selection: LodSelection, table_uniforms: dict) -> None:
        """Rays that pass under the mesh (``_sees_under_mesh``) meet the water body: draw the sphere
        below every trough (level − ΣA, no near clip) in deep-water colour; the depth test keeps the
        mesh wherever it is nearer. Only then: it costs a full-screen pass."""
        if self._underwater is not None:  # the eye below the surface: the water column and the bed instead
            self._fill_underwater(table_uniforms)
            return
        sphere = selection.error_sphere
        height = float(frame.view.position[2]) - frame.scene.ocean.level
        program = self.programs.program("common/fullscreen.vert.glsl", "water/body.frag.glsl",
                                        {**local_light_defines(frame.lights), **self._atmosphere_define()})
        set_uniforms(program, frame.uniforms)
        set_uniforms(program, table_uniforms)
        set_uniforms(program, {"u_plane_height": -height - 1.05 * sphere})
        self.fullscreen(program)
