"""The volumes pass's knobs: VolumeSettings (march steps, turbulence octaves, texture resolution,
level of detail, march scale, modelling rate) and the quality presets, registered with render/presets.py
under "volumes". Apart from the pass, so that what reads the knobs (the march plan, the modelling
stage, the quality study) does not import the GL pass."""

from __future__ import annotations

from dataclasses import dataclass

from .. import presets


@dataclass(frozen=True)
class VolumeSettings:
    steps: int = 64  # samples along the container's diagonal (the step is at most one voxel)
    octaves: int = 3  # turbulence octaves (2-4 in the paper)
    resolution: int = 32  # voxels across the container's diameter (height: in proportion)
    min_resolution: int = 8
    lod: bool = True  # screen-size level of detail (off: the knobs themselves): a coarser texture for
    #                   containers small on screen, a coarser march where the voxels are large on it
    scale: int = 1  # march resolution divisor: 1 full, 2 half, 4 quarter (depth-aware upsampling);
    #                 with lod, the finest: raised up to MAX_MARCH_SCALE by footprint_scale()
    model_hz: float = 0.0  # re-modelling keyframes per second of sim time; 0 = every frame


# Quality presets: points on the measured curves (igserver quality volumes: close night fire on
# llvmpipe, errors in 8-bit sRGB levels against 1024 steps / 4 octaves / 128 voxels, full
# resolution, exact modelling time). What the curves showed:
#   * the modelling stage dominates while time runs: re-modelling at 5-10 Hz with keyframe
#     blending instead of every frame cut the pass 2-4x for +0.2..2.5 RMSE;
#   * half-resolution marching cuts the march ~3x for ~+1.5 levels of low-passed error; quarter
#     resolution shows blocks at fire edges (low only);
#   * steps matter little once the step follows the pixel footprint; octaves and the texture cap
#     hardly change the error of a fire seen from outside (3 -> 2 octaves: none measurable, -10 %
#     time; 32 -> 16 voxels: +0.4 lowpass, -30 % time), but from INSIDE a plume the picture is all
#     texture detail: lowpass error 22 (3 octaves, 32 voxels) -> 30 (2 octaves) -> 39 (24 voxels),
#     so medium keeps 3 / 32; a 64-voxel texture makes modelling and the voxel-limited near steps
#     dominate.
PRESETS = {
    "low": VolumeSettings(steps=32, octaves=2, resolution=16, scale=4, model_hz=5.0),
    "medium": VolumeSettings(steps=48, octaves=3, resolution=32, scale=2, model_hz=10.0),
    "high": VolumeSettings(steps=96, octaves=4, resolution=48, scale=1, model_hz=30.0),
}
presets.register("volumes", PRESETS)
