// Light loop shared by every lit surface: sky ambient, sun, moon, point and spot lights, with the
// paper's shadow terms (docs/design.md#surfaces):
//   I = Ra*Ia + sum_j E_j * ( Rd_j * ((1 - k_j) + k_j * c_sh) + (1 - f_j) * Rs_j ),   k_j = d_sh * f_j
// where Rd_j, Rs_j are the diffuse and specular BRDF lobes times N.L (common/brdf.glsl), f_j in
// [0,1] is how much light j is blocked at the point (soft shadow maps), d_sh the shadow density
// and c_sh the shadow colour (the part of the diffuse light a full shadow leaves). We read c_sh
// as multiplying the diffuse lobe, so a black surface stays black in a coloured shadow.
// Point/spot lights arrive camera-relative, brightest-at-the-camera first, at most MAX_LIGHTS; the
// loop stops at u_light_count and skips lights out of range, so cost grows with the lights present.
// Passes that define SURFACE_SHADOWS get shadow maps (common/shadows.glsl); others (water, rain)
// include this file unchanged and see no shadows.
// Compile-time light terms (frame.py light_defines): a pass that knows the frame defines SUN_TERM /
// MOON_TERM as 0 when that body is below -0.1 (its term would be skipped at run time anyway). On
// llvmpipe a branch not taken still costs much of its body (SIMD code runs masked), so the
// night frame drops the sun's BRDF and shadow code entirely. Undefined: both compiled, run-time test.
// LOCAL_LIGHTS 0: the frame has no point or spot light. A loop over u_light_count runs its body once
// even for a count of 0 (masked, all lanes off), which cost the water ~6 ms of workers' CPU a frame.
#ifndef LOCAL_LIGHTS
#define LOCAL_LIGHTS 1
#endif
// SPOT_LIGHTS 0: no light of the frame is a spot (frame.py local_light_defines): the cone test is
// left out. Untaken, it still cost the demo's sea 3-4 ms of workers' CPU a frame (its uniforms read
// by the loop index and the smoothstep run masked for every point light).
#ifndef SPOT_LIGHTS
#define SPOT_LIGHTS 1
#endif
#ifndef SUN_TERM
#define SUN_TERM 1
#endif
#ifndef MOON_TERM
#define MOON_TERM 1
#endif
// u_light_count, u_light_pos, u_light_color, u_light_dir, u_light_cos_inner and MAX_LIGHTS: the
// frame's block (common/frame.glsl).
uniform float u_shadow_density;          // d_sh in [0,1] (0 when unset: no shadow terms)
uniform vec3 u_shadow_color;             // c_sh, linear

// Light ids for light_shadow(): the directional lights; point/spot lights use their index.
const int SUN_LIGHT = -1;
const int MOON_LIGHT = -2;
// Fraction of the sky's light reflected by the ground toward surfaces that face down (a
// typical soil/concrete/sea albedo; the ground itself is lit by the sun and the sky).
const float GROUND_BOUNCE_ALBEDO = 0.15;

#ifdef SURFACE_SHADOWS
#include "common/shadows.glsl"
#else
float light_shadow(int light, vec3 p, vec3 n, vec3 l) { return 0.0; }
#endif

// Smooth range window: inverse-square falloff that reaches exactly 0 at the light's range.
float range_window(float d, float range) {
    float x = d / range;
    float w = clamp(1.0 - x * x * x * x, 0.0, 1.0);
    return w * w;
}

// Illuminance (lux per channel) that light i casts at p on a plane facing it; l: unit, toward it.
// Surfaces weight it by the BRDF, particles (rain, snow) by their phase function.
vec3 light_illuminance(int i, vec3 p, out vec3 l) {
    vec3 to_light = u_light_pos[i].xyz - p;
    float d2 = max(dot(to_light, to_light), 1e-4);
    float d = sqrt(d2);
    l = to_light / d;
    float factor = range_window(d, u_light_pos[i].w) / d2;  // cd -> lux
#if SPOT_LIGHTS
    if (u_light_color[i].w > 0.5) {  // spot cone
        float c = dot(-l, u_light_dir[i].xyz);
        factor *= smoothstep(u_light_dir[i].w, u_light_cos_inner[i], c);
    }
#endif
    return u_light_color[i].rgb * factor;
}

// One light of illuminance e (lux per channel at the point, before N.L) with blocked fraction f.
// b: brdf_view(m, n, v), once per pixel for all its lights.
vec3 shadowed_light(Material m, BrdfView b, vec3 n, vec3 v, vec3 l, vec3 e, float f) {
    BrdfTerms t = brdf_terms(m, b, n, v, l);
    float k = u_shadow_density * f;
    return e * (t.diffuse * ((1.0 - k) + k * u_shadow_color) + (1.0 - f) * t.specular);
}

// Sky ambient: u_sky_ambient is the sky's irradiance / pi on an up-facing surface. A surface
// tilted by theta sees (1 + cos theta)/2 of the sky and the rest of the (lit) ground; ao in [0,1]
// is the material's ambient occlusion.
vec3 ambient_light(Material m, vec3 n, vec3 v, float ao) {
    float sky_view = 0.5 + 0.5 * n.z;
    vec3 ground = GROUND_BOUNCE_ALBEDO * (u_sky_ambient + u_sun_illuminance * max(u_sun_dir.z, 0.0) / PI);
    vec3 l_amb = u_sky_ambient * sky_view + ground * (1.0 - sky_view);
    vec3 spec = specular_albedo(m, dot(n, v));
    vec3 diffuse = m.base_color * (1.0 - m.metallic) * (1.0 - spec);
    return ao * l_amb * (diffuse + spec);
}

vec3 shade_surface_ao(Material m, vec3 p, vec3 n, vec3 v, float ao) {
    vec3 radiance = ambient_light(m, n, v, ao);  // Ra * Ia
    BrdfView b = brdf_view(m, n, v);
#if SUN_TERM
    if (u_sun_dir.z > -0.1)
        radiance += shadowed_light(m, b, n, v, u_sun_dir, u_sun_illuminance, light_shadow(SUN_LIGHT, p, n, u_sun_dir));
#endif
#if MOON_TERM
    if (u_moon_dir.z > -0.1)
        radiance += shadowed_light(m, b, n, v, u_moon_dir, u_moon_illuminance, light_shadow(MOON_LIGHT, p, n, u_moon_dir));
#endif
#if LOCAL_LIGHTS
    for (int i = 0; i < u_light_count; ++i) {
        vec3 d = u_light_pos[i].xyz - p;
        if (dot(d, d) >= u_light_pos[i].w * u_light_pos[i].w) continue;  // out of range: no cost
        vec3 l;
        vec3 e = light_illuminance(i, p, l);
        if (max(e.r, max(e.g, e.b)) <= 0.0 || dot(n, l) <= 0.0) continue;
        radiance += shadowed_light(m, b, n, v, l, e, light_shadow(i, p, n, l));
    }
#endif
    return radiance;
}

vec3 shade_surface(Material m, vec3 p, vec3 n, vec3 v) {
    return shade_surface_ao(m, p, n, v, 1.0);
}
