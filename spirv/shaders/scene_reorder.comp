#version 460
// Moves a scene's rows into another order on the device, and maps Gaussian
// indices through an order. Host side and CPU twin: engine/src/scene/order.rs.
// MODE 0, rows: dst[i·dst_stride + dst_first + j] = src[r·src_stride + src_first + j]
//   for j < width, with r = index[i] (r = i where index is null): words move
//   bit for bit, so any 32-bit data (floats with their NaN payloads) survives.
// MODE 1, ids: dst[i] = index[src[i]] where src[i] < width, else src[i]
//   (u32::MAX, "no Gaussian", stays); dst may be src.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#define SRUG_ADDRESS_64
#include "address.glsl"

layout(constant_id = 0) const uint MODE = 0u;

// Host mirror: engine/src/scene/layout.rs `ReorderPush` (its layout is checked against this block).
layout(push_constant) uniform ReorderPush {
    uvec2 src;
    uvec2 dst;
    uvec2 index;
    uint count;
    uint width;
    uint src_stride;
    uint src_first;
    uint dst_stride;
    uint dst_first;
} pc;

uint64_t word_address(uvec2 base, uint64_t word) {
    return packUint2x32(base) + word * uint64_t(4);
}

void main() {
    uint i = linear_index();
    if (i >= pc.count) return;
    bool indexed = any(notEqual(pc.index, uvec2(0u)));
    if (MODE == 0u) {
        uint r = indexed ? UintIn(word_address(pc.index, uint64_t(i))).v : i;
        uint64_t from = uint64_t(r) * uint64_t(pc.src_stride) + uint64_t(pc.src_first);
        uint64_t to = uint64_t(i) * uint64_t(pc.dst_stride) + uint64_t(pc.dst_first);
        for (uint j = 0u; j < pc.width; j++) {
            UintOut(word_address(pc.dst, to + uint64_t(j))).v = UintIn(word_address(pc.src, from + uint64_t(j))).v;
        }
    } else {
        uint id = UintIn(word_address(pc.src, uint64_t(i))).v;
        uint mapped = id < pc.width ? UintIn(word_address(pc.index, uint64_t(id))).v : id;
        UintOut(word_address(pc.dst, uint64_t(i))).v = mapped;
    }
}
