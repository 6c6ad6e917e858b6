// Shared by the precipitation light pass (precip_light.comp.glsl) and the streak vertex shader
// (precip.vert.glsl): the particle, tile and per-streak radiance buffers, per-level uniforms.
struct Particle {
    vec4 pos_diameter;       // xyz m in [0, L), camera-relative wrapped; w diameter m
    vec4 streak_brightness;  // xyz m, p(t) - p(t - T); w brightness factor (~1)
};
layout(std430, binding = 0) readonly buffer Particles { Particle particles[]; };
layout(std430, binding = 1) readonly buffer Tiles { vec4 tiles[]; };  // xyz camera-relative offset

layout(std430, binding = 2) buffer Radiance { vec4 radiance[]; };  // per streak, pre-exposed

uniform int u_first_tile;          // this level's tiles start here
uniform int u_first_particle;      // this level's particles start here
uniform int u_particles;           // particles per tile at this level
uniform int u_first_streak;        // this level's entries in radiance[] start here
