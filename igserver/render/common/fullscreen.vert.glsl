// One triangle covering the viewport; v_uv in [0,1]^2 over the screen. It lies at infinity
// (window depth 0): the sky draws there; ray-cast passes write their own gl_FragDepth.
#include "common/depth.glsl"
out vec2 v_uv;
void main() {
    vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);
    v_uv = p;
    gl_Position = vec4(p * 2.0 - 1.0, NDC_Z_AT_INFINITY, 1.0);
}
