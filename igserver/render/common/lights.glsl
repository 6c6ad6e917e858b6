// Light loop shared by every lit surface: sun, moon, sky ambient, point and spot lights.
// Point/spot lights arrive camera-relative, nearest/brightest first, at most MAX_LIGHTS.
#ifndef MAX_LIGHTS
#define MAX_LIGHTS 16
#endif
uniform int u_light_count;
uniform vec4 u_light_pos[MAX_LIGHTS];    // xyz camera-relative m, w = range m
uniform vec4 u_light_color[MAX_LIGHTS];  // rgb = colour * intensity (cd), w = 1 spot / 0 point
uniform vec4 u_light_dir[MAX_LIGHTS];    // xyz spot axis, w = cos(outer cone)
uniform float u_light_cos_inner[MAX_LIGHTS];

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
    if (u_light_color[i].w > 0.5) {  // spot cone
        float c = dot(-l, u_light_dir[i].xyz);
        factor *= smoothstep(u_light_dir[i].w, u_light_cos_inner[i], c);
    }
    return u_light_color[i].rgb * factor;
}

vec3 shade_surface(Material m, vec3 p, vec3 n, vec3 v) {
    vec3 radiance = m.base_color * (1.0 - m.metallic) * u_sky_ambient;  // Ra * Ia
    radiance += u_sun_illuminance * brdf_cos(m, n, v, u_sun_dir);
    radiance += u_moon_illuminance * brdf_cos(m, n, v, u_moon_dir);
    for (int i = 0; i < u_light_count; ++i) {
        vec3 l;
        vec3 e = light_illuminance(i, p, l);
        radiance += e * brdf_cos(m, n, v, l);
    }
    return radiance;
}
