// Bright stars as points at infinity (depth test AT_INFINITY against the sky, additive blending).
// A star of illuminance E (lux, outside the atmosphere) on a pixel of solid angle omega has the
// radiance E T(v) / omega over that pixel; a point of size s px spreads it over s^2 pixels.
#include "common/frame.glsl"
#include "common/atmosphere.glsl"

#ifdef VERTEX_SHADER
in vec3 in_dir;      // unit ENU direction toward the star
in float in_lux;     // illuminance outside the atmosphere
uniform float u_star_pixel_solid_angle;  // sr covered by the point sprite
out vec3 v_radiance;
void main() {
    vec3 t = dir_visible(in_dir) ? sky_transmittance(in_dir) : vec3(0.0);
    v_radiance = pre_expose(vec3(in_lux) * t / u_star_pixel_solid_angle);
    gl_Position = u_view_proj * vec4(in_dir, 0.0);  // a direction: window depth 0, the sky's depth
}
#endif

#ifdef FRAGMENT_SHADER
in vec3 v_radiance;
layout(location = 0) out vec4 out_color;
layout(location = 1) out float out_distance;
void main() {
    out_color = vec4(v_radiance, 0.0);
    out_distance = 0.0;  // added to the sky's 1e30 by the blend
}
#endif
