// The detail maps' third pass (detail_synth.py): per row of a spectral level that holds a bin, its
// inverse DFT along m (detail_fft.py), from the level's rows to its grid (detail_synth.glsl). One
// invocation per two rows (their spectra interleaved, a point of both one vec4), its DFTs serial (no
// barrier: llvmpipe runs a barrier's invocations as coroutines); each level's rows start on a work
// group of their own (padded), so a group's rows have one size and run one DFT function.
#define DETAIL_ROWS 1
#include "water/detail_synth.glsl"
// The pair's values v at x into the rows a and b.
void detail_row_store(int x, int a, int b, vec4 v) {
    detail_grid[a + x] = v.xy;
    detail_grid[b + x] = v.zw;
}

// Z between the FFT's steps (detail_fft.py): the invocation's own shared memory where it fits (llvmpipe
// bounds-checks no shared access), else the rows it writes.
#if DETAIL_N <= 128
shared vec4 detail_scratch[DETAIL_GROUP * DETAIL_N];
vec4 detail_z(int at, int a, int b) { return detail_scratch[int(gl_LocalInvocationIndex) * DETAIL_N + at]; }
void detail_z(int at, int a, int b, vec4 v) { detail_scratch[int(gl_LocalInvocationIndex) * DETAIL_N + at] = v; }
#else
vec4 detail_z(int at, int a, int b) { return vec4(detail_grid[a + at], detail_grid[b + at]); }
void detail_z(int at, int a, int b, vec4 v) { detail_row_store(at, a, b, v); }
#endif

#include "generated/detail_fft.glsl"

layout(local_size_x = DETAIL_GROUP) in;

// Per two rows: (level size S, their interleaved spectra in detail_grid (even), the first's transform
// there (−1: padding), the second's (an odd last row's: a spare row)).
layout(std430, binding = STORAGE_SEA_DETAIL_ROWS) readonly buffer DetailRows { ivec4 detail_rows[]; };

void main() {
    int size = detail_rows[gl_WorkGroupID.x * gl_WorkGroupSize.x].x;  // the group's
    ivec4 row = detail_rows[gl_GlobalInvocationID.x];
    if (row.z < 0) return;
    detail_row(size, row.y, row.z, row.w);
}
