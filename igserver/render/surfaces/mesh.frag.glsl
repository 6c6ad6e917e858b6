// glTF 2.0 metallic-roughness material (base colour sRGB, metallic-roughness, normal, occlusion,
// emissive textures; OPAQUE / MASK / BLEND) shaded by the project's one BRDF and light loop.
#include "common/frame.glsl"
#include "common/atmosphere.glsl"
#include "common/brdf.glsl"
#include "common/lights.glsl"
#include "common/aerial_table.glsl"
uniform sampler2D u_base_tex;       // sRGB texture: sampled as linear
uniform sampler2D u_mr_tex;         // G = roughness, B = metallic (linear)
uniform sampler2D u_normal_tex;     // tangent-space normal, RGB -> xyz in [-1,1]
uniform sampler2D u_occlusion_tex;  // R = ambient occlusion
uniform sampler2D u_emissive_tex;   // sRGB
uniform vec4 u_base_factor;
uniform float u_metallic_factor;
uniform float u_roughness_factor;
uniform float u_normal_scale;
uniform float u_occlusion_strength;
uniform vec3 u_emissive_factor;     // x EMISSIVE_LUMINANCE cd/m^2
uniform int u_alpha_mode;           // 0 OPAQUE, 1 MASK, 2 BLEND
uniform float u_alpha_cutoff;
uniform int u_has_normal_tex;
in vec3 v_rel;
in vec3 v_normal;
in vec2 v_uv;
flat in vec4 v_tint;
flat in float v_roughness_factor;
#ifndef SHADOW_PASS
layout(location = 0) out vec4 out_color;
layout(location = 1) out float out_distance;
#endif

// A glTF emissive of 1 is drawn as a lit panel of this luminance (a backlit sign, a lit window).
const float EMISSIVE_LUMINANCE = 200.0;  // cd/m^2

// Tangent frame from screen-space derivatives (Schüler 2013, "followup: normal mapping without
// precomputed tangents"): no TANGENT attribute needed. glTF's normal maps have +Y toward -v.
mat3 cotangent_frame(vec3 n, vec3 p, vec2 uv) {
    vec3 dp1 = dFdx(p), dp2 = dFdy(p);
    vec2 duv1 = dFdx(uv), duv2 = dFdy(uv);
    vec3 dp2perp = cross(dp2, n), dp1perp = cross(n, dp1);
    vec3 t = dp2perp * duv1.x + dp1perp * duv2.x;
    vec3 b = dp2perp * duv1.y + dp1perp * duv2.y;
    float scale = inversesqrt(max(max(dot(t, t), dot(b, b)), 1e-30));
    return mat3(t * scale, -b * scale, n);
}

void main() {
#ifdef SHADOW_PASS
    // Depth only. Opaque materials use the variant without ALPHA_TEST: an empty fragment shader
    // keeps early depth testing (a discard anywhere in the shader turns it off).
#ifdef ALPHA_TEST
    float alpha = texture(u_base_tex, v_uv).a * u_base_factor.a;
    if (alpha < (u_alpha_mode == 1 ? u_alpha_cutoff : 0.5)) discard;  // blended surfaces cast where mostly opaque
#endif
#else
    vec4 base = texture(u_base_tex, v_uv) * u_base_factor * vec4(v_tint.rgb, 1.0);
    if (u_alpha_mode == 1 && base.a < u_alpha_cutoff) discard;
    vec3 n = normalize(v_normal);
    vec3 v = normalize(-v_rel);
    if (!gl_FrontFacing) n = -n;  // double-sided (and backfaces of thin single-sided parts)
    if (u_has_normal_tex != 0) {
        vec3 t = texture(u_normal_tex, v_uv).xyz * 2.0 - 1.0;
        t.xy *= u_normal_scale;
        vec3 mapped = cotangent_frame(n, v_rel, v_uv) * t;
        if (dot(mapped, mapped) > 1e-12) n = normalize(mapped);
    }
    vec4 mr = texture(u_mr_tex, v_uv);
    float metallic = clamp(mr.b * u_metallic_factor * v_tint.a, 0.0, 1.0);
    float roughness = clamp(mr.g * u_roughness_factor * v_roughness_factor, 0.02, 1.0);
    float ao = 1.0 + u_occlusion_strength * (texture(u_occlusion_tex, v_uv).r - 1.0);
    Material m = Material(base.rgb, metallic, roughness);
    vec3 lit = shade_surface_ao(m, v_rel, n, v, ao);
    lit += EMISSIVE_LUMINANCE * u_emissive_factor * texture(u_emissive_tex, v_uv).rgb;
    float alpha = u_alpha_mode == 2 ? base.a : 1.0;
    out_color = vec4(pre_expose(aerial_perspective(lit, v_rel)), alpha);
    out_distance = length(v_rel);
#endif
}
