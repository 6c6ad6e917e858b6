"""The march's per-volume constants as one std140 uniform block (``VolumeBlock``, binding point
``BLOCK_VOLUME``, render/bindings.py), declared in march_block.glsl.

Everything the march of one volume reads that is not per frame - its slabs' boxes, base, extent,
lean, steps, extinction, albedo, emission, the glow's position - changes only with the visible
volumes, the view and the knobs, so it is packed once per change of those (march.py MarchPlan),
every visible volume's record one after the other in one buffer; a frame binds each volume's record
(one call) instead of writing a dozen uniforms per volume and two per slab. The per-frame parts -
the glow's flickering intensity, the keyframe blend, the start jitter's shift - are patched into
the records before the buffer is written (one write a frame, skipped when the bytes are unchanged).

Every member is a vec4, so the std140 layout is rows of 16 bytes in declaration order (ROW).
"""

from __future__ import annotations

import numpy as np

MAX_SLABS = 8  # slab boxes a record holds (effects.MAX_SLABS at most)
# Row indices of the record (march_block.glsl's members, in order).
ROW = {"slab_min": 0, "slab_max": MAX_SLABS, "base_step": 2 * MAX_SLABS, "extent_voxel": 2 * MAX_SLABS + 1,
       "lean_sigma_g": 2 * MAX_SLABS + 2, "glow_pos_albedo": 2 * MAX_SLABS + 3, "glow_intensity": 2 * MAX_SLABS + 4,
       "emission": 2 * MAX_SLABS + 5}
ROWS = 2 * MAX_SLABS + 6
RECORD_BYTES = 16 * ROWS


def stride(alignment: int) -> int:
    """Bytes from one record to the next: the record rounded up to the context's
    GL_UNIFORM_BUFFER_OFFSET_ALIGNMENT (16 on llvmpipe, 256 on most discrete GPUs)."""
    alignment = max(int(alignment), 16)
    return -(-RECORD_BYTES // alignment) * alignment


def record(slabs: list[tuple], base, step: float, extent, voxel: float, lean, sigma: float, hg_g: float,
           glow_pos, albedo_scale: float, emission) -> np.ndarray:
    """One volume's record as float32 rows (camera-relative metres; see march.frag.glsl's uniforms)."""
    if len(slabs) > MAX_SLABS:
        raise ValueError(f"{len(slabs)} slabs, the block holds {MAX_SLABS}")
    out = np.zeros((ROWS, 4), np.float32)
    for i, (lo, hi) in enumerate(slabs):
        out[ROW["slab_min"] + i, :3] = lo
        out[ROW["slab_max"] + i, :3] = hi
    out[ROW["base_step"]] = (*base, step)
    out[ROW["extent_voxel"]] = (*extent, voxel)
    out[ROW["lean_sigma_g"]] = (*lean, sigma, hg_g)
    out[ROW["glow_pos_albedo"]] = (*glow_pos, albedo_scale)
    out[ROW["emission"], :3] = emission
    return out


# The per-frame lanes (float32 index into a record): the glow's rgb intensity, the keyframe blend,
# the start jitter's shift.
GLOW = 4 * ROW["glow_intensity"]
BLEND = 4 * ROW["glow_intensity"] + 3
JITTER = 4 * ROW["emission"] + 3
