// The water pass's two per-frame tables (water.py, SeaTables), filled once per frame from the shared
// atmosphere library (common/atmosphere.glsl) so the sea's vertices and pixels pay one or two
// bilinear lookups instead of re-evaluating the atmosphere:
//
//   sky reflection  u_sky_reflect: sky_radiance(dir) (fog included) over the upper hemisphere, the
//                   only directions a reflected ray takes (water.frag mirrors the rest up), on a disk:
//                   s = dir.xy / (1 + dir.z) (stereographic), uv = (1 + s |s|) / 2 — a division and
//                   a square root per pixel (no inverse trigonometry); the |s| stretch gives the
//                   horizon, where the sky changes fastest, twice the rows of the plain projection
//                   (0.45 deg per texel at 128 texels) and the smooth zenith fewer.
//   aerial persp.   u_sea_air_t, u_sea_air_s: apply_aerial_perspective(L, rel) = L * T + S for points
//                   on the mean sea surface (earth's drop included), indexed by u = world azimuth /
//                   2 pi, v = log(1 + d / d0) / log(1 + d_max / d0) with d the distance from the
//                   camera (rows uniform in log distance: ~10 % steps past d0). A wave point uses its
//                   own azimuth and distance: its height changes only the direction within a few
//                   degrees of the surface, which matters only near the camera where the air in front
//                   is thin.
// Needs PI (common/frame.glsl). WATER_EXACT_ATMOSPHERE: the same functions evaluated directly instead
// (per pixel / per vertex; the reference of `igserver quality water` for the tables' error).
#ifdef WATER_EXACT_ATMOSPHERE
#include "common/atmosphere.glsl"
#endif
uniform sampler2D u_sky_reflect;
uniform sampler2D u_sea_air_t;
uniform sampler2D u_sea_air_s;
uniform vec2 u_sea_air_map;  // d0 (m), 1 / log(1 + d_max / d0)

float sea_azimuth_u(vec2 xy) {
    return atan(xy.y, xy.x) * (0.5 / PI) + 0.5;
}

vec3 sky_reflection(vec3 dir) {  // dir.z >= 0
#ifdef WATER_EXACT_ATMOSPHERE
    return sky_radiance(vec3(dir.xy, max(dir.z, 0.0)));
#endif
    vec2 st = dir.xy / (1.0 + max(dir.z, 0.0));
    return texture(u_sky_reflect, 0.5 + 0.5 * st * length(st)).rgb;
}

vec2 sea_air_uv(vec3 rel) {
    return vec2(sea_azimuth_u(rel.xy), log(1.0 + length(rel) / u_sea_air_map.x) * u_sea_air_map.y);
}

// apply_aerial_perspective for a sea point, as the affine map L -> L * t + s.
void sea_aerial_perspective(vec3 rel, out vec3 t, out vec3 s) {
#ifdef WATER_EXACT_ATMOSPHERE
    s = apply_aerial_perspective(vec3(0.0), rel);
    t = apply_aerial_perspective(vec3(1.0), rel) - s;
    return;
#endif
    vec2 uv = sea_air_uv(rel);
    t = textureLod(u_sea_air_t, uv, 0.0).rgb;
    s = textureLod(u_sea_air_s, uv, 0.0).rgb;
}

// Light entering the sea (lux on a horizontal surface) from the sun, the moon and the sky; the local
// lights are added by the caller.
vec3 sea_downwelling() {
    return u_sun_illuminance * max(u_sun_dir.z, 0.0) + u_moon_illuminance * max(u_moon_dir.z, 0.0)
         + PI * u_sky_ambient;
}
const vec3 DEEP_ALBEDO = vec3(0.004, 0.016, 0.022); // backscatter of the deep water column
