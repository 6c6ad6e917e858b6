// The sky seen through the fog/haze layer, on the sky-view table's directions (sky/sky_view_map.glsl),
// once per change of its inputs instead of once per sky pixel and frame (haze_sky() was ~60 % of the
// sky pass's CPU on llvmpipe). haze_sky = L T + S_diffuse + S_sun p_sun + S_moon p_moon
// (common/atmosphere.glsl haze_ray): all of it but the moon's phase p_moon depends on the ray's height
// above the horizon and its angle to the sun only, the table's two axes; the moon's term S_moon
// depends on the height alone and goes into a one-texel-wide column on the same rows, the sky pass
// adding S_moon p_moon per pixel while the moon is up (sky.py SkyPass._hazy_table).
#include "common/frame.glsl"
#include "common/atmosphere.glsl"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;
layout(binding = 0, rgba32f) uniform writeonly image2D u_out;
layout(binding = 1, rgba32f) uniform writeonly image2D u_out_moon;

void main() {
    ivec2 texel = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = imageSize(u_out);
    if (any(greaterThanEqual(texel, size))) return;
    vec2 uv = (vec2(texel) + 0.5) / vec2(size);
    vec3 dir = sky_view_dir(uv);
    HazeRay ray = haze_ray(dir);
    vec3 clear = texture(u_sky_view_radiance, uv).rgb;  // the clear table's own texel (same size)
    imageStore(u_out, texel, vec4(clear * ray.transmittance + ray.diffuse + ray.sun * haze_phases(dir).x, 0.0));
    if (texel.x == 0) imageStore(u_out_moon, ivec2(0, texel.y), vec4(ray.moon, 0.0));
}
