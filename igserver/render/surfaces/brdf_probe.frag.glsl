// Evaluates common/brdf.glsl's brdf_cos once per pixel for the quality study and the tests:
// pixel (x, y) reads its sample from two RGBA32F textures and writes the BRDF x N.L (float32).
#include "common/frame.glsl"
#include "common/brdf.glsl"
uniform sampler2D u_angles;    // theta_v, theta_l, phi (rad), roughness
uniform sampler2D u_material;  // metallic, base colour rgb (linear)
layout(location = 0) out vec4 out_value;
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec4 a = texelFetch(u_angles, px, 0);
    vec4 m = texelFetch(u_material, px, 0);
    vec3 n = vec3(0.0, 0.0, 1.0);
    vec3 v = vec3(sin(a.x), 0.0, cos(a.x));
    vec3 l = vec3(sin(a.y) * cos(a.z), sin(a.y) * sin(a.z), cos(a.y));
    out_value = vec4(brdf_cos(Material(m.yzw, m.x, a.w), n, v, l), 1.0);
}
