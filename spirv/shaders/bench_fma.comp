#version 460
// Peak-throughput probe: 8 independent vec4 FMA chains per invocation, so
// the device's practical FMA ceiling can be measured in the same run as a
// benchmark. 64 flops per loop iteration. Result written so nothing is elided.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "address.glsl"

// Keep in sync with engine/src/bench.rs `FmaPush`.
layout(push_constant) uniform FmaPush {
    uvec2 out_addr;
    uint iterations;
    uint count;
} pc;

void main() {
    uint i = linear_index();
    if (i >= pc.count) return;
    vec4 a = vec4(float(i) * 1e-7);
    vec4 m = vec4(0.999999), c = vec4(1e-7);
    vec4 x0 = a, x1 = a + 1.0, x2 = a + 2.0, x3 = a + 3.0, x4 = a + 4.0, x5 = a + 5.0, x6 = a + 6.0, x7 = a + 7.0;
    for (uint k = 0; k < pc.iterations; k++) {
        x0 = fma(x0, m, c); x1 = fma(x1, m, c); x2 = fma(x2, m, c); x3 = fma(x3, m, c);
        x4 = fma(x4, m, c); x5 = fma(x5, m, c); x6 = fma(x6, m, c); x7 = fma(x7, m, c);
    }
    vec4 s = x0 + x1 + x2 + x3 + x4 + x5 + x6 + x7;
    FloatsOut(pc.out_addr).v[i] = s.x + s.y + s.z + s.w;
}
