#version 460
// splat_preprocess.comp reading the Gaussians' means, log-scales, rotations,
// opacity logits and SH coefficients through R32F texel-buffer views
// (bindings 1-5) instead of device addresses: on lavapipe a texelFetch is one
// vector gather, a device-address load a loop over the lanes. Used where the
// arrays fit maxTexelBufferElements. CPU twin: engine/src/splat/cpu.rs `preprocess_one`.
#define TEXEL_INPUTS
#include "splat_preprocess_body.glsl"
