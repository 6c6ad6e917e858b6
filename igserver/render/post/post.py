"""Post pass: metering of the rendered frame, exposure (eye adaptation), mesopic vision, tone
mapping, sRGB encoding and dithering into the 8-bit output target.

The passes render pre-exposed with a provisional exposure (frame.py's estimate of the view from the
sky-view table); here the frame itself is metered (block means of its luminance, meter.glsl) and
the exposure the eye would settle on is chosen in display space (post/exposure.py), eased by the
renderer's adaptation state, and applied as a correction factor before the tone curve. So the
meter sees everything that is drawn (sea, fires, lamps, fog) and the displayed brightness follows
the light.
"""

from __future__ import annotations

import math

import moderngl
import numpy as np

from ...weather import precipitation_extinction
from ..bindings import PASS_UNITS, use_texture
from ..camera import cone_on_screen
from ..memo import view_key
from ..passes import RenderPass
from ..shaders import set_uniforms
from .exposure import display_metered_ev100, displayed, exposure_of_ev100
from .halos import HaloTable, halo_radius, table_uniforms
from .meter_lag import MeterTicket, copy_for, finite_cells

METER_CELLS = 32  # the meter works on at most this many cells across (32 x 18 at 16:9)
MAX_HALOS = 8
HALO_TABLE_UNIT = PASS_UNITS["HALO_TABLE"]
HALO_SCALE = 2  # halos at half resolution, depth-aware upsampling (post/halos.frag.glsl): 65.9 dB vs full
HALO_MIN_BETA = 1e-4  # 1/m (visibility < ~40 km): thinner air shows no halo worth 8 samples a pixel


# A light's halo is drawn when it can move a displayed pixel value by HALO_INVISIBLE (half an
# 8-bit step) or more somewhere on screen: under DISPLAY_SLOPE, the steepest slope of the displayed
# value in the exposed linear value (the ACES fit then sRGB), its radiance after exposure must stay
# below HALO_INVISIBLE / DISPLAY_SLOPE.
HALO_INVISIBLE = 0.5 / 255.0
_LINEAR = np.geomspace(1e-7, 64.0, 20000)
DISPLAY_SLOPE = float(np.max(np.diff(displayed(_LINEAR)) / np.diff(_LINEAR)))


def glow_extinction(scene, beta: float) -> float:
    """1/m, the part of the layer's extinction ``beta`` at the camera that makes lights glow. Rain
    drops and snow flakes are large against the wavelength: of their extinction (efficiency 2,
    weather.precipitation_extinction) half is diffraction into ~lambda/D = 0.5 um / 1 mm = 0.03 deg
    around the beam, inside the light's own pixel: it neither lights the air around a lamp or a
    fire nor dims the paths of the glow. The glow sees the air's extinction and the other half
    (reflection and refraction by the drops). At most half of ``beta`` goes: a host whose
    visibility already holds the rain may send less extinction than the rain alone has."""
    p = scene.weather.precipitation
    return max(beta - 0.5 * precipitation_extinction(p.type, p.rate), 0.5 * beta)


def halo_uniforms(frame, exposure_correction: float = 1.0) -> dict:
    """The brightest lights whose fog halos can show (tonemap.glsl), with the fog at the camera.
    ``exposure_correction``: the metered exposure over the frame's provisional one (the post pass
    applies both)."""
    haze = frame.resources.get("haze")
    if frame.resources.get("eye_under_water"):  # the lights' fog halos are in the air, not in the water
        return {"u_halo_count": 0}
    if haze is None or not frame.lights:
        return {"u_halo_count": 0}
    h = frame.camera_altitude - frame.scene.location.altitude
    beta = glow_extinction(frame.scene, float(haze.beta[1] * haze.density(h)))
    if beta < HALO_MIN_BETA:
        return {"u_halo_count": 0}
    # A light shows a halo when the cone of view rays where its halo's radiance can reach the
    # invisible threshold (halos.halo_radius: a bound over every surface distance) meets the frame:
    # no halo for a fire by day or a lamp in clear air, none for a light whose glow lies off screen.
    threshold = HALO_INVISIBLE / DISPLAY_SLOPE / max(frame.exposure * exposure_correction, 1e-30)
    view = frame.view
    pixel_angle = float(frame.uniforms.get("u_view_pixel_angle", 0.0))
    lights = []
    for light in frame.lights:
        rel = view.relative(light.position)
        d = max(math.sqrt(float(rel @ rel)), 1e-3)  # np.linalg.norm's sum and root, without its call
        radius = halo_radius(d, beta, float(haze.omega), float(haze.g), max(light.color.tolist()), threshold,
                             pixel_angle)
        if radius > 0.0 and _cone_on_screen(view, rel, d, radius):
            lights.append(light)
            if len(lights) == MAX_HALOS:
                break
    if not lights:
        return {"u_halo_count": 0}
    pos = np.zeros((MAX_HALOS, 4), np.float32)
    col = np.zeros((MAX_HALOS, 4), np.float32)
    for i, light in enumerate(lights):
        pos[i, :3] = view.relative(light.position)
        pos[i, 3] = math.sqrt(float(pos[i, :3] @ pos[i, :3]))
        col[i, :3] = light.color
    return {"u_halo_count": len(lights), "u_halo_pos": pos.tobytes(), "u_halo_intensity": col.tobytes(),
            "u_halo_beta": beta, "u_halo_omega": float(haze.omega), "u_halo_g": float(haze.g), "u_halo_far": 20.0 / beta,
            **table_uniforms(beta)}


_cones: dict = {}


def _cone_on_screen(view, rel: np.ndarray, d: float, radius: float) -> bool:
    """cone_on_screen of a light's halo (``rel``: camera-relative position, ``d`` its length), kept
    per exact view, position and radius: a still camera and still lights test it once."""
    key = (view_key(view), rel.tobytes(), radius)
    hit = _cones.get(key)
    if hit is None:
        if len(_cones) > 64:
            _cones.clear()
        hit = _cones[key] = cone_on_screen(view, rel / d, radius)
    return hit


def rod_fraction(adaptation_luminance: float) -> float:
    """Mesopic vision's rod share (tonemap.glsl): 0 at 3 cd/m^2 and above, 1 at 0.003 and below,
    log-linear between."""
    s = (math.log(3.0) - math.log(max(adaptation_luminance, 1e-9))) / (math.log(3.0) - math.log(0.003))
    return min(max(s, 0.0), 1.0)


class PostPass(RenderPass):
    name = "post"

    def execute(self, frame, targets) -> None:
        correction = self._meter(frame, targets)
        self.finish(frame, targets, correction)

    def finish(self, frame, targets, correction: float) -> None:
        """Halos, exposure (``correction`` x the frame's provisional one), tone curve: HDR to LDR."""
        halos = halo_uniforms(frame, correction)
        self.stats = {"halos": halos["u_halo_count"]}  # lights whose fog halo is drawn (bench rows)
        defines = {}
        if halos["u_halo_count"] > 0:
            defines["HALOS"] = 1  # variants: the common frame compiles neither the lookup nor the pass
            self._draw_halos(frame, targets, halos)
        if frame.scene.camera.mesopic_vision:
            defines["MESOPIC"] = 1
        program = self.programs.program("common/fullscreen.vert.glsl", "post/tonemap.glsl", defines)
        set_uniforms(program, frame.uniforms)
        set_uniforms(program, {"u_hdr": 0, "u_exposure_correction": correction,
                               "u_rod_fraction": rod_fraction(frame.uniforms["u_adaptation_luminance"])})
        if "u_halos" in program:
            set_uniforms(program, {"u_halos": 2, "u_distance": 1, "u_halo_far": halos["u_halo_far"]})
            use_texture(self._halo_target[0], 2)
            use_texture(targets.distance, 1)
        use_texture(targets.hdr, PASS_UNITS["HDR"])
        targets.ldr_fbo.use()
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
        self.fullscreen(program)

    def _draw_halos(self, frame, targets, halos: dict) -> None:
        """The halos at 1 / HALO_SCALE resolution (post/halos.frag.glsl), pre-exposed."""
        w, h = targets.size
        size = (-(-w // HALO_SCALE), -(-h // HALO_SCALE))
        self._halo_target = self.held_target("halos", size, "f2")
        if getattr(self, "_halo_table", None) is None:
            self._halo_table = HaloTable(self.ctx)
        # One variant per count of lights (1..MAX_HALOS): its loop unrolls to exactly that many.
        program = self.programs.program("common/fullscreen.vert.glsl", "post/halos.frag.glsl",
                                        {"HALO_SCALE": HALO_SCALE, "HALO_COUNT": halos["u_halo_count"]})
        set_uniforms(program, frame.uniforms)
        set_uniforms(program, halos)
        set_uniforms(program, {"u_distance": 1, "u_halo_table": HALO_TABLE_UNIT})
        use_texture(targets.distance, 1)
        self._halo_table.use(halos["u_halo_g"], HALO_TABLE_UNIT)
        self._halo_target[1].use()
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND)
        self.fullscreen(program)

    def _meter(self, frame, targets) -> float:
        """Meter the frame; set frame.ev100 (and the adaptation state); return the correction of
        the provisional exposure the passes used. In a stream the meter is the last frame's cells,
        copied out while it was drawn (post/meter_lag.py): this frame does not wait for its own."""
        scene = frame.scene
        state = frame.resources.get("frame_state")
        lag = getattr(state, "meter", None)
        if scene.camera.exposure_ev is not None:
            if lag is not None:
                lag.clear()
            return 1.0
        cells = lag.take() if lag is not None and lag.continues(None, scene, state.eye) else None
        tex = self.meter_dispatch(targets)
        if cells is not None:
            copy = self._meter_copy = copy_for(getattr(self, "_meter_copy", None), self.ctx, tex)
            ticket = MeterTicket(parts=[(copy, copy.queue(), frame.exposure)])
        else:
            cells = self.meter_cells(frame, tex)
            ticket = MeterTicket(cells)
        frame.resources["meter_ticket"] = ticket
        if lag is not None:
            lag.hold(ticket, None, scene.time.sim_time)
        if len(cells) == 0:
            return 1.0
        target, meter = display_metered_ev100(cells)
        ev = state.eye.update(target, scene.time.sim_time, scene.camera.adaptation) if state else target
        frame.ev100 = ev
        frame.meter_luminance = meter
        return exposure_of_ev100(ev) / frame.exposure

    def meter_dispatch(self, targets):
        """Queue the reduction of ``targets``' HDR colour to the meter's cells (into ``_meter_tex``,
        which the channels of a frame swap in and out: render/multiview.py); the texture."""
        w, h = targets.size
        # The GPU reduces the frame straight to the meter's cells (blocks of block x block pixels,
        # METER_CELLS across): one small read of a few kB per frame instead of a full-frame one.
        block = max(1, math.ceil(w / METER_CELLS))
        size = (math.ceil(w / block), math.ceil(h / block))
        tex = getattr(self, "_meter_tex", None)
        if tex is None or tex.size != size:
            if tex is not None:
                tex.release()
            tex = self._meter_tex = self.ctx.texture(size, 4, dtype="f4")
        prog = self.programs.compute("post/meter.glsl")
        set_uniforms(prog, {"u_block": block})
        if getattr(self, "_meter_sampler", None) is None:  # bilinear over the target's nearest filter
            self._meter_sampler = self.ctx.sampler(filter=(moderngl.LINEAR, moderngl.LINEAR),
                                                   repeat_x=False, repeat_y=False)
        use_texture(targets.hdr, PASS_UNITS["HDR"])
        self._meter_sampler.use(PASS_UNITS["HDR"])
        tex.bind_to_image(0, read=False, write=True)
        prog.run((size[0] + 3) // 4, (size[1] + 3) // 4, 1)
        self._meter_sampler.clear(PASS_UNITS["HDR"])
        self.ctx.memory_barrier()
        return tex

    @staticmethod
    def meter_cells(frame, tex) -> np.ndarray:
        """The finite cells of a dispatched meter texture, in linear RGB before pre-exposure: read
        at once (waits for the frame so far)."""
        return finite_cells(tex.read(), frame.exposure)
