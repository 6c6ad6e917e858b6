// The sea seen from under its surface (docs/water.md#under-water): the water column, the bed, and the
// surface from below, for a camera below the local surface (water.py compiles WATER_UNDERWATER then;
// water/underwater.frag.glsl fills what the mesh does not cover).
//
// Water type: Jerlov (1976) oceanic type II, the downwelling diffuse attenuation K_d (1/m) of his
// table (as tabulated by Solonenko & Mobley 2015, Appl. Opt. 54, 5392), averaged over each channel's
// band:
//   red   600-650 nm: K_d = 0.260 (600), 0.335 (625), 0.400 (650)         -> 0.33 1/m
//   green 525-575 nm: K_d = 0.075 (525), 0.088 (550), 0.115 (575)         -> 0.093 1/m
//   blue  450-500 nm: K_d = 0.067 (450), 0.062 (475), 0.065 (500)         -> 0.065 1/m
// One coefficient per channel serves both the light reaching depth z (E_d(z) = E_d(0) e^{-K z}) and
// the image attenuation along a path of length D (e^{-K D}): the broad-beam attenuation of an image's
// low frequencies, forward-scattered light staying in the image, is close to K_d, not to the beam
// attenuation c = a + b (Akkaynak & Treibitz 2018, "A revised underwater image formation model").
//
// Scattering: the downwelling light at depth z, scattered toward the eye isotropically, with a source
// S(z) = S0 e^{-K z} per unit K-path. Along a ray from depth z_e with upward cosine mu, depth
// z(s) = z_e - mu s, so the light scattered into the ray over [0, D] is
//   L_s = S0 e^{-K z_e} (1 - e^{-K (1 - mu) D}) / (1 - mu),
// and an infinite column seen straight down shows S0 e^{-K z_e} / 2. S0 = 2 DEEP_ALBEDO E_d(0) / pi
// makes that the upwelling radiance the surface shading uses from above (water.frag.glsl's body
// term): the sea looks the same just above and just below its surface; horizontally the column is
// twice as bright, toward the window brighter still (the radiance distribution's shape).
//
// The surface from below: Snell's window. A ray leaving the water through a facet n refracts into the
// sky if sin(theta_w) < 1 / 1.333 (the critical angle, 48.6 deg) and carries the sky's radiance
// times (1 - F) n^2 (radiance grows by n^2 entering the denser medium); the rest, F, is the water
// below reflected, all of it past the critical angle (total internal reflection). F: Schlick's
// approximation on the air side's angle. The sun through the window: the rough dielectric BTDF of
// Walter et al. 2007 (eq. 21) with the GGX lobe and Smith visibility of the project's one BRDF.
//
// Needs: PI, pre_expose (common/frame.glsl), the GGX functions (common/brdf.glsl), sky_reflection,
// sea_downwelling, DEEP_ALBEDO (water/sea_tables.glsl).

const vec3 UW_K = vec3(0.33, 0.093, 0.065);     // 1/m, Jerlov type II K_d per channel (above)
const float UW_N = 1.333;                        // refractive index of sea water
const float UW_R0 = 0.02037;                     // Fresnel reflectance at normal incidence
const vec3 UW_BED_ALBEDO = vec3(0.35, 0.30, 0.22);  // sand (water.frag.glsl's BOTTOM_ALBEDO)

uniform vec3 u_uw_bed;         // the bed as a plane, camera-relative: z = x + y * rel.x + z * rel.y (m)
uniform float u_uw_level_z;    // m, camera-relative z of the mean level

vec3 uw_source() {  // S0: the column's scattering source just under the surface
    return 2.0 * DEEP_ALBEDO * 0.98 * sea_downwelling() / PI;
}

// Light scattered into a ray from depth z0 (m below the mean level), upward cosine mu, over D metres.
vec3 uw_inscatter(float mu, float d, float z0) {
    float a = max(1.0 - mu, 1e-2);
    return uw_source() * exp(-UW_K * max(z0, 0.0)) * (1.0 - exp(-UW_K * (a * d))) / a;
}

// Distance along dir from the camera-relative point p to the bed plane (1e30: never).
float uw_bed_distance(vec3 p, vec3 dir) {
    float above = p.z - (u_uw_bed.x + u_uw_bed.y * p.x + u_uw_bed.z * p.y);  // > 0: p above the bed
    float closing = dir.z - u_uw_bed.y * dir.x - u_uw_bed.z * dir.y;        // < 0: going toward it
    return above > 0.0 && closing < 0.0 ? -above / closing : 1e30;
}

#ifdef UW_CAUSTICS
float uw_caustics(vec3 bed, float depth);  // the sun's irradiance on the bed at bed over its mean (1)
#endif

// Radiance reaching p along the ray from p in direction dir through the water: the bed if the ray
// meets it, else the column to infinity.
vec3 uw_column(vec3 p, vec3 dir, out float hit) {
    float z0 = u_uw_level_z - p.z;
    hit = uw_bed_distance(p, dir);
    vec3 l = uw_inscatter(dir.z, hit, z0);
    if (hit < 1e29) {
        float bed_depth = z0 - dir.z * hit;
#ifdef UW_CAUSTICS  // the sun's part focused by the surface (water/underwater.frag.glsl)
        vec3 e_sun = u_sun_illuminance * max(u_sun_dir.z, 0.0);
        float focus = uw_caustics(p + dir * hit, bed_depth);
        vec3 e_bed = 0.98 * (sea_downwelling() + (focus - 1.0) * e_sun) * exp(-UW_K * max(bed_depth, 0.0));
#else
        vec3 e_bed = 0.98 * sea_downwelling() * exp(-UW_K * max(bed_depth, 0.0));
#endif
        l += UW_BED_ALBEDO * e_bed / PI * exp(-UW_K * hit);
    }
    return l;
}

// The sun (or moon) seen through a rough surface facet n from below along d (unit, upward):
// Walter et al. 2007 eq. 21 with i = toward the light (air), o = toward the eye (water).
vec3 uw_glint_through(vec3 n, vec3 d, float alpha, vec3 light_dir, vec3 e) {
    vec3 o = -d;
    float n_dot_l = dot(n, light_dir);
    float n_dot_o = -dot(n, o);
    if (n_dot_l <= 0.0 || n_dot_o <= 0.0) return vec3(0.0);
    vec3 h = -normalize(light_dir + UW_N * o);
    if (dot(h, n) < 0.0) h = -h;
    float i_h = dot(light_dir, h);
    float o_h = dot(o, h);
    if (i_h <= 0.0 || o_h >= 0.0) return vec3(0.0);
    float denom = i_h + UW_N * o_h;
    float f = fresnel_schlick(i_h, vec3(UW_R0)).x;
    float g = smith_visibility(n_dot_o, n_dot_l, alpha) * 4.0 * n_dot_o * n_dot_l;
    float ft = i_h * -o_h / (n_dot_l * n_dot_o) * UW_N * UW_N * (1.0 - f) * g
             * ggx_distribution(n, h, max(dot(n, h), 0.0), alpha) / max(denom * denom, 1e-6);
    return e * ft * n_dot_l;
}

// The surface at p seen from below along d (unit, p = d * dist), facet normal n (up), GGX alpha:
// Snell's window and total internal reflection, then the water between the eye and p.
vec3 uw_surface_from_below(vec3 n, vec3 d, float dist, float alpha, vec3 light_dir, vec3 light_e) {
    float cos_w = dot(n, d);
    if (cos_w < 0.02) {  // facet turned away by the detail slopes: bend it back toward the ray
        n = normalize(n + d * (0.02 - cos_w));
        cos_w = 0.02;
    }
    float sin2_air = UW_N * UW_N * (1.0 - cos_w * cos_w);
    vec3 r = reflect(d, n);
    r.z = -abs(r.z);  // reflected down into the water
    float hit;
    vec3 below = uw_column(d * dist, r, hit);
    vec3 surface;
    if (sin2_air >= 1.0) {
        surface = below;  // total internal reflection
    } else {
        float cos_air = sqrt(1.0 - sin2_air);
        float f = fresnel_schlick(cos_air, vec3(UW_R0)).x;
        vec3 t = refract(d, -n, UW_N);
        t.z = max(t.z, 0.0);
        surface = (1.0 - f) * UW_N * UW_N * sky_reflection(normalize(t)) + f * below
                + uw_glint_through(n, d, alpha, light_dir, light_e);
    }
    return surface * exp(-UW_K * dist) + uw_inscatter(d.z, dist, u_uw_level_z);
}

// A sea mesh fragment seen from under water along d: its underside, or, where the mesh lies below the
// eye (its error beside the eye, a trough the eye is above), the water the ray goes on through.
vec3 underwater_mesh(vec3 n, vec3 geometric_n, vec3 d, float dist, float alpha, vec3 light_dir, vec3 light_e) {
    if (dot(geometric_n, d) <= 0.0) {
        float hit;
        return uw_column(vec3(0.0), d, hit);
    }
    return uw_surface_from_below(n, d, dist, alpha, light_dir, light_e);
}
