// Per-frame uniforms shared by every pass. Positions are camera-relative ENU metres (x east,
// y north, z up, origin at the camera), radiance is pre-exposed (multiplied by u_exposure) so that
// values stay well inside half-float range (the sun's disk is ~1.5e9 cd/m^2 before exposure).
uniform mat4 u_view_proj;        // camera-relative world -> clip
uniform mat4 u_inv_view_proj;    // clip -> camera-relative world
uniform vec2 u_resolution;       // px
uniform float u_camera_altitude; // m above mean sea level (origin altitude + camera z)
uniform float u_exposure;        // 1 / (1.2 * 2^EV100): cd/m^2 -> display-referred
uniform vec3 u_sun_dir;          // unit, toward the sun
uniform vec3 u_sun_illuminance;  // lux per channel at the camera, after the atmosphere
uniform vec3 u_moon_dir;
uniform vec3 u_moon_illuminance; // lux per channel
uniform vec3 u_sky_ambient;      // cd/m^2, cosine-weighted mean sky radiance (irradiance / pi)

const float PI = 3.14159265358979;
const float HALF_MAX = 60000.0;  // keep below float16 max (65504) after pre-exposure

// Direction of the view ray through a pixel (uv in [0,1]^2), camera-relative world frame.
vec3 view_ray(vec2 uv) {
    vec4 far_point = u_inv_view_proj * vec4(uv * 2.0 - 1.0, 1.0, 1.0);
    vec4 near_point = u_inv_view_proj * vec4(uv * 2.0 - 1.0, -1.0, 1.0);
    return normalize(far_point.xyz / far_point.w - near_point.xyz / near_point.w);
}

// Window depth of a camera-relative point (for gl_FragDepth of ray-cast surfaces).
float window_depth(vec3 rel) {
    vec4 clip = u_view_proj * vec4(rel, 1.0);
    return clamp(0.5 * clip.z / clip.w + 0.5, 0.0, 1.0);
}

vec3 pre_expose(vec3 radiance) {
    return min(radiance * u_exposure, vec3(HALF_MAX));
}
