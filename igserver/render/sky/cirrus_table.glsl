// The cirrus layer at reduced resolution, once per frame (sky.py draws it before the sky pass):
// (cloud radiance x alpha, alpha) per texel, premultiplied so that the sky pass's bilinear lookup
// interpolates it correctly; the sky pass composites it with its own per-pixel transmittance to the
// layer. The noise (7 simplex octaves) and the 16-ray earth shadow then run on 1/4 of the pixels.
#include "common/frame.glsl"
#include "common/atmosphere.glsl"
#include "sky/cirrus.glsl"

in vec2 v_uv;
layout(location = 0) out vec4 out_layer;

void main() {
    out_layer = cirrus_layer(view_ray(v_uv));
}
