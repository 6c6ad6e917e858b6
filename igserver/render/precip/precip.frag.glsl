// Precipitation streaks: hidden behind the scene (copied view distance), blended premultiplied (ONE, ONE_MINUS_SRC_ALPHA): a streak covers alpha of what
// lies behind it and adds its own radiance.
#include "common/frame.glsl"

uniform sampler2D u_scene_distance;  // m along the view ray, 1e30 = sky

in vec3 v_rel;
flat in vec3 v_radiance;
flat in float v_alpha;
layout(location = 0) out vec4 out_color;

void main() {
    if (v_alpha <= 0.0) discard;
    float scene_t = texelFetch(u_scene_distance, ivec2(gl_FragCoord.xy), 0).r;
    if (length(v_rel) > scene_t) discard;
    out_color = vec4(v_radiance * v_alpha, v_alpha);
}
