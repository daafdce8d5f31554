// Shared by the splat backward kernels: the backward uniform (binding 1; the
// forward frame's uniform stays at binding 0) and the per-pair record layout.
#ifndef SRUG_SPLAT_BACKWARD_GLSL
#define SRUG_SPLAT_BACKWARD_GLSL

// Which per-pixel gradients are given. Bits 0-7 as the blend's CHANNELS
// (depth, median depth, normal, albedo, roughness, metallic, ao, visibility),
// 256 rgb, 512 alpha. Keep in sync with engine/src/splat/backward.rs `BlendGrads::bits`.
layout(constant_id = 0) const uint GRADS = 0;
const bool GRAD_RGB = (GRADS & 256u) != 0u;
const bool GRAD_FEATURES = (GRADS & 252u) != 0u;
// Floats per (tile, splat) record: mean.xy, conic.abc, opacity, depth, 0;
// then rgb + 0 with rgb; then the ten features + 0, 0 with any feature.
const uint STRIDE = 8u + (GRAD_RGB ? 4u : 0u) + (GRAD_FEATURES ? 12u : 0u);
const uint MAX_STRIDE = 24u;

// Keep in sync with engine/src/splat/backward.rs `BackwardUniform` (std140: uvec4 only).
layout(std140, set = 0, binding = 1) uniform Backward {
    uvec4 in0;     // dL/d rgb, dL/d alpha
    uvec4 in1;     // dL/d depth, dL/d median depth
    uvec4 in2;     // dL/d normal, dL/d albedo
    uvec4 in3;     // dL/d roughness, dL/d metallic
    uvec4 in4;     // dL/d ao, dL/d visibility
    uvec4 pairs;   // per-(tile, splat) records, unused
    uvec4 out0;    // dL/d means, dL/d log-scales
    uvec4 out1;    // dL/d rotations, dL/d opacity logits
    uvec4 out2;    // dL/d values (16 floats per Gaussian: rgb, 0, ten features, 0, 0), unused
} bwd;

#endif
