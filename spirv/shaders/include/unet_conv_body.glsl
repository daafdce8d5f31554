// The body of unet_conv.comp and unet_conv_half.comp (see there).
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "address.glsl"
#include "unet_storage.glsl"

layout(constant_id = 0) const uint STRIDE = 1;
// 0: none, 1: ReLU, 2: leaky ReLU (slope 0.01).
layout(constant_id = 1) const uint ACT = 1;
// Output channels per invocation: 8, 16 or 32.
layout(constant_id = 2) const uint OCB = 8;

// Keep in sync with engine/src/indirect/mod.rs `CONV_UBO_VEC4S`.
layout(std140, set = 0, binding = 0) uniform Weights { vec4 wts[4096]; };
layout(std430, set = 0, binding = 1) readonly buffer Bias { vec4 bias[]; };

// Keep in sync with engine/src/indirect/mod.rs `ConvPush`.
layout(push_constant) uniform Push {
    uvec2 a;        // first input, ca channels
    uvec2 b;        // second input, cb channels (skip)
    uvec2 o;        // output, oc channels
    uvec2 partial;  // fp32 partial sums between passes, oc channels
    uint ca;
    uint cb;
    uint oc;
    uint ic0;       // this pass's input channels [ic0, ic1)
    uint ic1;
    uint flags;     // 1: first pass (start from the bias), 2: last pass (activate)
    uvec2 in_size;  // width, height
    uvec2 out_size;
} pc;

void main() {
    uint plane = pc.out_size.x * pc.out_size.y;
    uint p = (gl_WorkGroupID.x + gl_WorkGroupID.z * gl_NumWorkGroups.x) * WORKGROUP_SIZE_X + gl_LocalInvocationID.x;
    uint ob = gl_WorkGroupID.y;
    bool live = p < plane;
    p = min(p, plane - 1u);
    int ox = int(p % pc.out_size.x), oy = int(p / pc.out_size.x);
    const uint Q = OCB / 4u;
    vec4 acc[8];
    if ((pc.flags & 1u) != 0u) {
        for (uint q = 0u; q < Q; ++q) acc[q] = bias[Q * ob + q];
    } else {
        FloatsIn prev = FloatsIn(pc.partial);
        for (uint q = 0u; q < Q; ++q) {
            for (uint j = 0u; j < 4u; ++j) {
                uint c = min(ob * OCB + 4u * q + j, pc.oc - 1u);
                acc[q][j] = prev.v[c * plane + p];
            }
        }
    }
    uint in_plane = pc.in_size.x * pc.in_size.y;
    int w = int(pc.in_size.x), h = int(pc.in_size.y);
    // Input channels per pass as packed (engine/src/indirect/mod.rs `pass_channels`).
    uint chunk = 16384u / (gl_NumWorkGroups.y * OCB * 9u);
    for (uint ic = pc.ic0; ic < pc.ic1; ++ic) {
        uvec2 src = ic < pc.ca ? pc.a : pc.b;
        uint base = (ic < pc.ca ? ic : ic - pc.ca) * in_plane;
        uint wbase = ((ob * chunk + (ic - pc.ic0)) * 9u) * Q;
        for (int ky = 0; ky < 3; ++ky) {
            int iy = oy * int(STRIDE) + ky - 1;
            bool row_in = iy >= 0 && iy < h;
            for (int kx = 0; kx < 3; ++kx) {
                int ix = ox * int(STRIDE) + kx - 1;
                float v = row_in && ix >= 0 && ix < w ? load_input(src, base + uint(iy * w + ix)) : 0.0;
                uint t = wbase + uint(ky * 3 + kx) * Q;
                for (uint q = 0u; q < Q; ++q) acc[q] += v * wts[t + q];
            }
        }
    }
    if (!live) return;
    bool last = (pc.flags & 2u) != 0u;
    for (uint q = 0u; q < Q; ++q) {
        vec4 a = acc[q];
        if (last) {
            if (ACT == 1u) {
                a = max(a, 0.0);
            } else if (ACT == 2u) {
                a = mix(a * 0.01, a, greaterThanEqual(a, vec4(0.0)));
            }
        }
        for (uint j = 0u; j < 4u; ++j) {
            uint c = ob * OCB + 4u * q + j;
            if (c >= pc.oc) continue;
            if (last) {
                store_output(pc.o, c * plane + p, a[j]);
            } else {
                FloatsOut(pc.partial).v[c * plane + p] = a[j];
            }
        }
    }
}
