#version 460
// U-Net layer: 3×3 convolution, padding 1, stride STRIDE, fused bias and
// activation, over the channel concatenation of two CHW tensors A and B
// (B may be empty), so a skip connection needs no copy. One invocation per
// PX output pixels along x and block of OCB output channels; the block is
// the workgroup's y index, so its weights are dynamically uniform.
//
// Weights come through uniform buffers: lavapipe loads a uniform-buffer
// element with a uniform index once per SIMD group, but gathers storage and
// device-address loads lane by lane (6× slower here). A uniform buffer holds
// 64 KiB, so a layer runs in passes over chunks of its input channels
// [ic0, ic1): the first pass starts from the bias, later ones from the
// partial sums so far, the last applies the activation. Weights are packed
// host-side per pass as [oc/OCB][ic - ic0][3·3][OCB]. fp32 accumulation.
// Pixel blocks of 64 run along x, wrapping into z beyond the dispatch limit.
// Partial sums between passes stay fp32 in a scratch tensor. This file keeps
// activations in fp32; unet_conv_half.comp in fp16 (16-bit storage, a device
// feature, so a separate module rather than a specialization).
// CPU twin: engine/src/indirect/cpu.rs `conv3x3_cpu`.
#include "unet_conv_body.glsl"
