// Under water, what the sea mesh does not cover (water.py draws it after the mesh, for a camera below
// the local surface; water/underwater.glsl has the model): rays going down or level see the column and
// the bed; rays going up that miss the mesh (the near plane's hole, the mesh's error beside the eye)
// see the mean surface from below. The depth written keeps the mesh in front wherever it is drawn: a
// rising ray's depth is past the highest crest, a falling one's the bed or the distance at which the
// water hides everything (UW_OPAQUE) — and anything drawn farther (a ship's far hull) disappears.
#include "common/frame.glsl"
#include "common/brdf.glsl"
#include "water/sea_tables.glsl"
#include "water/underwater.glsl"

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
