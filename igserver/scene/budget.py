"""What one state may cost to render: an upper estimate, checked when the state is accepted (docs/design.md#service).

Every range in the scene model is reasonable alone, but products of them are not: 64 fires of 500 m
with smoke at the high preset, a 7680x4320 frame, 32 scattering orders at high table quality. The
estimate below bounds the work of a frame *for any camera pose* (a host may fly into the fire), in
"work units" of about one ray-march sample (~3 ns on 2 llvmpipe cores):

  frame  = P * BASE_PER_PIXEL                       sky, ground, water, post (~80 march samples/px)
         + P / scale^2 * sum over volumes of steps  the march (at 1/scale of the resolution): in the worst
                                                    pose every box covers the screen and every ray
                                                    crosses every box
         + sum over volumes of 4 res^3 * octaves    re-modelling (res_z <= 4 res_xy), every frame
  tables = texels * 2 n^2 * (orders - 1)            multiple scattering: each order integrates the
         (texels = nu mu_s mu r, n = density_samples)  density over the sphere at every scattering texel

where P = width * height and a fire that emits smoke is two volumes; ``auto`` quality is costed at
``high`` (the controller may climb there). ``tables`` is paid once per new
set of atmosphere parameters (cached, with progress in /v1/ready), ``frame`` every frame. A state over
either budget is rejected with a problem naming the fields to lower. ``IGSERVER_BUDGET_SCALE`` scales
both budgets (a GPU renders ~100x more per second than llvmpipe).

A scene with channels (docs/channels.md) counts every channel's pixels in P: three 640x360 channels
cost like one 1920x360 frame.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from ..effect_kinds import EFFECT_KINDS
from .channels import total_pixels

# Work of the per-pixel passes, in march samples per pixel. Measured on llvmpipe:
# a 7680x4320 frame without effects took 7-10 s on llvmpipe (~250 ns/px), a march sample ~3 ns.
BASE_PER_PIXEL = 80
# ~3 s of llvmpipe time: 3840x2160 clear sky, or 64 fires at 640x360 (medium), fit; 7680x4320 does not.
FRAME_BUDGET = 1.0e9
# Table precompute: "medium" with up to 30 orders or "high" with up to 8 fit; 32 orders at "high" do not.
TABLE_BUDGET = 1.0e9

# Mirrors of the renderer's presets (igserver.render.volumes.settings.PRESETS and
# igserver.render.sky.atmosphere_model.PRESETS); a test keeps them equal.
# steps, octaves, resolution, scale (the march runs at 1/scale of the frame's resolution)
VOLUME_PRESETS = {"low": (32, 2, 16, 4), "medium": (48, 3, 32, 2), "high": (96, 4, 48, 1)}
TABLE_PRESETS = {  # (scattering texels, density_samples)
    "low": (8 * 16 * 32 * 8, 6),
    "medium": (8 * 32 * 64 * 16, 16),
    "high": (8 * 64 * 128 * 32, 16),
}


def budget_scale() -> float:
    try:
        scale = float(os.environ.get("IGSERVER_BUDGET_SCALE", "1"))
    except ValueError:
        return 1.0
    return scale if scale > 0 and scale == scale and scale != float("inf") else 1.0


@dataclass(frozen=True)
class Cost:
    frame: float  # work units per frame
    tables: float  # work units of one table precompute
    volumes: int
    pixels: int

    @property
    def frame_budget(self) -> float:
        return FRAME_BUDGET * budget_scale()

    @property
    def table_budget(self) -> float:
        return TABLE_BUDGET * budget_scale()


def volume_level(scene) -> str:
    """The preset whose knobs bound the cost: ``auto`` may reach ``high``."""
    preset = scene.quality.preset
    return preset if preset in VOLUME_PRESETS else "high"


def volume_count(scene) -> int:
    return sum(EFFECT_KINDS[effect.type].volume_count(effect.emits_smoke) for effect in scene.effects)


def estimate(scene) -> Cost:
    pixels = scene.camera.width * scene.camera.height
    if scene.channels:  # the channels are drawn, not the camera's own frame
        pixels = total_pixels(scene)
    steps, octaves, resolution, scale = VOLUME_PRESETS[volume_level(scene)]
    volumes = volume_count(scene)
    march = pixels / scale**2 * steps
    frame = pixels * BASE_PER_PIXEL + volumes * (march + 4 * resolution**3 * octaves)
    texels, density = TABLE_PRESETS[scene.atmosphere.quality]
    tables = texels * 2 * density**2 * max(scene.atmosphere.scattering_orders - 1, 0)
    return Cost(frame, tables, volumes, pixels)


def over_budget(scene) -> list[tuple[tuple, str]]:
    """[(field location, message)] for each budget the scene exceeds; empty when it fits."""
    cost = estimate(scene)
    problems = []
    if cost.frame > cost.frame_budget:
        share = cost.frame / cost.frame_budget
        steps, _, _, scale = VOLUME_PRESETS[volume_level(scene)]
        if cost.volumes and cost.volumes * cost.pixels / scale**2 * steps > cost.frame / 2:
            where = ("effects",)
            lower = ("use fewer effects (a fire with emits_smoke counts twice), a lower quality.preset or a "
                     "smaller camera.width/height")
        else:
            where = ("camera", "width")
            lower = "use a smaller camera.width/height"
        problems.append((where, f"a frame would cost {share:.1f}x the render budget ({cost.volumes} volumes at "
                                f"{scene.camera.width}x{scene.camera.height}, quality {scene.quality.preset}): "
                                f"{lower}"))
        if scene.channels:  # name the channels' total, not the camera's size (unused while there are channels)
            lower = lower.replace("a smaller camera.width/height", "fewer or smaller channels (their pixels add up)")
            problems[-1] = (("effects",) if where == ("effects",) else ("channels",),
                            f"a frame would cost {share:.1f}x the render budget ({cost.volumes} volumes in "
                            f"{len(scene.channels)} channels of {cost.pixels} px in all, quality "
                            f"{scene.quality.preset}): {lower}")
    if cost.tables > cost.table_budget:
        texels, density = TABLE_PRESETS[scene.atmosphere.quality]
        max_orders = int(cost.table_budget // (texels * 2 * density**2)) + 1
        problems.append((("atmosphere", "scattering_orders"),
                         f"atmosphere tables would cost {cost.tables / cost.table_budget:.1f}x the precompute "
                         f"budget: at quality {scene.atmosphere.quality!r} use at most {max_orders} scattering "
                         "orders, or a lower atmosphere.quality"))
    return problems
