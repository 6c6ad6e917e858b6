// Light loop shared by every lit surface: sky ambient, sun, moon, point and spot lights, with the
// paper's shadow terms (docs/design.md#surfaces):
//   I = Ra*Ia + sum_j E_j * ( Rd_j * ((1 - k_j) + k_j * c_sh) + (1 - f_j) * Rs_j ),   k_j = d_sh * f_j
// where Rd_j, Rs_j are the diffuse and specular BRDF lobes times N.L (common/brdf.glsl), f_j in
// [0,1] is how much light j is blocked at the point (soft shadow maps), d_sh the shadow density
// and c_sh the shadow colour (the part of the diffuse light a full shadow leaves). We read c_sh
// as multiplying the diffuse lobe, so a black surface stays black in a coloured shadow.
// Point/spot lights arrive camera-relative, brightest-at-the-camera first, at most MAX_LIGHTS.
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
// LIGHT_TILES 1: a pixel loops over its screen tile's lights only (tile_lights: those whose range
// can reach a point seen in the tile, render/light_tiles.py), in ascending index as the full loop
// does, so the sum is the full loop's: a light left out adds exactly 0 there (range_window). On
// llvmpipe a light skipped inside the loop still costs its whole body (masked SIMD), so only a
// shorter loop saves it. 0 (frame.py local_light_defines: no tile lists fewer lights than the frame
// has, or a pass that does not say): every light, no lookup.
#ifndef LIGHT_TILES
#define LIGHT_TILES 0
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

#if LOCAL_LIGHTS && LIGHT_TILES
// Tile light lists: one RG32UI texel per LIGHT_TILE_PX^2 tile of the view, bit i set when light i
// can reach the tile (bit 32 + i of .y for i >= 32). Row 0 is the bottom row.
layout(binding = UNIT_LIGHT_TILES) uniform usampler2D u_light_tiles;

// The light mask of the tile p is seen in. The tile comes from p itself, through the image-plane
// tangents view_ray() uses (x = p.right / p.forward, pixel x = (x - left) / (right - left) * width),
// not from gl_FragCoord: the lists then hold for any point of the frame's view whatever target is
// drawn. A point off the grid (behind the camera, outside the frustum) gets every light.
uvec2 tile_lights(vec3 p) {
    float depth = dot(p, u_camera_forward);
    vec2 tangent = vec2(dot(p, u_camera_right), dot(p, u_camera_up)) / depth;
    vec2 px = (tangent - u_frustum_tangents.xz) / (u_frustum_tangents.yw - u_frustum_tangents.xz) * u_resolution;
    px = clamp(px, vec2(-1.0), u_resolution + float(LIGHT_TILE_PX));  // keeps the int conversion defined
    ivec2 tile = ivec2(floor(px / float(LIGHT_TILE_PX)));
    ivec2 size = textureSize(u_light_tiles, 0);
    bool inside = depth > 0.0 && all(greaterThanEqual(tile, ivec2(0))) && all(lessThan(tile, size));
    uvec2 every = uvec2(u_light_count >= 32 ? ~0u : (1u << u_light_count) - 1u,
                        u_light_count >= 64 ? ~0u : (1u << max(u_light_count - 32, 0)) - 1u);
    uvec2 listed = texelFetch(u_light_tiles, clamp(tile, ivec2(0), size - 1), 0).xy;
    return inside ? listed : every;
}

// The lowest light of ``lights`` (not empty), removed from it: lights come in ascending index.
int next_light(inout uvec2 lights) {
    bool low = lights.x != 0u;
    uint word = low ? lights.x : lights.y;
    int i = findLSB(word) + (low ? 0 : 32);
    word &= word - 1u;
    lights = low ? uvec2(word, lights.y) : uvec2(0u, word);
    return i;
}

bool any_light(uvec2 lights) {
    return (lights.x | lights.y) != 0u;
}
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
#if LIGHT_TILES
    for (uvec2 lights = tile_lights(p); any_light(lights);) {
        int i = next_light(lights);
#else
    for (int i = 0; i < u_light_count; ++i) {
#endif
        vec3 d = u_light_pos[i].xyz - p;
        if (dot(d, d) >= u_light_pos[i].w * u_light_pos[i].w) continue;  // out of range
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
