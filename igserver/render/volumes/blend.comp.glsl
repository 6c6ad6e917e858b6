// Capped-rate modelling (volumes.py): the two keyframe textures of an effect mixed ONCE per frame
// into the texture the march reads, instead of two 3D lookups per march sample (trilinear
// filtering is linear, so mixing the voxels then filtering equals filtering both then mixing,
// up to the rgba16f rounding of the mixed voxel). Keyframes of different sizes (the level of
// detail changed between them) are resampled at the output's voxel centres.
layout(local_size_x = 4, local_size_y = 4, local_size_z = 4) in;
layout(rgba16f, binding = 0) writeonly uniform image3D u_out;
uniform sampler3D u_volume;
uniform sampler3D u_volume_next;
uniform float u_blend;

void main() {
    ivec3 id = ivec3(gl_GlobalInvocationID);
    ivec3 size = imageSize(u_out);
    if (any(greaterThanEqual(id, size))) return;
    vec4 a, b;
    if (textureSize(u_volume, 0) == size) a = texelFetch(u_volume, id, 0);
    else a = textureLod(u_volume, (vec3(id) + 0.5) / vec3(size), 0.0);
    if (textureSize(u_volume_next, 0) == size) b = texelFetch(u_volume_next, id, 0);
    else b = textureLod(u_volume_next, (vec3(id) + 0.5) / vec3(size), 0.0);
    imageStore(u_out, id, mix(a, b, u_blend));
}
