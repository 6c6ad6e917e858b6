// Post pass: the HDR target is already pre-exposed; tone map (ACES fit, Narkowicz 2015), encode
// sRGB, and dither by half an 8-bit step with interleaved gradient noise to hide banding.
#include "common/frame.glsl"

uniform sampler2D u_hdr;
uniform sampler2D u_distance;        // m along the view ray (1e30: sky)

// Halos of lights in fog (issue 10: a night fog glows around fires and lamps, more as visibility
// falls): the single-scattered light of each point source along the pixel's view ray up to the
// surface, in a homogeneous medium of the fog's extinction at the camera (beta, albedo omega,
// Henyey-Greenstein g). With h the light's distance from the ray and s = t0 + h tan(phi):
//   L = omega beta I / h  integral_{phi0}^{phi1} p(sin phi) exp(-beta (s + h / cos phi)) dphi,
// phi0 = -atan(t0 / h), phi1 = atan((D - t0) / h); 8 midpoint steps in phi (smooth in phi).
#ifdef HALOS
#define MAX_HALOS 8
uniform int u_halo_count;
uniform vec4 u_halo_pos[MAX_HALOS];        // camera-relative m
uniform vec4 u_halo_intensity[MAX_HALOS];  // cd, linear rgb
uniform float u_halo_beta;                 // 1/m
uniform float u_halo_g;
uniform float u_halo_omega;

float halo_hg(float g, float c) {
    return (1.0 - g * g) / (4.0 * PI * pow(max(1.0 + g * g - 2.0 * g * c, 1e-6), 1.5));
}

vec3 light_halos(vec3 dir, float surface_distance) {
    vec3 sum = vec3(0.0);
    float D = min(surface_distance, 20.0 / max(u_halo_beta, 1e-9));  // past 20 optical depths: nothing
    for (int i = 0; i < MAX_HALOS; ++i) {
        if (i >= u_halo_count) break;
        vec3 p = u_halo_pos[i].xyz;
        float t0 = dot(p, dir);
        float h = max(length(p - t0 * dir), 0.05);
        float phi0 = -atan(t0 / h), phi1 = atan((D - t0) / h);
        if (phi1 <= phi0) continue;
        float dphi = (phi1 - phi0) / 8.0;
        float acc = 0.0;
        for (int k = 0; k < 8; ++k) {
            float phi = phi0 + (float(k) + 0.5) * dphi;
            float s = t0 + h * tan(phi);
            float r = h / cos(phi);
            acc += halo_hg(u_halo_g, sin(phi)) * exp(-min(u_halo_beta * (s + r), 80.0));
        }
        sum += u_halo_intensity[i].rgb * (u_halo_omega * u_halo_beta / h * acc * dphi);
    }
    return sum;
}
#endif
uniform float u_exposure_correction;  // metered exposure / the passes' provisional one (post.py)
uniform float u_adaptation_luminance;  // cd/m^2, what the exposure adapted to (post/exposure.py)

#ifdef MESOPIC
// Mesopic vision: below ~3 cd/m^2 rods take over from cones; at 0.003 cd/m^2 vision is scotopic
// (no colour). Rod fraction s from the adaptation luminance (log-linear between the two), rod
// luminance from linear sRGB with weights near the scotopic curve V'(lambda) (peak 507 nm: mostly
// G and B), shown with a slight blue tint (the "Purkinje" night look, Jensen et al. 2000).
vec3 mesopic(vec3 c) {
    float s = clamp((log(3.0) - log(max(u_adaptation_luminance, 1e-9))) / (log(3.0) - log(0.003)), 0.0, 1.0);
    float rod = dot(c, vec3(0.02, 0.55, 0.43));
    return mix(c, rod * vec3(0.80, 0.95, 1.25), s);
}
#endif
in vec2 v_uv;
out vec4 out_color;

vec3 aces_fit(vec3 x) {
    return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
}

vec3 linear_to_srgb(vec3 c) {
    return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(0.0031308, c));
}

float interleaved_gradient_noise(vec2 p) {
    return fract(52.9829189 * fract(dot(p, vec2(0.06711056, 0.00583715))));
}

void main() {
    vec3 hdr = texture(u_hdr, v_uv).rgb;
#ifdef HALOS
    hdr += pre_expose(light_halos(view_ray(v_uv), texture(u_distance, v_uv).r));
#endif
    hdr *= u_exposure_correction;
    hdr = max(hdr, vec3(0.0));  // no negative radiance; NaN-free inputs are the passes' duty
#ifdef MESOPIC
    hdr = mesopic(hdr);
#endif
    vec3 srgb = linear_to_srgb(aces_fit(hdr));
    srgb += (interleaved_gradient_noise(gl_FragCoord.xy) - 0.5) / 255.0;
    out_color = vec4(clamp(srgb, 0.0, 1.0), 1.0);
}
