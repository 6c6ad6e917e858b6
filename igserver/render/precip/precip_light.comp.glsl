// Light of every streak, once per streak (not once per quad vertex: 6x less work): sun, moon,
// sky and point/spot lights through the particle's phase function, then the one aerial
// perspective at its head (within the fade distance it varies far less along a streak than the
// streak's own brightness does). Pre-exposed radiance into radiance[].
layout(local_size_x = 64) in;
#include "common/frame.glsl"
#include "common/atmosphere.glsl"
#include "common/brdf.glsl"
#include "common/lights.glsl"
#include "precip/precip_common.glsl"

uniform int u_streaks;              // tiles x particles, every level
uniform int u_level_count;
uniform float u_albedo;
uniform float u_phase_g;           // Henyey-Greenstein asymmetry of one particle's scattering

float henyey_greenstein(float cos_theta, float g) {
    float d = 1.0 + g * g - 2.0 * g * cos_theta;
    return (1.0 - g * g) / (4.0 * PI * d * sqrt(d));
}

// Radiance a particle sends toward the camera: sky light (a drop shows the sky around it, a flake
// reflects it), sun and moon, and the point/spot lights (fires' flicker lights, lamps, searchlights)
// through the particle's phase function; cos(theta) = l . v with v from the camera to the particle.
vec3 particle_radiance(vec3 p) {
    vec3 v = normalize(p);
    vec3 radiance = u_sky_ambient;
    radiance += u_sun_illuminance * henyey_greenstein(dot(u_sun_dir, v), u_phase_g);
    radiance += u_moon_illuminance * henyey_greenstein(dot(u_moon_dir, v), u_phase_g);
    for (int i = 0; i < u_light_count; ++i) {
        vec3 l;
        vec3 e = light_illuminance(i, p, l);
        radiance += e * henyey_greenstein(dot(l, v), u_phase_g);
    }
    return u_albedo * radiance;
}


void main() {
    int s = int(gl_GlobalInvocationID.x);
    if (s >= u_streaks) return;
    int level = 0;  // the streaks of level l start at u_levels[l].LEVEL_FIRST_STREAK, in order
    while (level + 1 < u_level_count && s >= u_levels[level + 1].LEVEL_FIRST_STREAK) ++level;
    ivec4 lv = u_levels[level];
    int local = s - lv.LEVEL_FIRST_STREAK;
    int tile = local / lv.LEVEL_PARTICLES;
    Particle particle = particles[lv.LEVEL_FIRST_PARTICLE + local - tile * lv.LEVEL_PARTICLES];
    vec3 head = particle.pos_diameter.xyz + tiles[lv.LEVEL_FIRST_TILE + tile].xyz;
    vec3 light = particle_radiance(head) * particle.streak_brightness.w;
    radiance[s] = vec4(pre_expose(apply_aerial_perspective(light, head)), 1.0);
}
