// Under water, what the surfaces pass drew before the sea (hulls, piles, the quay's feet): each such
// pixel seen through the water between it and the eye (water/underwater.glsl), drawn in two blended
// passes over the colour (water.py): u_uw_pass 0 multiplies it by the water's transmittance along the
// ray and the daylight lost down to the point, 1 adds the light scattered into the ray. Pixels nothing
// was drawn at yet (distance 0) are left alone; a point above the water level is seen through the
// water up to the mean surface only.
#include "common/frame.glsl"
#include "common/brdf.glsl"
#include "water/sea_tables.glsl"
#include "water/underwater.glsl"

uniform sampler2D u_uw_distance;  // the frame's distance so far (m along the ray; 0: nothing drawn)
uniform int u_uw_pass;

in vec2 v_uv;
layout(location = 0) out vec4 out_color;

void main() {
    float d = texelFetch(u_uw_distance, ivec2(gl_FragCoord.xy), 0).r;
    if (d <= 0.0) discard;
    vec3 dir = view_ray(v_uv);
    float wet = dir.z > 1e-4 ? min(d, max(u_uw_level_z, 0.0) / dir.z) : d;  // path in the water
    float point_depth = max(u_uw_level_z - d * dir.z, 0.0);
    if (u_uw_pass == 0) {
        out_color = vec4(exp(-UW_K * (wet + point_depth)), 1.0);
    } else {
        out_color = vec4(pre_expose(uw_inscatter(dir.z, wet, u_uw_level_z)), 1.0);
    }
}
