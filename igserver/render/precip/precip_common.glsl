// Shared by the precipitation light pass (precip_light.comp.glsl) and the streak vertex shader
// (precip.vert.glsl): the particle, tile and per-streak radiance buffers, the level table.
struct Particle {
    vec4 pos_diameter;       // xyz m in [0, L), camera-relative wrapped; w diameter m
    vec4 streak_brightness;  // xyz m, p(t) - p(t - T); w brightness factor (~1)
};
layout(std430, binding = 0) readonly buffer Particles { Particle particles[]; };
layout(std430, binding = 1) readonly buffer Tiles { vec4 tiles[]; };  // xyz camera-relative offset, w level

layout(std430, binding = 2) buffer Radiance { vec4 radiance[]; };  // per streak, pre-exposed

// The levels of detail (particles.py Level), written when the layout changes: per level its
// first tile, first particle, particles per tile and first entry in radiance[].
#define MAX_LEVELS 16
uniform ivec4 u_levels[MAX_LEVELS];
#define LEVEL_FIRST_TILE x
#define LEVEL_FIRST_PARTICLE y
#define LEVEL_PARTICLES z
#define LEVEL_FIRST_STREAK w
