// Shared by the shadow backward kernels: their uniform (binding 1; the
// forward's Shadow uniform stays at binding 0).
#ifndef SRUG_SHADOW_BACKWARD_GLSL
#define SRUG_SHADOW_BACKWARD_GLSL

// Host mirror: engine/src/shadow/backward.rs `ShadowBackwardUniform` (its layout is checked against this block).
layout(std140, set = 0, binding = 1) uniform ShadowBackward {
    uvec2 upstream;          // dL/dV in (or the BCE target V_f)
    uvec2 loss;              // per-pixel loss out
    uvec2 dk;                // per-pixel dL/dk out
    uvec2 light_depth;       // dL/dz (light depth) out
    uvec2 d_receiver_depth;  // dL/d receiver depth channel out (Σwz or median)
    uvec2 d_receiver_alpha;  // dL/d receiver alpha out
    uvec2 bin_keys;          // bin keys (uvec2) out
    uvec2 bin_pixels;        // bin values (pixel) out
    uvec2 records;           // per pixel two vec4: (u, v, 0, 0), its footprint texels' dL/dz out
    uvec2 bin_ranges;        // per-texel bin ranges
    uvec2 texel_depth;       // dL/dz_s per texel out
    uvec2 d_map_depth;       // dL/d map depth channel out (Σwz or median)
    uvec2 d_map_alpha;       // dL/d map alpha out
    uvec2 receiver_count;    // uint
    uvec4 counts;  // pixels, texels, bin key of "no texel", pairs (sorted)
} sbw;

layout(buffer_reference, std430, buffer_reference_align = 16) buffer Vec4s { vec4 v[]; };

#endif
