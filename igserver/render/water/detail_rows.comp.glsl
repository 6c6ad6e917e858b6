// The detail maps' third pass (detail_synth.py): per row of a spectral level that holds a bin, its
// inverse DFT along m (detail_fft.py), from the level's rows to its grid (detail_synth.glsl). One
// invocation per row, its DFT serial (no shared memory, no barrier: llvmpipe runs a barrier's
// invocations as coroutines); each level's rows start on a work group of their own (padded), so a
// group's rows have one size and run one DFT function.
#define DETAIL_ROWS 1
#include "water/detail_synth.glsl"
#include "generated/detail_fft.glsl"

layout(local_size_x = DETAIL_GROUP) in;

// Per row: (level size S, the row's spectrum in detail_grid, its transform there (−1: padding), unused).
layout(std430, binding = STORAGE_SEA_DETAIL_ROWS) readonly buffer DetailRows { ivec4 detail_rows[]; };

void main() {
    int size = detail_rows[gl_WorkGroupID.x * gl_WorkGroupSize.x].x;  // the group's
    ivec4 row = detail_rows[gl_GlobalInvocationID.x];
    if (row.z < 0) return;
    detail_row(size, row.y, row.z);
}
