#version 460
// U-Net layer: 3×3 convolution, padding 1, stride STRIDE, fused bias and
// activation, over the channel concatenation of two CHW tensors A and B
// (B may be empty), so a skip connection needs no copy. One invocation per
// output pixel and block of 8 output channels; weights are packed host-side
// as [oc/8][ic][3·3][8] so each input value feeds 8 FMAs from two vec4
// loads shared by every invocation of the block. fp32 accumulation.
// CPU twin: engine/src/indirect/cpu.rs `conv3x3_cpu`.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "address.glsl"

layout(constant_id = 0) const uint STRIDE = 1;
// 0: none, 1: ReLU, 2: leaky ReLU (slope 0.01).
layout(constant_id = 1) const uint ACT = 1;

layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer Vec4sIn { vec4 v[]; };

// Keep in sync with engine/src/indirect/mod.rs `ConvPush`.
layout(push_constant) uniform Push {
    uvec2 a;        // first input, ca channels
    uvec2 b;        // second input, cb channels (skip)
    uvec2 w;        // packed weights
    uvec2 bias;     // bias, padded to a multiple of 8
    uvec2 o;        // output, oc channels
    uint ca;
    uint cb;
    uint oc;
    uint pad0;
    uvec2 in_size;  // width, height
    uvec2 out_size;
} pc;

void main() {
    uint i = linear_index();
    uint plane = pc.out_size.x * pc.out_size.y;
    uint blocks = (pc.oc + 7u) / 8u;
    if (i >= plane * blocks) return;
    uint p = i % plane;
    uint ob = i / plane;
    int ox = int(p % pc.out_size.x), oy = int(p / pc.out_size.x);
    Vec4sIn wts = Vec4sIn(pc.w);
    Vec4sIn bias = Vec4sIn(pc.bias);
    vec4 acc0 = bias.v[2u * ob], acc1 = bias.v[2u * ob + 1u];
    uint cin = pc.ca + pc.cb;
    uint in_plane = pc.in_size.x * pc.in_size.y;
    int w = int(pc.in_size.x), h = int(pc.in_size.y);
    for (uint ic = 0u; ic < cin; ++ic) {
        FloatsIn src = ic < pc.ca ? FloatsIn(pc.a) : FloatsIn(pc.b);
        uint base = (ic < pc.ca ? ic : ic - pc.ca) * in_plane;
        uint wbase = ((ob * cin + ic) * 9u) * 2u;
        for (int ky = 0; ky < 3; ++ky) {
            int iy = oy * int(STRIDE) + ky - 1;
            if (iy < 0 || iy >= h) continue;
            for (int kx = 0; kx < 3; ++kx) {
                int ix = ox * int(STRIDE) + kx - 1;
                if (ix < 0 || ix >= w) continue;
                float v = src.v[base + uint(iy * w + ix)];
                uint t = wbase + uint(ky * 3 + kx) * 2u;
                acc0 += v * wts.v[t];
                acc1 += v * wts.v[t + 1u];
            }
        }
    }
    if (ACT == 1u) {
        acc0 = max(acc0, 0.0);
        acc1 = max(acc1, 0.0);
    } else if (ACT == 2u) {
        acc0 = mix(acc0 * 0.01, acc0, greaterThanEqual(acc0, vec4(0.0)));
        acc1 = mix(acc1 * 0.01, acc1, greaterThanEqual(acc1, vec4(0.0)));
    }
    FloatsOut o = FloatsOut(pc.o);
    float r[8] = float[8](acc0.x, acc0.y, acc0.z, acc0.w, acc1.x, acc1.y, acc1.z, acc1.w);
    for (uint j = 0u; j < 8u; ++j) {
        uint c = ob * 8u + j;
        if (c < pc.oc) o.v[c * plane + p] = r[j];
    }
}
