// Copy of the scene distance (R32F, m along the view ray) by a fullscreen draw.
uniform sampler2D u_distance;
layout(location = 0) out float out_distance;
void main() {
    out_distance = texelFetch(u_distance, ivec2(gl_FragCoord.xy), 0).r;
}
