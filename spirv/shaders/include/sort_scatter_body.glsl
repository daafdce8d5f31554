// The body of sort_scatter.comp and sort_scatter_texel.comp (see there).
#extension GL_EXT_control_flow_attributes : require
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "address.glsl"

#define ITEMS 16
#define SORT_BLOCK (WORKGROUP_SIZE_X * ITEMS)
#define RADIX 16
#define NONE 0xffffffffu

// Keep in sync with engine/src/splat/sort.rs `SortPush`.
layout(push_constant) uniform Push {
    uvec2 keys_in;
    uvec2 values_in;
    uvec2 keys_out;
    uvec2 values_out;
    uvec2 hist;
    uint count;
    uint shift;
    uint blocks;
    uint digit_mask;  // 15, or fewer bits on the last pass
} pc;

shared uint table[RADIX][WORKGROUP_SIZE_X];

#ifdef TEXEL_INPUT
// The input keys (RG32UI) and values (R32UI) as texel-buffer views.
layout(set = 0, binding = 0) uniform usamplerBuffer keys_view;
layout(set = 0, binding = 1) uniform usamplerBuffer values_view;
// Clamped: lanes past the end fetch the last key (and discard it), never out of the view.
#define KEY(i) texelFetch(keys_view, int(min(i, pc.count - 1u))).xy
#define VALUE(i) texelFetch(values_view, int(min(i, pc.count - 1u))).x
#else
#define KEY(i) Uvec2sIn(pc.keys_in).v[i]
#define VALUE(i) UintsIn(pc.values_in).v[i]
#endif

uint digit_of(uvec2 key) {
    return (pc.shift < 32 ? key.x >> pc.shift : key.y >> (pc.shift - 32)) & pc.digit_mask;
}

void main() {
    uint block = block_index();
    uint t = gl_LocalInvocationID.x;
    uint base = block * SORT_BLOCK + t * ITEMS;
    uvec2 k[ITEMS];
    uint dig[ITEMS];
    [[unroll]] for (uint i = 0; i < ITEMS; i++) {
        bool valid = base + i < pc.count;
        k[i] = valid ? KEY(base + i) : uvec2(0u);
        dig[i] = valid ? digit_of(k[i]) : NONE;
    }
    [[unroll]] for (uint d = 0; d < RADIX; d++) {
        uint c = 0;
        [[unroll]] for (uint i = 0; i < ITEMS; i++) c += dig[i] == d ? 1u : 0u;
        table[d][t] = c;
    }
    barrier();
    // Exclusive scan of each digit's row across threads (one thread per digit).
    if (t < RADIX) {
        uint running = Uints(pc.hist).v[t * pc.blocks + block];
        for (uint j = 0; j < WORKGROUP_SIZE_X; j++) {
            uint c = table[t][j];
            table[t][j] = running;
            running += c;
        }
    }
    barrier();
    [[unroll]] for (uint i = 0; i < ITEMS; i++) {
        if (dig[i] != NONE) {
            uint earlier = 0;
            [[unroll]] for (uint j = 0; j < i; j++) earlier += dig[j] == dig[i] ? 1u : 0u;
            uint dst = table[dig[i]][t] + earlier;
            Uvec2sOut(pc.keys_out).v[dst] = k[i];
            UintsOut(pc.values_out).v[dst] = VALUE(base + i);
        }
    }
}
