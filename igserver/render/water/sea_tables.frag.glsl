// Fills the water pass's per-frame tables (see sea_tables.glsl) from the shared atmosphere library.
// SEA_TABLE_SKY: the sky reflection table (one output); else the aerial perspective table (two).
#include "common/frame.glsl"
#include "common/atmosphere.glsl"

uniform vec2 u_sea_air_map;  // d0 (m), 1 / log(1 + d_max / d0)
uniform float u_level_z;     // m, camera-relative z of the mean sea level

in vec2 v_uv;  // texel centres: the viewport is the table
layout(location = 0) out vec4 out_0;
#ifndef SEA_TABLE_SKY
layout(location = 1) out vec4 out_1;
#endif

const float EARTH_RADIUS = 6.371e6;

void main() {
#ifdef SEA_TABLE_SKY
    // Inverse stereographic projection; texels outside the unit disk (never read but by the bilinear
    // footprint of the horizon) hold the horizon's radiance.
    vec2 q = 2.0 * v_uv - 1.0;
    q *= inversesqrt(max(length(q), 1e-12));  // undo the |s| stretch: q = s
    float q2 = dot(q, q);
    vec3 dir = q2 < 1.0 ? vec3(2.0 * q, 1.0 - q2) / (1.0 + q2) : vec3(q / sqrt(q2), 0.0);
    out_0 = vec4(sky_radiance(dir), 1.0);
#else
    float az = (v_uv.x - 0.5) * 2.0 * PI;
    vec2 h = vec2(cos(az), sin(az));
    float d = u_sea_air_map.x * (exp(v_uv.y / u_sea_air_map.y) - 1.0);
    // The mean sea point at distance d in this azimuth: horizontal distance r, earth's drop below it
    // (as water.vert.glsl).
    float r = sqrt(max(d * d - u_level_z * u_level_z, 0.0));
    float drop = r * r / (EARTH_RADIUS + sqrt(max(EARTH_RADIUS * EARTH_RADIUS - r * r, 0.0)));
    vec3 rel = d * normalize(vec3(r * h, u_level_z - drop));
    vec3 s = apply_aerial_perspective(vec3(0.0), rel);
    out_0 = vec4(apply_aerial_perspective(vec3(1.0), rel) - s, 1.0);
    out_1 = vec4(s, 1.0);
#endif
}
