#version 460
// Each tile's chunk count for the split blend (`list_chunks`; the host's
// exclusive scan then gives each tile its first chunk slot, and the total),
// one invocation per tile. CPU twin: engine/src/splat/mod.rs `list_chunks`;
// checked through the split blend's tests against the CPU twin.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "splat.glsl"

// Entries of a chunk (keep in sync with the blend's `CHUNK_LENGTH`).
layout(constant_id = 0) const uint CHUNK_LENGTH = 4096u;

layout(push_constant) uniform ChunkCountPush {
    uvec2 counts;  // u32 per tile, then the total's slot
} push;

void main() {
    uint t = linear_index();
    if (t >= frame.size.z * frame.size.w) return;
    UintsOut(push.counts).v[t] = list_chunks(Uvec2sIn(frame.ranges).v[t], CHUNK_LENGTH);
}
