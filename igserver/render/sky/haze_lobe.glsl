// The fog/haze layer's lobe (haze_sky_lobe below) of every direction on the sky-view map, at the
// height where that direction's ray gathers its light (aerial_ray's: half the first optical depth's
// run along it), times the single-scattering albedo and the camera's weight: the term the sky, the
// sea and the surfaces add to the layer's source with one lookup (common/atmosphere.glsl
// haze_lobe), filled once per change of the sky-view table, the layer or the camera's height
// (sky/haze_lobe.py).
#include "common/frame.glsl"
#include "common/atmosphere.glsl"

// The clear sky's light that reaches height h straight through the layer, scattered toward the
// eye by the layer's phase function instead of isotropically (cd/m^2, before omega):
//     A(h, v) = integral L_c(w) T(h, w) p_HG(w . v) dw  -  w_down(v) / pi  integral L_c(w) T(h, w) w_z dw,
// L_c the clear sky (the sky-view table), T(h, w) = exp(-(1 - g^2) haze_tau_up(h, w_z)) the layer
// above h along w, delta-scaled as the two-stream's own direct part (its forward peak stays in the
// beam). The two-stream's diffuse rows (haze_source_terms) hold this light as isotropic flux (the
// second integral, in the weight w_down / pi they give any downward flux); A moves it to where the
// phase function sends it, so it adds nothing for an isotropic sky. Where the clear sky is
// anisotropic and the layer lets it through, the haze takes the light of the sky it looks toward:
// a low sun's aureole, crossing a few air masses of the layer from 2-20 deg up, lights the haze on
// the horizon below it (the direct sun crosses 60-90 there and is gone). In a thick fog T ~ 0 and
// A ~ 0. From below the horizon: over land nothing (the ground's reflection stays in the
// two-stream's up row), over a sea the sky it mirrors (haze_clear_sky_through), less the same light
// as the up row holds it. Quadratures: the first by importance sampling of p_HG, HAZE_LOBE_RINGS
// rings stratified in its inverse CDF x HAZE_LOBE_AZIMUTHS azimuths (over land spent on each ring's
// arc above the horizon); the second cosine-weighted over the half hemisphere from the sun's azimuth. 16 x 8 and 4 x 8: within 4 % of
// 32 x 16 and 12 x 16 on the horizon under a sun 0.47 deg up (the issue's view in
// tests/test_haze_aureole.py). 160 taps a texel, once per change.
const int HAZE_LOBE_RINGS = 16;
const int HAZE_LOBE_AZIMUTHS = 8;
const int HAZE_FLUX_RINGS = 4;
const int HAZE_FLUX_AZIMUTHS = 8;
uniform float u_haze_sea_mss;  // mean-square slope of a sea under the layer; < 0 over land
vec3 haze_clear_sky_through(float h, vec3 w, vec2 size) {
    if (w.z > 0.0) {
        return texture(u_sky_view_radiance, sky_view_uv_sized(w, size)).rgb
             * exp(-min((1.0 - u_haze_g * u_haze_g) * haze_tau_up(h, w.z), vec3(80.0)));
    }
    // From below: a sea mirrors the sky of the direction m into the layer, Fresnel-weighted (Schlick,
    // water's 0.02 at normal incidence) at the incidence of its facets: the cosine sqrt(w_z^2 + mss),
    // the rms facet tilt added to a grazing ray (a flat sea is a mirror at grazing incidence, a wind's
    // slopes turn its facets toward the sky above); then through the layer below h to the scatterer.
    if (u_haze_sea_mss < 0.0 || w.z > -1e-4) return vec3(0.0);
    vec3 m = vec3(w.xy, -w.z);
    float x = 1.0 - sqrt(m.z * m.z + u_haze_sea_mss);
    float fresnel = 0.02 + 0.98 * x * x * x * x * x;
    vec3 below = u_haze_beta * max(haze_column(0.0) - haze_column(h), 0.0) / m.z;
    return fresnel * texture(u_sky_view_radiance, sky_view_uv_sized(m, size)).rgb
         * exp(-min((1.0 - u_haze_g * u_haze_g) * (haze_tau_up(0.0, m.z) + below), vec3(80.0)));
}
vec3 haze_sky_lobe(float h, vec3 v) {
    vec2 size = vec2(textureSize(u_sky_view_radiance, 0));
    float g = u_haze_g;
    vec3 t1 = abs(v.z) < 0.999 ? normalize(vec3(-v.y, v.x, 0.0)) : vec3(1.0, 0.0, 0.0);
    vec3 t2 = cross(v, t1);
    vec3 lobe = vec3(0.0);
    for (int i = 0; i < HAZE_LOBE_RINGS; ++i) {
        float xi = (float(i) + 0.5) / float(HAZE_LOBE_RINGS);
        float q = (1.0 - g * g) / (1.0 - g + 2.0 * g * xi);
        float c = clamp((1.0 + g * g - q * q) / (2.0 * g), -1.0, 1.0);
        float s = sqrt(max(1.0 - c * c, 0.0));
        // The ring's taps above the horizon: z = c v_z + s t2_z sin(phi) > 0 (t1 is level), the arc
        // phi in (asin k, pi - asin k), k = -c v_z / (s t2_z); the azimuths share out that arc only
        // (the sky's light ends at the horizon: spent on the arc, every tap counts).
        float a_z = s * t2.z;
        float k = u_haze_sea_mss >= 0.0 ? -2.0 : a_z > 1e-6 ? -c * v.z / a_z : (c * v.z > 0.0 ? -2.0 : 2.0);
        if (k >= 1.0) continue;
        float phi0 = k <= -1.0 ? 0.0 : asin(k);
        float arc = k <= -1.0 ? 2.0 * ATMO_PI : ATMO_PI - 2.0 * phi0;
        vec3 ring = vec3(0.0);
        for (int j = 0; j < HAZE_LOBE_AZIMUTHS; ++j) {
            float phi = phi0 + (float(j) + 0.5) * arc / float(HAZE_LOBE_AZIMUTHS);
            ring += haze_clear_sky_through(h, c * v + s * (cos(phi) * t1 + sin(phi) * t2), size);
        }
        lobe += ring * (arc / (2.0 * ATMO_PI));
    }
    lobe /= float(HAZE_LOBE_RINGS * HAZE_LOBE_AZIMUTHS);
    // The flux: the sky is symmetric about the sun's vertical (the sky-view map's azimuth runs from
    // the sun, 0 to pi), so half the circle, from the sun's azimuth, holds it.
    // (Over a sea the same for the light going up, which the two-stream holds in its up row.)
    vec3 flux = vec3(0.0), flux_up = vec3(0.0);
    vec2 sun_h = u_sky_view_sun_h, side = vec2(-sun_h.y, sun_h.x);
    for (int i = 0; i < HAZE_FLUX_RINGS; ++i) {
        float mu = sqrt(1.0 - (float(i) + 0.5) / float(HAZE_FLUX_RINGS));  // cosine-weighted rings
        float s = sqrt(1.0 - mu * mu);
        for (int j = 0; j < HAZE_FLUX_AZIMUTHS; ++j) {
            float phi = (float(j) + 0.5) * ATMO_PI / float(HAZE_FLUX_AZIMUTHS);
            vec2 w_h = s * (cos(phi) * sun_h + sin(phi) * side);
            flux += haze_clear_sky_through(h, vec3(w_h, mu), size);
            if (u_haze_sea_mss >= 0.0) flux_up += haze_clear_sky_through(h, vec3(w_h, -mu), size);
        }
    }
    float norm = ATMO_PI / float(HAZE_FLUX_RINGS * HAZE_FLUX_AZIMUTHS);
    return lobe - ((0.5 + 0.5 * v.z) * flux + (0.5 - 0.5 * v.z) * flux_up) * norm / ATMO_PI;
}

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
layout(binding = 0, rgba32f) uniform writeonly image2D u_out;

void main() {
    ivec2 texel = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = imageSize(u_out);
    if (any(greaterThanEqual(texel, size))) return;
    vec3 dir = sky_view_dir((vec2(texel) + 0.5) / vec2(size));
    float h = max(haze_height() + dir.z * 0.5 * haze_first_depth_run(haze_height()), 0.0);
    imageStore(u_out, texel, vec4(u_haze_omega * haze_lobe_weight() * haze_sky_lobe(h, dir), 0.0));
}
