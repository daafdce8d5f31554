#version 460
// U-Net: bilinear resize of a CHW tensor to the skip's exact size, PyTorch's
// F.interpolate(mode="bilinear") with either align_corners convention.
// One invocation per output value. CPU twin: engine/src/indirect/cpu.rs `upsample_cpu`.
#include "unet_upsample_body.glsl"
