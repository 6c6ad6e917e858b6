// Infinite horizontal plane at z = u_plane_height (ENU), ray-cast per pixel: the ground (the sea
// is the water pass's Gerstner mesh, render/water/).
#include "common/frame.glsl"
#include "common/atmosphere.glsl"
#include "common/brdf.glsl"
#include "common/lights.glsl"
#include "common/earth.glsl"
#include "common/aerial_table.glsl"

uniform float u_plane_height;   // m, camera-relative height of the plane
uniform vec3 u_base_color;
uniform float u_roughness;

in vec2 v_uv;
layout(location = 0) out vec4 out_color;
layout(location = 1) out float out_distance;

void main() {
    vec3 dir = view_ray(v_uv);
    float t;
    vec3 n;
    if (u_plane_height < 0.0) {
        // Seen from above, the surface is a sphere of the earth's radius (common/earth.glsl).
        float H = -u_plane_height;
        t = earth_sphere_distance(dir, H);
        if (t < 0.0) discard;
        vec3 centre = vec3(0.0, 0.0, -(EARTH_SPHERE_RADIUS + H));
        n = normalize(dir * t - centre);
    } else {
        // Seen from below (under water / under ground): a flat plane is enough.
        if (dir.z <= 0.0) discard;
        t = u_plane_height / dir.z;
        n = vec3(0.0, 0.0, -1.0);
    }
    // No far limit: the earth's surface is drawn out to its horizon (reversed-Z depth holds there).
    if (!(t > 0.0)) discard;
    vec3 p = dir * t;
    vec3 v = -dir;
    Material m = Material(u_base_color, 0.0, u_roughness);
    vec3 lit = shade_surface(m, p, n, v);
    out_color = vec4(pre_expose(aerial_perspective(lit, p)), 1.0);
    out_distance = t;
    gl_FragDepth = window_depth(p);
}
