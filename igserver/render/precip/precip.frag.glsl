// Precipitation streaks: hidden behind the scene (copied view distance), round-ended when wide,
// blended premultiplied (ONE, ONE_MINUS_SRC_ALPHA): a streak covers alpha of what
// lies behind it and adds its own radiance.
#include "common/frame.glsl"

uniform sampler2D u_scene_distance;  // m along the view ray, 1e30 = sky

in vec3 v_rel;
noperspective in vec2 v_local;  // px, screen-space (no perspective division)
flat in vec2 v_shape;
flat in vec3 v_radiance;
flat in float v_alpha;
layout(location = 0) out vec4 out_color;

void main() {
    if (v_alpha <= 0.0) discard;
    float scene_t = texelFetch(u_scene_distance, ivec2(gl_FragCoord.xy), 0).r;
    if (length(v_rel) > scene_t) discard;
    float alpha = v_alpha;
    if (v_shape.y > 2.0) {  // capsule: distance from the streak's axis segment, soft 1 px edge
        float half_w = 0.5 * v_shape.y;
        float x = max(abs(v_local.x - half_w - 0.5 * v_shape.x) - 0.5 * v_shape.x, 0.0);
        alpha *= clamp(half_w + 0.5 - length(vec2(x, v_local.y)), 0.0, 1.0);
    }
    out_color = vec4(v_radiance * alpha, alpha);
}
