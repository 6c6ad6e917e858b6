// The foam's streak noise, tabulated once (water.py WaterPass._foam_noise): per channel two octaves of
// the project's one noise (common/noise.glsl) over one period of FOAM_PERIOD cells in x and y, scaled
// to about standard normal — the two-octave sum over the plane z = 0 is near-normal with sigma 0.405
// (measured) — and stored as 0.5 + z / 8 (8 bits: steps of 0.03 sigma over +-4 sigma), so the water
// shader's dither (water/foam_streaks.glsl foam_cover) can add lookups of it and keep its distribution.
// The first channel's cells are the table's; the second's and third's are u_cells_g and u_cells_b of
// them (foam.py rows_channel_cells: the coarsest wind row and the meander, read in one lookup with the
// first coarse row); the fourth is unused (0.5).
#include "common/noise.glsl"

uniform float u_period;   // noise cells per side of the tile
uniform vec2 u_cells_g;   // the second channel's cell, in cells of the first (divides u_period)
uniform vec2 u_cells_b;   // the third channel's
in vec2 v_uv;
layout(location = 0) out vec4 out_u;

float standard(vec2 cells, uint seed) {
    vec2 period = u_period / cells;
    return turbulence3(vec3(v_uv * period, 0.0), vec3(period, 0.0), 2, seed) / 0.405;
}

void main() {
    vec3 z = vec3(standard(vec2(1.0), 7u), standard(u_cells_g, 13u), standard(u_cells_b, 19u));
    out_u = vec4(0.5 + z / 8.0, 0.5);
}
