// Per-frame uniforms shared by every pass. Positions are camera-relative ENU metres (x east,
// y north, z up, origin at the camera), radiance is pre-exposed (multiplied by u_exposure) so that
// values stay well inside half-float range (the sun's disk is ~1.5e9 cd/m^2 before exposure).
#include "common/depth.glsl"
// The camera, exposure, sun, moon and point/spot lights: the frame's uniform block (declared in
// render/frame_block.py, one buffer shared by every draw program; plain uniforms where FRAME_BLOCK
// is 0). Units there: positions m, illuminance lux per channel, radiance cd/m^2.
#include "generated/frame_block.glsl"

const float PI = 3.14159265358979;
const float HALF_MAX = 60000.0;  // keep below float16 max (65504) after pre-exposure

// Direction of the view ray through a pixel (uv in [0,1]^2), camera-relative world frame: from
// the camera basis and the frustum tangents (screen position is linear in the tangents), with no
// matrix inverse, so it is as exact at fov 0.2 deg and at any near/far as at fov 60.
vec3 view_ray(vec2 uv) {
    vec2 t = mix(u_frustum_tangents.xz, u_frustum_tangents.yw, uv);
    return normalize(u_camera_forward + t.x * u_camera_right + t.y * u_camera_up);
}

// Window depth of a camera-relative point (for gl_FragDepth of ray-cast surfaces): near / d,
// clip z / clip w, in the context's clip range. Relative precision 2^-24 at every distance.
float window_depth(vec3 rel) {
    vec4 clip = u_view_proj * vec4(rel, 1.0);
#if DEPTH_ZERO_TO_ONE
    return clamp(clip.z / clip.w, 0.0, 1.0);
#else
    return clamp(0.5 * clip.z / clip.w + 0.5, 0.0, 1.0);
#endif
}

vec3 pre_expose(vec3 radiance) {
    return min(radiance * u_exposure, vec3(HALF_MAX));
}
