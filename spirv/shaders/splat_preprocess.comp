#version 460
// Splatting stage 1, one invocation per Gaussian (body: splat_preprocess_body.glsl),
// reading the scene by device address. CPU twin: engine/src/splat/cpu.rs `preprocess_one`.
#include "splat_preprocess_body.glsl"
