// The foam's streak noise, tabulated once (water.py WaterPass._foam_noise): two octaves of the
// project's one noise (common/noise.glsl) over one period of FOAM_PERIOD cells in x and y, scaled to
// about standard normal — the two-octave sum over the plane z = 0 is near-normal with sigma 0.405
// (measured) — and stored as 0.5 + z / 8 (8 bits: steps of 0.03 sigma over +-4 sigma), so the water
// shader's dither (water.frag.glsl foam_cover) can add octaves of it and keep its distribution.
#include "common/noise.glsl"

uniform float u_period;  // noise cells per side of the tile
in vec2 v_uv;
layout(location = 0) out vec4 out_u;

void main() {
    float n = turbulence3(vec3(v_uv * u_period, 0.0), vec3(u_period, u_period, 0.0), 2, 7u);
    out_u = vec4(0.5 + n / (0.405 * 8.0));
}
