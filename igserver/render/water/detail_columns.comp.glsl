// The detail maps' last pass (detail_synth.py): per level of each map, per column x, the inverse DFT
// along n of the level's grid, as (sx, sy, sx² + removed_x, sy² + removed_y) into the level's texels
// (x, y) in detail_texels, from where each level goes to its texture (a copy: llvmpipe's imageStore cost
// 2x the pass). A level no wave fits holds (0, 0, removed): the tile's slope variance.
// One invocation per two columns (x, x + 1: a point of both one vec4 load); each level's columns start
// on a work group (padded to 8 invocations), so the level and its size are the same throughout a group.
#define DETAIL_COLUMNS 1
#include "water/detail_synth.glsl"

layout(local_size_x = DETAIL_GROUP) in;

// Per level, rows along the tile's y, S × S texels from its first.
layout(std430, binding = STORAGE_SEA_DETAIL_TEXELS) buffer DetailTexels { vec4 detail_texels[]; };

// The level's texels at y of the columns x and x + 1 from their values v (a pair).
// The texels as pairs (8 floats as a dvec4 of their bits): two texels in one store (at even).
layout(std430, binding = STORAGE_SEA_DETAIL_TEXELS) writeonly buffer DetailTexelPairs { dvec4 detail_texel_pairs[]; };
double detail_bits(float a, float b) { return packDouble2x32(uvec2(floatBitsToUint(a), floatBitsToUint(b))); }
void detail_column_store(int at, vec4 v, vec2 removed) {
    vec4 a = vec4(v.xy, v.xy * v.xy + removed), b = vec4(v.zw, v.zw * v.zw + removed);
    detail_texel_pairs[at >> 1] = dvec4(detail_bits(a.x, a.y), detail_bits(a.z, a.w), detail_bits(b.x, b.y), detail_bits(b.z, b.w));
}

// Z between the FFT's steps (detail_fft.py): the invocation's own shared memory where it fits (llvmpipe
// bounds-checks no shared access), else the texels of its column x (each all four channels: the pair).
#if DETAIL_N <= 128
shared vec4 detail_scratch[DETAIL_GROUP * DETAIL_N];
#define DETAIL_Z(at) detail_scratch[int(gl_LocalInvocationIndex) * DETAIL_N + (at)]
#else
#define DETAIL_Z(at) detail_texels[texel + (at) * size]
#endif

#include "generated/detail_fft.glsl"

// Per level of each map: its size S, its grid in detail_grid (spectral), the first invocation of its
// columns, whether it holds waves; the variance its gains removed, fixed part Σ ½ (1 − G²) g²
// (sx², sy²); its pairs [first, end) in detail_pairs; its first texel in detail_texels.
struct DetailLevel { int size; int along; int first; int spectral; vec2 removed; int pair_first; int pair_end;
                     int texels; int unused[3]; };
layout(std430, binding = STORAGE_SEA_DETAIL_LEVELS) readonly buffer DetailLevels { DetailLevel detail_levels[]; };
// Per pair of waves on the same lattice point (j: w = ½ cos(φ_i − φ_j)) or on opposite ones (~j:
// ½ cos(φ_i + φ_j)), per level: (1 − G_i G_j) (g_xi g_xj, g_yi g_yj).
struct DetailPair { vec2 weight; int i; int j; };
layout(std430, binding = STORAGE_SEA_DETAIL_PAIRS) readonly buffer DetailPairs { DetailPair detail_pairs[]; };

uniform int u_levels;  // levels of the maps written (a prefix: the first maps')

void main() {
    // The level from the work group's first invocation: the same for the whole group, so llvmpipe runs
    // one DFT function for the group's 8 lanes, not every size's under a mask.
    int group = int(gl_WorkGroupID.x * gl_WorkGroupSize.x);
    int level = 0;
    for (int l = 1; l < u_levels; ++l) {
        if (group >= detail_levels[l].first) level = l;
    }
    DetailLevel record = detail_levels[level];
    int x = 2 * (group - record.first + int(gl_LocalInvocationID.x));  // the pair's first column
    if (x >= record.size) return;  // the padding of a level narrower than two work groups
    vec2 removed = record.removed;
    for (int p = record.pair_first; p < record.pair_end; ++p) {
        DetailPair pair = detail_pairs[p];
        double sum = pair.j < 0 ? detail_phase(pair.i) + detail_phase(~pair.j) : detail_phase(pair.i) - detail_phase(pair.j);
        removed += pair.weight * (0.5 * cos(detail_angle(sum)));
    }
    if (record.spectral == 0) {
        for (int y = 0; y < record.size; ++y) {
            detail_texels[record.texels + y * record.size + x] = vec4(0.0, 0.0, removed);
            if (x + 1 < record.size) detail_texels[record.texels + y * record.size + x + 1] = vec4(0.0, 0.0, removed);
        }
    } else {
        detail_column(record.size, record.along, x, record.texels + x, removed);
    }
}
