// The per-frame aerial-perspective table (render/common/aerial_table.py): a camera-frustum volume
// ("froxels", Hillaire 2020) of screen x, y (nodes on the edges of the table's frustum, the view's
// widened by a guard band, uv = i / (n - 1)) times
// distance slices d_k = d0 q^k, holding for the view ray to each node
//   u_aerial_tau     rgb optical depth camera -> node          T = exp(-tau)
//   u_aerial_source  rgb mean in-scattered source of the path  S = source (1 - T)
// filled from apply_aerial_perspective (common/atmosphere.glsl: clear air + fog/haze layer) by
// common/aerial_table.comp.glsl, and refilled only when what it reads changed. A pixel pays one
// projection, a log and two trilinear fetches instead of the sky-view lookups, a 4-point
// quadrature and the fog layer's light table.
//
// Between two slices the table is read with a weight linear in DISTANCE (the z coordinate is set
// so the hardware's linear filter does that), so tau is exact for a homogeneous medium (fog, haze
// seen level) and the source, constant along such a path, too. Nearer than d0 tau is scaled by
// d / d0 (the same exactness); past the last slice (nothing drawn there by the surfaces: the table
// reaches the ground's horizon and the farthest entity) likewise by d / d_max.
//
// Needs common/frame.glsl and common/atmosphere.glsl before it. AERIAL_EXACT: the per-pixel
// function instead (the reference the table is measured and tested against).
#include "generated/bindings.glsl"
#ifndef AERIAL_EXACT
layout(binding = UNIT_AERIAL_TAU) uniform sampler3D u_aerial_tau;
layout(binding = UNIT_AERIAL_SOURCE) uniform sampler3D u_aerial_source;
uniform vec4 u_aerial_map;  // d0 (m), log2(q), q, number of slices
// The table's own frame (aerial_table.py: the camera's at the fill, its frustum widened by a guard
// band, so a turning camera reuses the table): basis and frustum tangents left, right, bottom, top.
uniform vec3 u_aerial_right;
uniform vec3 u_aerial_up;
uniform vec3 u_aerial_forward;
uniform vec4 u_aerial_tangents;
#endif

vec3 aerial_perspective(vec3 radiance, vec3 rel) {
#ifdef AERIAL_EXACT
    return apply_aerial_perspective(radiance, rel);
#else
    float d = length(rel);
    if (!(d > 1e-4)) return radiance;
    // Position of the point in the table's frustum: its tangents, as view_ray() maps uv to them.
    vec3 c = vec3(dot(rel, u_aerial_right), dot(rel, u_aerial_up), dot(rel, u_aerial_forward));
    vec2 t = c.xy / max(c.z, 1e-6 * d);
    vec2 uv = clamp((t - u_aerial_tangents.xz) / (u_aerial_tangents.yw - u_aerial_tangents.xz), 0.0, 1.0);
    vec2 n_xy = vec2(textureSize(u_aerial_tau, 0).xy);
    float n = u_aerial_map.w;
    float k = log2(d / u_aerial_map.x) / u_aerial_map.y;
    float scale = 1.0;
    float z;
    if (k <= 0.0) {
        z = 0.0;
        scale = d / u_aerial_map.x;
    } else if (k >= n - 1.0) {
        z = n - 1.0;
        scale = d / (u_aerial_map.x * exp2(u_aerial_map.y * (n - 1.0)));
    } else {
        float k0 = floor(k);
        z = k0 + clamp((d / (u_aerial_map.x * exp2(u_aerial_map.y * k0)) - 1.0) / (u_aerial_map.z - 1.0), 0.0, 1.0);
    }
    vec3 coord = vec3((uv * (n_xy - 1.0) + 0.5) / n_xy, (z + 0.5) / n);
    vec3 tau = texture(u_aerial_tau, coord).rgb * scale;
    vec3 source = texture(u_aerial_source, coord).rgb;
    return radiance * exp(-min(tau, vec3(80.0))) + source * one_minus_exp(tau);
#endif
}
