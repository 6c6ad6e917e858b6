// Entity meshes: model matrices arrive camera-relative (translation subtracted in float64).
#include "common/frame.glsl"
uniform mat4 u_model;
uniform mat3 u_normal_matrix;
in vec3 in_position;
in vec3 in_normal;
out vec3 v_rel;
out vec3 v_normal;
void main() {
    vec4 rel = u_model * vec4(in_position, 1.0);
    v_rel = rel.xyz;
    v_normal = u_normal_matrix * in_normal;
    gl_Position = u_view_proj * rel;
}
