#version 460
// unet_conv.comp with activations stored as fp16 (read by the next layer,
// widened to fp32; accumulation and partial sums stay fp32). IN_HALF and
// OUT_HALF choose per layer: the network's input and output stay fp32.
// CPU twin: engine/src/indirect/cpu.rs `conv3x3_cpu` on fp16-rounded activations.
#define HALF_STORAGE 1
#include "unet_conv_body.glsl"
