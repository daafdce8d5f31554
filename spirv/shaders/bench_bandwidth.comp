#version 460
// Floor probe for memory-bound stages: a buffer read once, front to back,
// through an RGBA32F texel-buffer view (16 bytes a fetch, as the texel
// kernels read) or, with ADDRESS, as uvec4s by device address (a GPU's plain
// loads, which may outrun its texel fetches; an invocation whose texels are
// all in range reads them with no bound checks, so its loads can be issued
// together). Each invocation owns ITEMS consecutive texels (the layout CPU
// implementations vectorize best) or, with INTERLEAVED, every 64th texel of
// its workgroup's block (neighbouring lanes read neighbouring texels, the
// layout GPUs coalesce); the host takes the fastest. With COPY each texel is
// also written by device address to the same index of a second buffer.
// Without COPY each invocation writes the xor of what it read, so the reads
// cannot be skipped. The bytes moved over the time is the device's streaming
// bandwidth.
// CPU twin: cli/src/bench/limits.rs `bandwidth_cpu`.
#extension GL_EXT_control_flow_attributes : require
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "address.glsl"

// Keep in sync with cli/src/bench/limits.rs `BANDWIDTH_ITEMS`.
#define ITEMS 64
layout(constant_id = 0) const bool COPY = false;
layout(constant_id = 1) const bool INTERLEAVED = false;
layout(constant_id = 2) const bool ADDRESS = false;

// Keep in sync with cli/src/bench/limits.rs `BandwidthPush`.
layout(push_constant) uniform BandwidthPush {
    uvec2 src_addr;  // uvec4[count], the same buffer the view shows (ADDRESS)
    uvec2 out_addr;  // uvec4[count] with COPY, else uint[invocations]
    uint count;      // texels
    uint blocks;
} pc;

layout(buffer_reference, std430, buffer_reference_align = 16) writeonly buffer Uvec4sOut { uvec4 v[]; };
layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer Uvec4sIn { uvec4 v[]; };

layout(set = 0, binding = 0) uniform textureBuffer source;  // RGBA32F, finite values

void main() {
    uint me = block_index() * WORKGROUP_SIZE_X + gl_LocalInvocationID.x;
    uint sum = 0u;
    // Texel k of this invocation: me·ITEMS + k, or interleaved block start + k·64 + lane.
    uint first = INTERLEAVED ? block_index() * WORKGROUP_SIZE_X * ITEMS + gl_LocalInvocationID.x : me * ITEMS;
    uint step = INTERLEAVED ? WORKGROUP_SIZE_X : 1u;
    if (ADDRESS && first + (ITEMS - 1u) * step < pc.count) {
        [[unroll]] for (uint k = 0u; k < ITEMS; k++) {
            uint i = first + k * step;
            uvec4 t = Uvec4sIn(pc.src_addr).v[i];
            if (COPY) Uvec4sOut(pc.out_addr).v[i] = t;
            sum ^= t.x ^ t.y ^ t.z ^ t.w;
        }
    } else {
        for (uint k = 0u; k < ITEMS; k++) {
            uint i = first + k * step;
            if (i >= pc.count) break;
            uvec4 t = ADDRESS ? Uvec4sIn(pc.src_addr).v[i] : floatBitsToUint(texelFetch(source, int(i)));
            if (COPY) Uvec4sOut(pc.out_addr).v[i] = t;
            sum ^= t.x ^ t.y ^ t.z ^ t.w;
        }
    }
    if (!COPY && first < pc.count) UintsOut(pc.out_addr).v[me] = sum;
}
