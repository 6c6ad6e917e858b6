// Keeps the GPU busy for a known time and nothing else (the bench's GPU head start, bench_gpu.py).
// One work group of 64 invocations runs a serial chain of u_iterations dependent steps, so its
// duration is proportional to u_iterations and independent of how many shader cores the GPU has.
// The result is stored, so the compiler cannot drop the chain; nothing reads it.
#include "generated/bindings.glsl"

layout(local_size_x = 64) in;
layout(std430, binding = STORAGE_GPU_HEAD_START) writeonly buffer Sink { float sink[]; };
uniform int u_iterations;

void main() {
    uint i = gl_LocalInvocationID.x;
    float x = float(i) * 0.015625;
    for (int k = 0; k < u_iterations; ++k) {
        x = fract(x * 1.6180339 + 0.1234567);  // a dependent chain: no step can start before the last
    }
    sink[i] = x;
}
