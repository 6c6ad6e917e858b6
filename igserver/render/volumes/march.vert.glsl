// The container's slabs, camera-relative (corners subtracted in float64 on the CPU): instance i
// draws slab i's box (march_block.glsl), farthest first. Only back faces are drawn: they cover the
// box's screen area whether the camera is outside or inside it.
#include "common/frame.glsl"
#include "volumes/march_block.glsl"
in vec3 in_position;     // unit cube corner in [0,1]^3
out vec3 v_rel;
flat out vec3 v_box_min;  // m, camera-relative AABB of this slab
flat out vec3 v_box_max;
void main() {
    v_box_min = u_slab_min[gl_InstanceID].xyz;
    v_box_max = u_slab_max[gl_InstanceID].xyz;
    v_rel = mix(v_box_min, v_box_max, in_position);
    gl_Position = u_view_proj * vec4(v_rel, 1.0);
}
