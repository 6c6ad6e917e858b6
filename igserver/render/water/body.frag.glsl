// The water body seen under the crests (water.py, _fill_under_crests): rays from a camera inside
// the wave envelope that pass under the mesh meet the sphere below every trough; they see the deep
// water's backscatter (the body term of water.frag.glsl) through the air in front. Depth from the
// ray, so the mesh wins wherever it is nearer.
#include "common/frame.glsl"
#include "common/brdf.glsl"
#include "common/lights.glsl"
#include "common/earth.glsl"
#include "water/sea_tables.glsl"

uniform float u_plane_height;   // m, camera-relative height of the sphere's top (< 0)

in vec2 v_uv;
layout(location = 0) out vec4 out_color;
layout(location = 1) out float out_distance;

void main() {
    vec3 dir = view_ray(v_uv);
    float t = earth_sphere_distance(dir, -u_plane_height);  // the sphere below every trough
    if (t < 0.0) discard;
    vec3 p = dir * t;
    vec3 e = sea_downwelling();
#if LOCAL_LIGHTS
#if LIGHT_TILES  // the tile's lights only (common/lights.glsl)
    for (uvec2 lights = tile_lights(p); any_light(lights);) {
        int i = next_light(lights);
#else
    for (int i = 0; i < u_light_count; ++i) {
#endif
        vec3 l;
        vec3 e_i = light_illuminance(i, p, l);
        e += e_i * max(l.z, 0.0);
    }
#endif
    vec3 air_t, air_s;
    sea_aerial_perspective(p, air_t, air_s);
    out_color = vec4(pre_expose(DEEP_ALBEDO * e / PI * air_t + air_s), 1.0);
    out_distance = t;
    gl_FragDepth = window_depth(p);
}
