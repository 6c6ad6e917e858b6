"""The march's side of the volumes pass (volumes.py): what a frame's march derives from the visible
volumes, the view and the knobs - texture sizes, the footprint's march scale, the boxes' screen
rectangles, the extinctions, and every volume's record of the march block (march_block.py) - made
once per change of them as a MarchPlan (VolumesPass.memo "march_plan")."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ...effect_kinds import EFFECT_KINDS, FUELS
from ...scene.model import Scene
from ..camera import CameraView
from . import march_block
from .effects import Volume, plume_soot_extinction
from .fire_lights import flame
from .profiles import PLUME_VIRTUAL_ORIGIN, SMOKE_ALBEDO

if TYPE_CHECKING:
    from .settings import VolumeSettings

FIRE_LUMINANCE = 2.0e4  # cd/m^2 of profile colour 1 at intensity 1 (a candle is ~1e4, large flames more)
FIRE_SIGMA_D = 1.5  # extinction of a gas burner's density 1 times its diameter: a premixed flame, thin
# A pool fire's soot absorbs (and emits) per metre of flame, a property of the fuel: k = 1.7-3.5 /m
# for gasoline, kerosene and fuel oils (Babrauskas, SFPE Handbook, the k beta of the burning-rate
# law). Across a base of diameter D the optical depth is k D: a 3 m fire's base is opaque (e^-6),
# a 0.3 m one translucent (e^-0.6), and the intermittent tips, where the profile thins, let light
# through (effect_kinds.FUELS: k beta per fuel; methanol's soot-free flame stays nearly clear).
# (A fixed optical depth of 1.5 per diameter left every fire a translucent ghost.)
SMOKE_SIGMA_D = 3.0


def scattering(vol: Volume) -> bool:
    """The march shades the volume as a lit, scattering medium (SMOKE), not as emitted light."""
    return EFFECT_KINDS[vol.kind].shading == "scattering"


def texture_size(vol: Volume, view: CameraView, settings: "VolumeSettings") -> tuple[int, int, int]:
    """(x, y, z) voxels: the knob, lowered for containers that are small on screen."""
    distance = max(float(np.linalg.norm(view.relative(vol.bounding_sphere[0]))) - vol.bounding_sphere[1], 1e-3)
    pixels_per_m = view.projection[1, 1] * view.height / 2.0 / distance
    # About one voxel per 1.5 px; for smoke, per 1.5 pixels of the preset's march (scale 2 at
    # medium): neighbouring rays a march pixel apart skip finer voxels, which only alias. A far
    # plume's texture then halves per axis (sea_harbour_fire's 32 x 32 x 50 at 111 m: 16 x 16 x 25,
    # its modelling an eighth) and its low-passed error against a 64-voxel full-resolution march
    # rises from 0.5-0.9 to 1.7-3.0 levels of 8 bits (the plume's pixels, EV 6, four sim times;
    # by eye the same dark plume at 111 m), for half the pass's worker CPU.
    # A flame keeps the full-resolution rule: its clipped silhouette and tips are its picture.
    march_px = max(settings.scale, 1) if scattering(vol) else 1
    across = 2.0 * vol.radius * pixels_per_m / (1.5 * march_px)
    res_xy = settings.resolution
    if settings.lod:
        res_xy = int(min(res_xy, max(settings.min_resolution, 2 ** round(math.log2(max(across, 1.0))))))
    aspect = vol.height / max(2.0 * vol.radius, 1e-6)
    res_z = int(min(max(round(res_xy * aspect), settings.min_resolution), 4 * res_xy))
    return res_xy, res_xy, res_z


MAX_MARCH_SCALE = 4  # the coarsest march (quarter resolution per axis)
# A march pixel may be at most this many voxels wide at the far side of a container. Measured
# (night_fire, medium knobs, 640x360, low-passed error in 8-bit levels against a 1024-step
# full-resolution march of the same texture, half -> quarter resolution): camera in the plume
# (3.4 px per far voxel) 0.07 -> 0.17; 4 m from the fire (2.8 px) 0.27 -> 0.96; 6 m (2.7 px)
# 0.53 -> 1.78; 12 m (2.0 px) 1.41 -> 3.76. 1.25 takes quarter resolution only where it adds
# ~0.1 level.
MARCH_PIXEL_VOXELS = 1.25


def footprint_scale(volumes: list[Volume], sizes: list[tuple[int, int, int]], view: CameraView) -> int:
    """The coarsest march divisor (a power of two, at most MAX_MARCH_SCALE) whose march pixels are
    at most MARCH_PIXEL_VOXELS voxels wide everywhere in every visible container: a finer march
    only samples the same trilinear texture more densely. The voxel's angle is taken at the far
    side of the container's bounding sphere and the pixel's at the frame's centre (where a pixel
    spans the most angle), so every voxel spans at least that many pixels. With the camera in a
    plume the march falls to quarter resolution (0.38x its cost); a fire 4 m away or more keeps
    the preset's half resolution."""
    _, _, bottom, top = view.tangents
    rad_per_px = (top - bottom) / max(view.height, 1)
    scale = MAX_MARCH_SCALE
    for vol, size in zip(volumes, sizes):
        voxel = min(2.0 * vol.radius / size[0], 2.0 * vol.radius / size[1], vol.height / size[2])
        centre, radius = vol.bounding_sphere
        far = float(np.linalg.norm(view.relative(centre))) + radius
        pixels = voxel / max(far, 1e-6) / rad_per_px  # pixels per voxel, the fewest in the container
        s = 1
        while 2 * s <= MAX_MARCH_SCALE and 2 * s <= MARCH_PIXEL_VOXELS * pixels:
            s *= 2
        scale = min(scale, s)
    return scale


def screen_rect(volumes: list[Volume], view: CameraView, width: int, height: int, pad: int):
    """(x, y, w, h) in pixels (GL's lower-left origin) covering every volume's box, padded; the
    whole screen when a box reaches behind the near plane. The full-resolution passes of the
    reduced march (downsample, upsample) run only there."""
    x0, y0, x1, y1 = width, height, 0, 0
    for vol in volumes:
        lo, hi = (view.relative(c) for c in vol.box)
        corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        clip = corners @ view.view_proj.T
        if (clip[:, 3] <= view.near).any():
            return 0, 0, width, height
        ndc = clip[:, :2] / clip[:, 3:4]
        px = (ndc * 0.5 + 0.5) * np.array([width, height])
        x0, y0 = min(x0, float(px[:, 0].min())), min(y0, float(px[:, 1].min()))
        x1, y1 = max(x1, float(px[:, 0].max())), max(y1, float(px[:, 1].max()))
    x0, y0 = max(int(math.floor(x0)) - pad, 0), max(int(math.floor(y0)) - pad, 0)
    x1, y1 = min(int(math.ceil(x1)) + pad, width), min(int(math.ceil(y1)) + pad, height)
    return x0, y0, max(x1 - x0, 0), max(y1 - y0, 0)


def extinction(vol: Volume, smoke: bool) -> float:
    """1/m, the extinction of the volume's density 1: smoke per its plume's diameter, a pool
    fire's flame per metre (its fuel's k beta), a gas burner per its diameter."""
    if smoke and vol.key[1] == "smoke" and EFFECT_KINDS[vol.effect.type].plume is not None:
        # A fire's plume: its soot from the heat release (effects.plume_soot_extinction), at the
        # plume's base (its height above the pool, its half-density radius: smoke_profile).
        e = vol.effect
        base_radius = 0.8 * PLUME_VIRTUAL_ORIGIN / (1.0 + PLUME_VIRTUAL_ORIGIN) * vol.radius
        return plume_soot_extinction(e, float(vol.base[2] - e.position[2]), base_radius)
    if smoke:
        return SMOKE_SIGMA_D / max(vol.effect.diameter, 1e-3)
    if EFFECT_KINDS[vol.kind].container == "pool_fire":
        return FUELS[vol.effect.fuel].k_beta
    return FIRE_SIGMA_D / max(vol.effect.diameter, 1e-3)


class MarchPlan:
    """What the frame's march derives from the visible volumes, the view and the knobs, made once
    per change of them (VolumesPass.memo "march_plan", keyed on those): each volume's texture size
    and hard modelling state, the footprint's march scale, the boxes' screen rectangles and far
    distance, and the block's records (march_block.py) - the slabs sorted farthest first and every
    constant of the march. A stream that only advances sim_time reuses it whole; the per-frame
    parts (keyframes, blend, jitter, the glow's flicker) are not in it."""

    def __init__(self, volumes: list[Volume], scene: Scene, view: CameraView, settings: "VolumeSettings"):
        self.volumes = volumes
        self.sizes = [texture_size(v, view, settings) for v in volumes]
        self.smoke = [scattering(v) for v in volumes]
        # the fuel and the heat release set the plume's soot and size: a host changing them changes the
        # fire now, not at the next keyframe
        self.hard = [(size, settings.octaves, v.seed, v.kind, v.profile, v.effect.diameter, v.effect.intensity,
                      v.effect.active, v.effect.fuel, v.effect.heat_release_kw) for v, size in zip(volumes, self.sizes)]
        self.soft = [(v.radius, v.height, v.opacity, v.level) for v in volumes]
        self.lod_scale = footprint_scale(volumes, self.sizes, view) if settings.lod else 1
        self.far = max((float(np.linalg.norm(view.relative(v.bounding_sphere[0]))) + v.bounding_sphere[1]
                        for v in volumes), default=1.0)
        self._rects: dict[tuple, tuple] = {}
        self.stride = 0
        self.records = b""
        self.slab_counts: list[int] = []
        self.glows: list[tuple] = []  # (volume index, effect, its Flame) of each plume its fire lights

    def pack(self, scene: Scene, view: CameraView, settings: "VolumeSettings", alignment: int) -> "MarchPlan":
        stride = march_block.stride(alignment)
        out = np.zeros((len(self.volumes), stride // 4), np.float32)
        cam_z = float(view.position[2])
        for i, (vol, size, smoke) in enumerate(zip(self.volumes, self.sizes, self.smoke)):
            lo, hi = vol.box
            # Steps: the knob's share of the diagonal at most, one voxel at least, in between the
            # pixel footprint at the sample's distance (march.frag.glsl).
            step = float(np.linalg.norm(hi - lo)) / settings.steps
            voxel = min(2.0 * vol.radius / size[0], 2.0 * vol.radius / size[1], vol.height / size[2])
            # Along a ray z is monotonic, so the slabs come in order of their height distance from the
            # camera: drawn farthest first they compose as one front-to-back march.
            slabs = sorted(vol.slabs(), key=lambda b: -max(float(b[0][2]) - cam_z, cam_z - float(b[1][2]), 0.0))
            glow_pos, albedo_scale, hg_g, emission = (0.0, 0.0, 0.0), 1.0, 0.0, (0.0, 0.0, 0.0)
            if smoke:
                hg_g = 0.6
                # a plume is lit by its own effect's flame (a smoke effect casts no light: None); its
                # intensity flickers, patched in per frame (VolumesPass._write_block)
                lit = flame(vol.effect, scene)
                if lit is not None:
                    glow_pos = view.relative(lit.position)
                    self.glows.append((i, vol.effect, lit))
                # sooty smoke of a fire vs. a light grey smoke generator: scale the profile's albedo
                sooty = EFFECT_KINDS[vol.effect.type].plume is not None and vol.profile is None
                albedo_scale = FUELS[vol.effect.fuel].smoke_albedo / SMOKE_ALBEDO if sooty else 1.0
            else:
                lum = FIRE_LUMINANCE * math.sqrt(vol.intensity)
                emission = (lum, lum, lum)
            rec = march_block.record([(view.relative(a), view.relative(b)) for a, b in slabs], view.relative(vol.base),
                                     max(step, 1e-4), (vol.radius, vol.radius, vol.height), max(min(voxel, step), 1e-4),
                                     vol.lean[:2], extinction(vol, smoke), hg_g, glow_pos, albedo_scale, emission)
            out[i, :march_block.ROWS * 4] = rec.ravel()
            self.slab_counts.append(len(slabs))
        self.stride, self.records = stride, out.tobytes()
        return self

    def screen_rect(self, view: CameraView, width: int, height: int, pad: int) -> tuple[int, int, int, int]:
        """screen_rect of the plan's volumes, once per (width, height, pad)."""
        key = (width, height, pad)
        rect = self._rects.get(key)
        if rect is None:
            rect = self._rects[key] = screen_rect(self.volumes, view, width, height, pad)
        return rect
