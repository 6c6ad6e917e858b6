// The cirrus table's polygon (sky.py cirrus_polygon): the part of the frame, in uv, whose rays can
// meet the layer (the fragment shader takes its uv from gl_FragCoord).
#include "common/depth.glsl"
in vec2 in_uv;
void main() {
    gl_Position = vec4(in_uv * 2.0 - 1.0, NDC_Z_AT_INFINITY, 1.0);
}
