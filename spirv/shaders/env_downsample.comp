#version 460
// Environment pyramid: one level from the previous by a 2×2 box (edges
// clamped for odd sizes), one invocation per output texel. The prefilter
// reads coarse levels where its samples are sparse (filtered importance sampling).
// CPU twin: engine/src/shade/cpu.rs `downsample_cpu`.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "latlong.glsl"

// Keep in sync with engine/src/shade/env.rs `DownsamplePush`.
layout(push_constant) uniform DownsamplePush {
    uvec2 src;      // source level (address of its first texel)
    uvec2 dst;      // output level
    uvec2 src_size;
    uvec2 dst_size;
} push;

void main() {
    uint i = linear_index();
    if (i >= push.dst_size.x * push.dst_size.y) return;
    uvec2 t = uvec2(i % push.dst_size.x, i / push.dst_size.x);
    uvec2 lo = min(2u * t, push.src_size - 1u);
    uvec2 hi = min(2u * t + 1u, push.src_size - 1u);
    vec3 s = latlong_texel(push.src, 0u, push.src_size, int(lo.x), int(lo.y))
           + latlong_texel(push.src, 0u, push.src_size, int(hi.x), int(lo.y))
           + latlong_texel(push.src, 0u, push.src_size, int(lo.x), int(hi.y))
           + latlong_texel(push.src, 0u, push.src_size, int(hi.x), int(hi.y));
    FloatsOut o = FloatsOut(push.dst);
    o.v[3u * i] = 0.25 * s.x;
    o.v[3u * i + 1u] = 0.25 * s.y;
    o.v[3u * i + 2u] = 0.25 * s.z;
}
