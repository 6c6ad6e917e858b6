// The detail maps' second pass (detail_synth.py): per bin of each spectral level, the sum of its
// coefficients c_± e^{±iφ} (one but where the snapped waves share a lattice point), into its place in
// the level's rows (detail_synth.glsl). One invocation per bin: a gather, no atomics.
#include "water/detail_synth.glsl"

layout(local_size_x = DETAIL_GROUP) in;

// Per bin: (its place in detail_grid, its coefficients [first, end), unused).
layout(std430, binding = STORAGE_SEA_DETAIL_BINS) readonly buffer DetailBins { ivec4 detail_bins[]; };
// Per coefficient: c_± = ½ G (g_x + i g_y) e^{±iπ (m + n) / S} and its wave (~wave: the conjugate bin
// −(m, n), times e^{−iφ}), read as one vec4 (value, wave's bits, unused): one load on llvmpipe.
layout(std430, binding = STORAGE_SEA_DETAIL_ENTRIES) readonly buffer DetailEntries { vec4 detail_entries[]; };

uniform int u_bins;  // bins of the maps written (a prefix of the table: the first maps')

void main() {
    int id = int(gl_GlobalInvocationID.x);
    if (id >= u_bins) return;
    ivec4 bin = detail_bins[id];
    vec2 sum = vec2(0.0);
    for (int e = bin.y; e < bin.z; ++e) {
        vec4 entry = detail_entries[e];
        int wave = floatBitsToInt(entry.z);
        vec2 phasor = detail_grid[wave < 0 ? ~wave : wave] * vec2(1.0, wave < 0 ? -1.0 : 1.0);  // one load
        sum += vec2(entry.x * phasor.x - entry.y * phasor.y, entry.x * phasor.y + entry.y * phasor.x);
    }
    detail_grid[bin.x] = sum;
}
