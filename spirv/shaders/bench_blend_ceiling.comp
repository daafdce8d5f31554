#version 460
// Ceiling probe for the blend: the blend's per-(pixel, splat) arithmetic
// (splat_alpha, the stop test, weight, transmittance and rgb, as selects like
// splat_blend_texel.comp) with no memory traffic: the splats come from the
// loop counter (a few ops, the same for every lane) and each invocation blends
// PIXELS pixels (distinct, all within 17×16 of the splats' means). Splats are faint and wide, so every evaluation contributes
// and, under the benchmark's flop counts, no blend kernel can do better on
// the device.
// CPU twin: engine/src/bench.rs `blend_ceiling_cpu`.
#extension GL_EXT_control_flow_attributes : require
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "splat_types.glsl"

layout(constant_id = 0) const uint PIXELS = 4u;

// Keep in sync with engine/src/bench.rs `BlendCeilingPush`.
layout(push_constant) uniform BlendCeilingPush {
    uvec2 out_addr;  // one float per invocation: Σ over its pixels of T + r + g + b
    uint splats;     // splats every pixel blends (at most 1024 keep T above 1e-4)
    uint count;      // invocations
} pc;

void main() {
    uint i = linear_index();
    if (i >= pc.count) return;
    float T[PIXELS];
    vec3 rgb[PIXELS];
    vec2 centre[PIXELS];
    [[unroll]] for (uint k = 0u; k < PIXELS; k++) {
        T[k] = 1.0;
        rgb[k] = vec3(0.0);
        // Distinct for every k (else the compiler merges pixels that blend alike).
        centre[k] = vec2(float(i % 16u) + float(k) / 64.0, float((k + i / 16u) % 16u)) + 0.5;
    }
    for (uint j = 0u; j < pc.splats; j++) {
        // α ≥ 0.0048 > 1/255 at every centre (σ ≤ 0.025), and 0.995^1024 > 1e-4.
        vec4 head = vec4(float(j & 15u), float((j >> 4u) & 15u), float(j), 0.005);
        vec4 conic = vec4(1e-4, 1e-5, 1e-4, 0.0);
        vec3 color = vec3(0.25, 0.5, 0.75) + head.z * 1e-6;
        [[unroll]] for (uint k = 0u; k < PIXELS; k++) {
            float alpha, gauss;
            vec2 d;
            bool hit = splat_alpha(head, conic, centre[k], alpha, gauss, d);
            float next_T = T[k] * (1.0 - alpha);
            bool takes = all(bvec2(hit, next_T >= 1e-4));
            rgb[k] += mix(0.0, alpha * T[k], takes) * color;
            T[k] = mix(T[k], next_T, takes);
        }
    }
    float s = 0.0;
    [[unroll]] for (uint k = 0u; k < PIXELS; k++) s += T[k] + rgb[k].r + rgb[k].g + rgb[k].b;
    FloatsOut(pc.out_addr).v[i] = s;
}
