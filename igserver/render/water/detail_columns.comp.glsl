// The detail maps' last pass (detail_synth.py): per level of each map, per column x, the inverse DFT
// along n of the level's grid, as (sx, sy, sx² + removed_x, sy² + removed_y) into the level's texels
// (x, y) in detail_texels, from where each level goes to its texture (a copy: llvmpipe's imageStore cost
// 2x the pass). A level no wave fits holds (0, 0, removed): the tile's slope variance.
// One invocation per four columns (x .. x + 3: a point of all one dvec4 load); each level's columns start
// on a work group (padded to 8 invocations), so the level and its size are the same throughout a group.
#define DETAIL_COLUMNS 1
#include "water/detail_synth.glsl"

layout(local_size_x = DETAIL_GROUP) in;

// Per level, rows along the tile's y, S × S texels from its first.
layout(std430, binding = STORAGE_SEA_DETAIL_TEXELS) buffer DetailTexels { vec4 detail_texels[]; };

// Four complex values (8 floats) as a dvec4 of their bits: one access. The grid's points (x .. x + 3)
// of a row (x a multiple of 4, as the grid's rows and start), the texels (x, x + 1) of a level.
layout(std430, binding = STORAGE_SEA_DETAIL_GRID) readonly buffer DetailGridQuads { dvec4 detail_grid_quads[]; };
layout(std430, binding = STORAGE_SEA_DETAIL_TEXELS) buffer DetailTexelPairs { dvec4 detail_texel_pairs[]; };
double detail_bits(vec2 v) { return packDouble2x32(floatBitsToUint(v)); }
vec2 detail_floats(double d) { return uintBitsToFloat(unpackDouble2x32(d)); }
dvec4 detail_pack(mat2x4 v) {
    return dvec4(detail_bits(v[0].xy), detail_bits(v[0].zw), detail_bits(v[1].xy), detail_bits(v[1].zw));
}
mat2x4 detail_unpack(dvec4 d) {
    return mat2x4(vec4(detail_floats(d.x), detail_floats(d.y)), vec4(detail_floats(d.z), detail_floats(d.w)));
}
mat2x4 detail_quad(int at) { return detail_unpack(detail_grid_quads[at >> 2]); }

// The level's texels at y of the columns x .. x + 3 from their values v, two stores (at even).
void detail_column_store(int at, mat2x4 v, vec2 removed) {
    detail_texel_pairs[at >> 1] = detail_pack(mat2x4(vec4(v[0].xy, v[0].xy * v[0].xy + removed),
                                                     vec4(v[0].zw, v[0].zw * v[0].zw + removed)));
    detail_texel_pairs[(at >> 1) + 1] = detail_pack(mat2x4(vec4(v[1].xy, v[1].xy * v[1].xy + removed),
                                                           vec4(v[1].zw, v[1].zw * v[1].zw + removed)));
}

// Z between the FFT's steps (detail_fft.py): the invocation's own shared memory where it fits (llvmpipe
// bounds-checks no shared access), else the texels (x, x + 1) (8 floats: the four columns' Z).
#if DETAIL_N <= 128  // 32 KiB: llvmpipe's limit
shared dvec4 detail_scratch[DETAIL_GROUP * DETAIL_N];
mat2x4 detail_z(int at, int texel, int size) { return detail_unpack(detail_scratch[int(gl_LocalInvocationIndex) * DETAIL_N + at]); }
void detail_z(int at, int texel, int size, mat2x4 v) { detail_scratch[int(gl_LocalInvocationIndex) * DETAIL_N + at] = detail_pack(v); }
#else
mat2x4 detail_z(int at, int texel, int size) { return detail_unpack(detail_texel_pairs[(texel + at * size) >> 1]); }
void detail_z(int at, int texel, int size, mat2x4 v) { detail_texel_pairs[(texel + at * size) >> 1] = detail_pack(v); }
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
    int x = 4 * (group - record.first + int(gl_LocalInvocationID.x));  // the first of four columns
    if (x >= record.size) return;  // the padding of a level narrower than four work groups
    vec2 removed = record.removed;
    for (int p = record.pair_first; p < record.pair_end; ++p) {
        DetailPair pair = detail_pairs[p];
        double sum = pair.j < 0 ? detail_phase(pair.i) + detail_phase(~pair.j) : detail_phase(pair.i) - detail_phase(pair.j);
        removed += pair.weight * (0.5 * cos(detail_angle(sum)));
    }
    if (record.spectral == 0) {
        for (int y = 0; y < record.size; ++y) {
            for (int c = x; c < min(x + 4, record.size); ++c) detail_texels[record.texels + y * record.size + c] = vec4(0.0, 0.0, removed);
        }
    } else {
        detail_column(record.size, record.along, x, record.texels + x, removed);
    }
}
