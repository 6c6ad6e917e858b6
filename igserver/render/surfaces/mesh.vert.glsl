// Entity meshes, instanced: one instance per entity drawing this primitive. The instance's model
// matrix arrives camera-relative (translation subtracted in float64 on the CPU); SHADOW_PASS
// variants transform into a light's clip space instead of the camera's.
#include "common/frame.glsl"
#ifdef SHADOW_PASS
uniform mat4 u_light_view_proj;   // camera-relative world -> light clip
#endif
in vec3 in_position;
in vec3 in_normal;
in vec2 in_uv;
in vec4 in_model0;   // columns of the instance's model matrix
in vec4 in_model1;
in vec4 in_model2;
in vec4 in_model3;
in vec4 in_tint;     // rgb base-colour factor, a = metallic factor
in vec4 in_extra;    // x = roughness factor
out vec3 v_rel;
out vec3 v_normal;
out vec2 v_uv;
flat out vec4 v_tint;
flat out float v_roughness_factor;
void main() {
    mat4 model = mat4(in_model0, in_model1, in_model2, in_model3);
    vec4 rel = model * vec4(in_position, 1.0);
    v_rel = rel.xyz;
    // Normals transform by the inverse transpose; the cofactor matrix is that up to a scale,
    // and is finite for any non-singular (also non-uniformly scaled) model matrix.
    mat3 m = mat3(model);
    mat3 cofactor = mat3(cross(m[1], m[2]), cross(m[2], m[0]), cross(m[0], m[1]));
    v_normal = cofactor * in_normal;
    v_uv = in_uv;
    v_tint = in_tint;
    v_roughness_factor = in_extra.x;
#ifdef SHADOW_PASS
    gl_Position = u_light_view_proj * rel;
#else
    gl_Position = u_view_proj * rel;
#endif
}
