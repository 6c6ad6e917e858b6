// Shadow maps read by lit surfaces (included by common/lights.glsl when SURFACE_SHADOWS is set).
// One map for the key directional light (the sun, or the moon when it is the brighter one), one
// for the brightest spot light. Matrices take camera-relative positions to [0,1]^3 map space.
//
// Soft filtering: percentage-closer filtering with SHADOW_TAPS taps on a Vogel (golden-angle)
// disk of radius u_shadow_softness metres (at least half a texel), rotated per pixel by interleaved gradient noise, each
// tap a hardware 2x2 bilinear compare (sampler2DShadow with LINEAR filtering).
// Bias without acne or peter-panning at a grazing light: the depth pass uses slope-scaled
// polygon offset, and the lookup moves the point along its normal by a fraction of a texel that
// grows with the angle to the light (normal offset), so no large constant depth bias is needed.
#include "generated/bindings.glsl"
#ifndef SHADOW_TAPS
#define SHADOW_TAPS 4
#endif
// KEY_SHADOW_MAP / SPOT_SHADOW_MAP: compile the lookup of a map only when the frame drew it
// (surfaces.py); a run-time test alone still pays for the lookup on llvmpipe.
layout(binding = UNIT_SHADOW_KEY) uniform sampler2DShadow u_key_shadow_map;
uniform mat4 u_key_shadow_matrix;
uniform int u_key_shadow_light;      // SUN_LIGHT, MOON_LIGHT, or 0 when there is no map
uniform float u_key_shadow_texel;    // m, world size of one texel
layout(binding = UNIT_SHADOW_SPOT) uniform sampler2DShadow u_spot_shadow_map;
uniform mat4 u_spot_shadow_matrix;
uniform int u_spot_shadow_light;     // index of the spot light with the map, -1 none
uniform float u_spot_shadow_texel;   // m per texel at 1 m from the spot light
uniform float u_shadow_softness;     // m, PCF radius on the receiver (penumbra half-width)

float interleaved_gradient_noise(vec2 pixel) {
    return fract(52.9829189 * fract(dot(pixel, vec2(0.06711056, 0.00583715))));
}

// Fraction in [0,1] of taps that see an occluder (1 = fully shadowed).
float pcf_shadow(sampler2DShadow map, vec4 coord_h, float radius_texels) {
    vec3 c = coord_h.xyz / coord_h.w;
    if (coord_h.w <= 0.0 || any(lessThan(c.xy, vec2(0.0))) || any(greaterThan(c.xy, vec2(1.0)))) return 0.0;
    // Depth is reversed (render/depth.py): 1 nearest the light, maps cleared to 0. A receiver beyond
    // the map's far plane (the ground under the casters) compares at 0: shadowed where a caster was
    // drawn, lit where the map is empty. The compare is ">=": lit when at least as near the light.
    float ref = max(c.z, 0.0);
    float radius = max(radius_texels, 0.5) / float(textureSize(map, 0).x);
    float angle = 6.2831853 * interleaved_gradient_noise(gl_FragCoord.xy);
    float lit = 0.0;
    for (int i = 0; i < SHADOW_TAPS; ++i) {
        float r = sqrt((float(i) + 0.5) / float(SHADOW_TAPS)) * radius;
        float a = float(i) * 2.39996323 + angle;  // golden angle
        lit += texture(map, vec3(c.xy + r * vec2(cos(a), sin(a)), ref));
    }
    return 1.0 - lit / float(SHADOW_TAPS);
}

float light_shadow(int light, vec3 p, vec3 n, vec3 l) {
    float cos_nl = clamp(dot(n, l), 0.0, 1.0);
    float sin_nl = sqrt(1.0 - cos_nl * cos_nl);
#ifdef KEY_SHADOW_MAP
    if (light == u_key_shadow_light && light < 0) {
        // 1.5 texels along the normal at grazing light, half a texel toward the light always
        vec3 q = p + u_key_shadow_texel * (1.5 * sin_nl * n + 0.5 * l);
        return pcf_shadow(u_key_shadow_map, u_key_shadow_matrix * vec4(q, 1.0), u_shadow_softness / u_key_shadow_texel);
    }
#endif
#ifdef SPOT_SHADOW_MAP
    if (light >= 0 && light == u_spot_shadow_light) {
        float texel = u_spot_shadow_texel * length(u_light_pos[light].xyz - p);
        vec3 q = p + texel * (1.5 * sin_nl * n + 0.5 * l);
        return pcf_shadow(u_spot_shadow_map, u_spot_shadow_matrix * vec4(q, 1.0), u_shadow_softness / texel);
    }
#endif
    return 0.0;
}
