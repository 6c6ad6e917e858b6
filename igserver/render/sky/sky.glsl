// Sky pass: fills every pixel no surface covered (drawn at the far plane with depth test LEQUAL).
#include "common/frame.glsl"
#include "common/atmosphere.glsl"

in vec2 v_uv;
layout(location = 0) out vec4 out_color;
layout(location = 1) out float out_distance;

void main() {
    vec3 dir = view_ray(v_uv);
    vec3 radiance = sky_radiance(dir) + sun_disk(dir);
    out_color = vec4(pre_expose(radiance), 1.0);
    out_distance = 1e30;  // sky: infinitely far
}
