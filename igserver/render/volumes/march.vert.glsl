// The container's box, camera-relative (corners subtracted in float64 on the CPU). Only back faces
// are drawn: they cover the box's screen area whether the camera is outside or inside it.
#include "common/frame.glsl"
uniform vec3 u_box_min;  // m, camera-relative
uniform vec3 u_box_max;
in vec3 in_position;     // unit cube corner in [0,1]^3
out vec3 v_rel;
void main() {
    v_rel = mix(u_box_min, u_box_max, in_position);
    gl_Position = u_view_proj * vec4(v_rel, 1.0);
}
