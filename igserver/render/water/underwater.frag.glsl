// Under water, what the sea mesh does not cover (water.py draws it after the mesh, for a camera below
// the local surface; water/underwater.glsl has the model): rays going down or level see the column and
// the bed; rays going up that miss the mesh (the near plane's hole, the mesh's error beside the eye)
// see the mean surface from below. The depth written keeps the mesh in front wherever it is drawn: a
// rising ray's depth is past the highest crest, a falling one's the bed or the distance at which the
// water hides everything (UW_OPAQUE) — and anything drawn farther (a ship's far hull) disappears.
#ifndef UW_EVEN_BED  // water.py WaterPass.caustics False: the bed evenly lit
#define UW_CAUSTICS 1
#endif
#include "common/frame.glsl"
#include "common/brdf.glsl"
#include "water/sea_tables.glsl"
#include "water/underwater.glsl"

// Caustics on the bed: sunlight refracted by the rippled surface converges and spreads. A ray through
// a surface of slope s leaves tilted by (1 - 1/n) s, so at depth h it lands displaced by -a s, a =
// h (1 - 1/n); the light through a patch lands on an area det(I - a H) times as large (H the
// surface's Hessian, the slope's gradient, from the detail maps by central differences), so the
// irradiance is 1 / |det(I - a H)|, capped at 5 (the sun's 0.53 deg disc blurs a focus by 0.0046 h:
// the maps are read at least that coarse) and 0 past a fold where the patch turns over (the crossing
// rays carry it), normalised to a mean of 1 (below). The surface point is the one the refracted sun
// ray through the bed point left; the maps' mip filtering smooths distant caustics to 1.
#ifdef UW_CAUSTICS
uniform sampler2D u_detail0;
uniform sampler2D u_detail1;
uniform vec3 u_detail_map[3];
uniform int u_uw_caustic_maps;  // detail maps written this frame that carry waves (0..2)
// The mean of the capped 1 / |det| over the bed: traced back from each bed point (one ray, not every
// branch that lands there) it is biased high; measured 1.4-1.9 for winds of 3-25 m/s and beds 1-8 m
// below the eye (1 + its second-order estimate a^2 sum A^2 k^4 / 2 overshoots: the maps are filtered).
const float UW_CAUSTIC_MEAN = 1.6;

mat2 uw_hessian(sampler2D tex, vec3 map, vec2 xy, float blur_m) {
    vec2 uv = xy * map.x + map.yz;
    float texel = 1.0 / float(textureSize(tex, 0).x);
    float bias = max(log2(blur_m * map.x / texel), 0.0);
    vec2 e = vec2(texel * exp2(bias), 0.0);
    vec2 dx = texture(tex, uv + e.xy, bias).xy - texture(tex, uv - e.xy, bias).xy;
    vec2 dy = texture(tex, uv + e.yx, bias).xy - texture(tex, uv - e.yx, bias).xy;
    float step_m = 2.0 * e.x / map.x;
    return mat2(dx, dy) / step_m;  // columns: the slope's derivative along x and along y (1/m)
}

float uw_caustics(vec3 bed, float depth) {
    if (u_uw_caustic_maps == 0 || u_sun_dir.z <= 0.0) return 1.0;
    vec3 sun_w = refract(-u_sun_dir, vec3(0.0, 0.0, 1.0), 1.0 / UW_N);  // travelling down
    float h = max(depth, 0.0);
    vec2 surface = bed.xy + sun_w.xy * (h / sun_w.z);  // back up the ray to the surface
    float blur = 0.0046 * h;
    mat2 hess = uw_hessian(u_detail0, u_detail_map[0], surface, blur);
    if (u_uw_caustic_maps > 1) hess += uw_hessian(u_detail1, u_detail_map[1], surface, blur);
    float a = h * (1.0 - 1.0 / UW_N);
    mat2 j = mat2(1.0) - a * hess;
    return min(1.0 / max(abs(determinant(j)), 0.2), 5.0) / UW_CAUSTIC_MEAN;
}
#endif

uniform float u_uw_reach;       // m, highest crest above the mean level
uniform vec3 u_glint_dir;
uniform vec3 u_glint_illuminance;

const float UW_OPAQUE = 110.0;  // m: e^{-K D} < 1e-3 in every channel (K >= 0.065 1/m)

in vec2 v_uv;
layout(location = 0) out vec4 out_color;
layout(location = 1) out float out_distance;

void main() {
    vec3 dir = view_ray(v_uv);
    vec3 l;
    float t;
    if (dir.z > 1e-4) {
        float up = u_uw_level_z / dir.z;  // the mean surface
        vec3 n = vec3(0.0, 0.0, 1.0);
        l = uw_surface_from_below(n, dir, max(up, 0.0), 0.05, u_glint_dir, u_glint_illuminance);
        t = min((u_uw_level_z + u_uw_reach) / dir.z, UW_OPAQUE);
    } else {
        float hit;
        l = uw_column(vec3(0.0), dir, hit);
        t = min(hit, UW_OPAQUE);
    }
    out_color = vec4(pre_expose(l), 1.0);
    out_distance = t;
    gl_FragDepth = window_depth(dir * t);
}
