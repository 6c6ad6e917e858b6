// Modelling stage (docs/design.md#fire-and-smoke): one voxel per invocation of an effect's 3D texture.
//
// Normalised container: (x, y) in [-1,1] (units of the container radius), z in [0,1] (height).
//   P = (q_m / lambda) - (0, 0, tau)          q_m: metres from the base centre at nominal size
//   u = sqrt(x^2 + y^2)    v = z + Roughness * Turb(P) * sqrt(z)    (colour, density) = Profile(u, v)
// (a pool fire's u and v then puff: main() below)
// This is the paper's P = (x, y, z - time) * noiseScale with the noise attached to the nominal
// (un-faded) container, lambda = nominal radius / noiseScale, so it stays isotropic in metres and
// does not jump when the fade changes the container's size; tau is reduced modulo the noise period
// on the CPU in float64.
//
// Output (rgba16f): fire: rgb = emitted colour (x the effect's luminance at render time), a = density.
// smoke: r = transmittance toward the sun, g = toward the zenith (sky light), b = albedo, a = density;
// the two shadow rays march the profile without turbulence (cheap, smooth, slightly soft). They do
// not depend on the noise scroll, so SHADOWS models them alone into an rg16f texture once per
// change of their inputs (size, extent, sun, extinction, opacity: modelling.py) and each smoke
// keyframe reads them back (u_shadows): ~40 % of a smoke keyframe's modelling.
#include "common/noise.glsl"

layout(local_size_x = 4, local_size_y = 4, local_size_z = 4) in;
#ifdef SHADOWS
layout(rg16f, binding = 0) writeonly uniform image3D u_volume;
#else
layout(rgba16f, binding = 0) writeonly uniform image3D u_volume;
#endif
#ifdef SMOKE
#ifndef SHADOWS
// Not declared in the SHADOWS variant: left unset there, it would share unit 0 with u_profile as
// another sampler type, and GL refuses the dispatch wherever a compiler counts such a sampler as
// active (tests/test_gl_hazards.py).
uniform sampler3D u_shadows;  // (t_sun, t_sky) per voxel, from the SHADOWS variant
#endif
#endif
uniform sampler2D u_profile;
uniform ivec3 u_size;
uniform int u_z_first;       // first z slice of this dispatch (a keyframe is modelled in slices, modelling.py)
uniform vec3 u_extent;       // m: (radius, radius, height) of the container now (after fade)
uniform float u_wavelength;  // m per noise lattice unit (lambda)
uniform float u_tau;         // noise scroll along P.z, lattice units, in [0, period)
uniform float u_period;      // noise period along P.z, lattice units
uniform float u_roughness;
uniform int u_octaves;
uniform uint u_seed;
uniform float u_opacity;     // fade: profile opacity
uniform float u_cooling;     // 0 burning .. 1 dying: the colour reddens and dims
uniform vec3 u_sun_local;    // direction to the sun in normalised container units (unit length in metres)
uniform float u_sigma;       // 1/m, extinction of density 1 (smoke shadow rays)
uniform float u_puff;            // pool fire's puffing: relative amplitude (0: none)
uniform float u_puff_phase;      // rad, 2 pi f t (f = 1.5 / sqrt(D) Hz), reduced on the CPU
uniform float u_puff_wavenumber; // rad/m, 2 pi f / w: vortices rising at the flame's speed w

const int SHADOW_STEPS = 6;

float profile_density(vec3 n) {
    float u = length(n.xy);
    if (u >= 1.0 || n.z <= 0.0 || n.z >= 1.0) return 0.0;
    return textureLod(u_profile, vec2(u, n.z), 0.0).a;
}

// Transmittance from normalised point n along direction d (metres per unit step in d_m).
float shadow(vec3 n, vec3 dir_m) {
    vec3 dir_n = dir_m / u_extent;                      // normalised units per metre
    // Distance (m) to leave the container's cylinder-ish bounds: march a fixed budget of its size.
    float length_m = 2.0 * max(u_extent.x, u_extent.z) / float(SHADOW_STEPS);
    float tau = 0.0;
    for (int i = 0; i < SHADOW_STEPS; ++i) {
        vec3 p = n + dir_n * (length_m * (float(i) + 0.5));
        tau += profile_density(p) * length_m;
    }
    return exp(-min(tau * u_sigma * u_opacity, 60.0));
}

void main() {
    ivec3 id = ivec3(gl_GlobalInvocationID) + ivec3(0, 0, u_z_first);
    if (any(greaterThanEqual(id, u_size))) return;
    vec3 n = (vec3(id) + 0.5) / vec3(u_size);
    n.xy = n.xy * 2.0 - 1.0;                            // normalised container coordinates
#ifdef SHADOWS
    imageStore(u_volume, id, vec4(shadow(n, u_sun_local), shadow(n, vec3(0.0, 0.0, 1.0)), 0.0, 0.0));
    return;
#else
    vec3 q = n * u_extent;                              // metres from the base centre
    vec3 p = q / u_wavelength - vec3(0.0, 0.0, u_tau);
    float turb = turbulence3(p, vec3(0.0, 0.0, u_period), u_octaves, u_seed);
    float u = length(n.xy);
    float v = n.z + u_roughness * turb * sqrt(n.z);
    // Puffing: a wave of necks and bulges travels up the flame, u / (1 + a(z) sin(2 pi f t - k z)).
    // The flame stays attached to the pool's rim and the vortex grows as it rises: a(z) ramps from
    // 0 at the pool to u_puff at a quarter of the container's height. There the profile's envelope
    // (0.95 (1 - z)^0.6, profiles.py fire_profile) is 0.8 of the container's radius, so a bulge of
    // 1 + a(z) <= 1.25 stays inside it at every height; a full-amplitude bulge at the base would
    // cut the flame flat at the container's sides.
    if (u_puff > 0.0) u /= 1.0 + u_puff * min(n.z * 4.0, 1.0) * sin(u_puff_phase - u_puff_wavenumber * q.z);
    vec4 prof = (u < 1.0 && v < 1.0) ? textureLod(u_profile, vec2(u, clamp(v, 0.0, 1.0)), 0.0) : vec4(0.0);
    float density = prof.a * u_opacity;
#ifdef SMOKE
    vec2 t_sun_sky = texelFetch(u_shadows, id, 0).rg;
    imageStore(u_volume, id, vec4(t_sun_sky, prof.r, density));
#else
    // Dying fire cools: red survives longest (a blackbody's blue and green fall first).
    vec3 cool = pow(vec3(1.0, 0.75, 0.5), vec3(3.0 * u_cooling));
    imageStore(u_volume, id, vec4(prof.rgb * cool * (1.0 - 0.6 * u_cooling), density));
#endif
#endif
}
