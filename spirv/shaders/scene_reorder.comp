#version 460
// Moves a scene's rows into another order on the device, and maps Gaussian
// indices through an order. Host side and CPU twin: engine/src/scene/order.rs.
// MODE 0, rows: dst[i·dst_stride + dst_first + j] = src[r·src_stride + src_first + j]
//   for j < width, with r = index[i] (r = i where index is null): words move
//   bit for bit, so any 32-bit data (floats with their NaN payloads) survives;
//   four at a time where every stride and offset is a multiple of four words
//   (both buffers' addresses being 16-byte aligned, as srug's allocations are).
// MODE 1, ids: dst[i] = index[src[i]] where src[i] < width, else src[i]
//   (u32::MAX, "no Gaussian", stays); dst may be src.
// MODE 2, rows scattered: as MODE 0 with source row i written to row index[i].
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

layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer Uvec4In { uvec4 v; };
layout(buffer_reference, std430, buffer_reference_align = 16) writeonly buffer Uvec4Out { uvec4 v; };

uint64_t word_address(uvec2 base, uint64_t word) {
    return packUint2x32(base) + word * uint64_t(4);
}

void main() {
    uint i = linear_index();
    if (i >= pc.count) return;
    bool indexed = any(notEqual(pc.index, uvec2(0u)));
    if (MODE == 0u || MODE == 2u) {
        uint r = indexed ? UintIn(word_address(pc.index, uint64_t(i))).v : i;
        uint src_row = MODE == 0u ? r : i, dst_row = MODE == 0u ? i : r;
        uint64_t from = uint64_t(src_row) * uint64_t(pc.src_stride) + uint64_t(pc.src_first);
        uint64_t to = uint64_t(dst_row) * uint64_t(pc.dst_stride) + uint64_t(pc.dst_first);
        if (((pc.width | pc.src_stride | pc.src_first | pc.dst_stride | pc.dst_first) & 3u) == 0u) {
            // Whole aligned quads (an SH row's blocks): 16-byte loads and stores.
            for (uint j = 0u; j < pc.width; j += 4u) {
                Uvec4Out(word_address(pc.dst, to + uint64_t(j))).v = Uvec4In(word_address(pc.src, from + uint64_t(j))).v;
            }
        } else {
            for (uint j = 0u; j < pc.width; j++) {
                UintOut(word_address(pc.dst, to + uint64_t(j))).v = UintIn(word_address(pc.src, from + uint64_t(j))).v;
            }
        }
    } else {
        uint id = UintIn(word_address(pc.src, uint64_t(i))).v;
        uint mapped = id < pc.width ? UintIn(word_address(pc.index, uint64_t(id))).v : id;
        UintOut(word_address(pc.dst, uint64_t(i))).v = mapped;
    }
}
