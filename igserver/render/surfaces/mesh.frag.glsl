#include "common/frame.glsl"
#include "common/atmosphere.glsl"
#include "common/brdf.glsl"
#include "common/lights.glsl"
uniform vec3 u_base_color;
uniform float u_metallic;
uniform float u_roughness;
in vec3 v_rel;
in vec3 v_normal;
layout(location = 0) out vec4 out_color;
layout(location = 1) out float out_distance;
void main() {
    vec3 n = normalize(v_normal);
    vec3 v = normalize(-v_rel);
    if (dot(n, v) < 0.0) n = -n;  // two-sided
    Material m = Material(u_base_color, u_metallic, u_roughness);
    vec3 lit = shade_surface(m, v_rel, n, v);
    out_color = vec4(pre_expose(apply_aerial_perspective(lit, v_rel)), 1.0);
    out_distance = length(v_rel);
}
