// The one BRDF of the project (DESIGN 4.4, seed 002): metallic-roughness Cook-Torrance.
//   Rs = D G F / (4 (N.V)(N.L)),  D = GGX/Trowbridge-Reitz,  G = height-correlated Smith,
//   F = Schlick with F0 = 0.04 for dielectrics and base colour for metals.
//   Rd = (1 - F(N.V)) (1 - F(N.L)) (1 - metallic) base / pi  (Shirley's coupling): light entering
//   the surface has lost its Fresnel reflection on the way in, and again on the way out. The
//   specular lobe's directional albedo never exceeds F(N.V) (measured), so the total reflected
//   energy stays <= 1 at every view angle (`igserver quality surfaces`, white furnace); the common
//   weighting of Rd by (1 - F(V.H)) instead reflects up to 1.8x the incident energy at grazing views.
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

// Directional albedo of the specular lobe (split-sum environment BRDF, Karis' analytic fit
// "EnvBRDFApprox"): what the specular lobe reflects of uniform light from the view direction.
vec3 specular_albedo(Material m, float n_dot_v) {
    const vec4 c0 = vec4(-1.0, -0.0275, -0.572, 0.022);
    const vec4 c1 = vec4(1.0, 0.0425, 1.04, -0.04);
    vec4 r = m.roughness * c0 + c1;
    float a004 = min(r.x * r.x, exp2(-9.28 * max(n_dot_v, 0.0))) * r.x + r.y;
    vec2 ab = vec2(-1.04, 1.04) * a004 + r.zw;
    vec3 f0 = mix(vec3(0.04), m.base_color, m.metallic);
    return clamp(f0 * ab.x + ab.y, 0.0, 1.0);
}

// The two lobes separately (both times N.L): the paper's shading (common/lights.glsl) weights the
// diffuse and the specular light differently inside a shadow.
struct BrdfTerms {
    vec3 diffuse;
    vec3 specular;
};

BrdfTerms brdf_terms(Material m, vec3 n, vec3 v, vec3 l) {
    float n_dot_l = dot(n, l);
    if (n_dot_l <= 0.0) return BrdfTerms(vec3(0.0), vec3(0.0));
    float n_dot_v = max(dot(n, v), 1e-4);
    vec3 h = normalize(v + l);
    float alpha = max(m.roughness * m.roughness, MIN_GGX_ALPHA);
    vec3 f0 = mix(vec3(0.04), m.base_color, m.metallic);
    vec3 f = fresnel_schlick(max(dot(v, h), 0.0), f0);
    vec3 specular = f * ggx_distribution(n, h, max(dot(n, h), 0.0), alpha) * smith_visibility(n_dot_v, n_dot_l, alpha);
    vec3 diffuse = (1.0 - fresnel_schlick(n_dot_v, f0)) * (1.0 - fresnel_schlick(n_dot_l, f0))
                 * (1.0 - m.metallic) * m.base_color / PI;
    return BrdfTerms(diffuse * n_dot_l, specular * n_dot_l);
}

vec3 brdf_cos(Material m, vec3 n, vec3 v, vec3 l) {
    BrdfTerms t = brdf_terms(m, n, v, l);
    return t.diffuse + t.specular;
}
