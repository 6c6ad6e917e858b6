// The cirrus layer at reduced resolution, once per frame (sky.py draws it before the sky pass),
// premultiplied so that the sky pass's bilinear lookup interpolates it correctly, and already
// seen through the air between the camera and the layer (clear air and haze, per channel):
//   out_layer = (cloud radiance x alpha x T, alpha)   out_hide = (alpha x T, 0)
// so the sky pass composites L (1 - out_hide) + out_layer.rgb with two lookups and no
// per-pixel ray-layer intersection or transmittance (those cost ~60 % of the sky pass's
// per-pixel work on llvmpipe). The noise (7 simplex octaves) and the 16-ray earth shadow run
// on 1/4 of the pixels, and only on those whose rays can meet the layer (sky.py cirrus_polygon).
#include "common/frame.glsl"
#include "common/atmosphere.glsl"
#include "sky/cirrus.glsl"

uniform vec2 u_cirrus_table_size;  // texels
layout(location = 0) out vec4 out_layer;
layout(location = 1) out vec4 out_hide;

void main() {
    // The texel's uv from its window position, not an interpolated varying: the same value
    // whatever polygon covers it (the frame is then independent of the polygon, bit for bit).
    vec3 dir = view_ray(gl_FragCoord.xy / u_cirrus_table_size);
    vec4 c = cirrus_layer(dir);
    vec3 t_cam = c.a > 0.0 ? cirrus_transmittance(dir, max(cirrus_distance(dir), 0.0)) : vec3(1.0);
    out_layer = vec4(c.rgb * t_cam, c.a);
    out_hide = vec4(c.a * t_cam, 0.0);
}
