// The one BRDF of the project (docs/design.md#surfaces): metallic-roughness Cook-Torrance.
//   Rs = D G F / (4 (N.V)(N.L)),  D = GGX/Trowbridge-Reitz,  G = height-correlated Smith,
//   F = Schlick with F0 = 0.04 for dielectrics and base colour for metals.
//   Rd = (1 - E_s(N.V)) (1 - E_s(N.L)) / (1 - E_avg) (1 - metallic) base / pi  (Kelemen and
//   Szirmay-Kalos 2001): E_s is the specular lobe's own directional albedo (tabulated from this BRDF,
//   common/brdf_tables.glsl) and E_avg its hemispherical mean, so the diffuse lobe takes exactly the
//   energy the specular lobe leaves, at every view angle, and stays reciprocal: the white furnace
//   reflects <= 1 (`igserver quality surfaces`). The common weighting of Rd by (1 - F(V.H)) reflects
//   up to 1.8x the incident energy at grazing views; (1 - F(N.V))(1 - F(N.L)) darkens rough ground
//   seen or lit at grazing angles by half.
// Returns the BRDF times N.L, so a light contributes  E_light * brdf_cos(...).

struct Material {
    vec3 base_color;  // linear
    float metallic;   // 0 dielectric .. 1 metal
    float roughness;  // perceptual, 0 mirror .. 1 rough
};

const float MIN_GGX_ALPHA = 2e-3;  // alpha = roughness^2 floor: a mirror's highlight stays finite

// GGX normal distribution, written with |N x H|^2 = 1 - (N.H)^2 computed without cancellation
// (near the peak N.H -> 1 and 1 - (N.H)^2 loses all float32 digits when alpha is small).
float ggx_distribution(vec3 n, vec3 h, float n_dot_h, float alpha) {
    vec3 nxh = cross(n, h);
    float a = n_dot_h * alpha;
    float k = alpha / (dot(nxh, nxh) + a * a);
    return k * k / PI;
}

// Smith visibility V = G / (4 N.V N.L), height-correlated form (Heitz 2014).
float smith_visibility(float n_dot_v, float n_dot_l, float alpha) {
    float a2 = alpha * alpha;
    float gv = n_dot_l * sqrt(n_dot_v * n_dot_v * (1.0 - a2) + a2);
    float gl = n_dot_v * sqrt(n_dot_l * n_dot_l * (1.0 - a2) + a2);
    return 0.5 / max(gv + gl, 1e-6);
}

vec3 fresnel_schlick(float cos_theta, vec3 f0) {
    float m = clamp(1.0 - cos_theta, 0.0, 1.0);
    float m2 = m * m;
    return f0 + (1.0 - f0) * (m2 * m2 * m);
}

#include "common/brdf_tables.glsl"

// Directional albedo of the specular lobe, E_s = F0 A + B (common/brdf_tables.glsl: integrated
// from this very BRDF in float64), bilinear in (sqrt(N.V), roughness); returns (A, B).
vec2 brdf_table(float mu, float roughness) {
    float x = sqrt(clamp(mu, 0.0, 1.0)) * float(BRDF_TABLE_N - 1);
    float y = clamp(roughness, 0.0, 1.0) * float(BRDF_TABLE_N - 1);
    int i0 = min(int(x), BRDF_TABLE_N - 2);
    int j0 = min(int(y), BRDF_TABLE_N - 2);
    float fx = x - float(i0), fy = y - float(j0);
    int k = j0 * BRDF_TABLE_N + i0;
    vec2 c00 = vec2(BRDF_TABLE_A[k], BRDF_TABLE_B[k]);
    vec2 c10 = vec2(BRDF_TABLE_A[k + 1], BRDF_TABLE_B[k + 1]);
    vec2 c01 = vec2(BRDF_TABLE_A[k + BRDF_TABLE_N], BRDF_TABLE_B[k + BRDF_TABLE_N]);
    vec2 c11 = vec2(BRDF_TABLE_A[k + BRDF_TABLE_N + 1], BRDF_TABLE_B[k + BRDF_TABLE_N + 1]);
    return mix(mix(c00, c10, fx), mix(c01, c11, fx), fy);
}

// Its cosine-weighted hemispherical mean E_avg = F0 A_avg + B_avg; returns (A_avg, B_avg).
vec2 brdf_table_average(float roughness) {
    float y = clamp(roughness, 0.0, 1.0) * float(BRDF_TABLE_N - 1);
    int j0 = min(int(y), BRDF_TABLE_N - 2);
    float fy = y - float(j0);
    return mix(vec2(BRDF_TABLE_A_AVG[j0], BRDF_TABLE_B_AVG[j0]),
               vec2(BRDF_TABLE_A_AVG[j0 + 1], BRDF_TABLE_B_AVG[j0 + 1]), fy);
}

vec3 specular_albedo(Material m, float n_dot_v) {
    vec2 ab = brdf_table(n_dot_v, m.roughness);
    return mix(vec3(0.04), m.base_color, m.metallic) * ab.x + ab.y;
}

// The two lobes separately (both times N.L): the paper's shading (common/lights.glsl) weights the
// diffuse and the specular light differently inside a shadow.
struct BrdfTerms {
    vec3 diffuse;
    vec3 specular;
};

// The parts of the BRDF that depend on the surface and the view only, not on the light: computed
// once per pixel and shared by every light (a pixel's light loop, common/lights.glsl), where each
// light would otherwise look up E_s(N.V) and E_avg again (bilinear reads of the tables).
struct BrdfView {
    float n_dot_v;
    float alpha;          // GGX alpha = roughness^2, floored
    vec3 f0;
    vec3 view_albedo;     // 1 - E_s(N.V)
    vec3 albedo_norm;     // max(1 - E_avg, 1e-6)
};

BrdfView brdf_view(Material m, vec3 n, vec3 v) {
    float n_dot_v = max(dot(n, v), 1e-4);
    vec3 f0 = mix(vec3(0.04), m.base_color, m.metallic);
    vec2 ab_v = brdf_table(n_dot_v, m.roughness);
    vec2 ab_avg = brdf_table_average(m.roughness);
    vec3 e_avg = f0 * ab_avg.x + ab_avg.y;
    return BrdfView(n_dot_v, max(m.roughness * m.roughness, MIN_GGX_ALPHA), f0,
                    1.0 - (f0 * ab_v.x + ab_v.y), max(1.0 - e_avg, vec3(1e-6)));
}

BrdfTerms brdf_terms(Material m, BrdfView b, vec3 n, vec3 v, vec3 l) {
    float n_dot_l = dot(n, l);
    if (n_dot_l <= 0.0) return BrdfTerms(vec3(0.0), vec3(0.0));
    vec3 h = normalize(v + l);
    vec3 f = fresnel_schlick(max(dot(v, h), 0.0), b.f0);
    vec3 specular = f * ggx_distribution(n, h, max(dot(n, h), 0.0), b.alpha) * smith_visibility(b.n_dot_v, n_dot_l, b.alpha);
    vec2 ab_l = brdf_table(n_dot_l, m.roughness);
    vec3 diffuse = b.view_albedo * (1.0 - (b.f0 * ab_l.x + ab_l.y)) / b.albedo_norm
                 * (1.0 - m.metallic) * m.base_color / PI;
    return BrdfTerms(diffuse * n_dot_l, specular * n_dot_l);
}

BrdfTerms brdf_terms(Material m, vec3 n, vec3 v, vec3 l) {
    return brdf_terms(m, brdf_view(m, n, v), n, v, l);
}

vec3 brdf_cos(Material m, vec3 n, vec3 v, vec3 l) {
    BrdfTerms t = brdf_terms(m, n, v, l);
    return t.diffuse + t.specular;
}
