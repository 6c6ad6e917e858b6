// One detail normal map (a tile of side L): the slopes of the spectrum's high-frequency waves that
// the mesh cannot carry, on a lattice (k = 2 pi (m, n) / L) so the tile repeats seamlessly.
// Stored: (sx, sy, sx^2, sy^2); after mip-filtering, E[s^2] - E[s]^2 is the slope variance a
// texel no longer resolves, which the water shader turns into roughness (LEAN mapping).
// DETAIL_COUNT: the tile's wave count (water.py compiles one variant per count, at most MAX_DETAIL).
uniform vec4 u_detail_wave[DETAIL_COUNT];   // 2 pi (m, n) for m, n cycles per tile, phase (rad)
uniform vec4 u_detail_slope[DETAIL_COUNT];  // xy: slope amplitude A k along the unit (m, n)

in vec2 v_uv;
layout(location = 0) out vec4 out_slope;

void main() {
    vec2 s = vec2(0.0);
    for (int i = 0; i < DETAIL_COUNT; ++i) {
        vec4 w = u_detail_wave[i];
        s += u_detail_slope[i].xy * cos(dot(w.xy, v_uv) + w.z);
    }
    out_slope = vec4(s, s * s);
}
