// Shared by the shadow backward kernels: their uniform (binding 1; the
// forward's Shadow uniform stays at binding 0).
#ifndef SRUG_SHADOW_BACKWARD_GLSL
#define SRUG_SHADOW_BACKWARD_GLSL

// Keep in sync with engine/src/shadow/backward.rs `ShadowBackwardUniform` (std140: uvec4 only).
layout(std140, set = 0, binding = 1) uniform ShadowBackward {
    uvec4 b0;      // dL/dV in (or the BCE target V_f), per-pixel loss out
    uvec4 b1;      // per-pixel dL/dk out, dL/dz (light depth) out
    uvec4 b2;      // dL/d receiver depth channel out (Σwz or median), dL/d receiver alpha out
    uvec4 b3;      // bin keys (uvec2) out, bin values (pixel) out
    uvec4 b4;      // per-pixel (u, v, dL/dz_s, 0) out, per-texel bin ranges
    uvec4 b5;      // dL/dz_s per texel out, dL/d map depth channel out (Σwz or median)
    uvec4 b6;      // dL/d map alpha out, receiver count (uint)
    uvec4 counts;  // pixels, texels, bin key of "no texel", pairs (sorted)
} sbw;

layout(buffer_reference, std430, buffer_reference_align = 16) buffer Vec4s { vec4 v[]; };

#endif
