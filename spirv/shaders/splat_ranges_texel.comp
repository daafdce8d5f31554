#version 460
// splat_ranges.comp reading the sorted keys through an RG32UI texel view
// (binding 1): used with the keys kernel's texel reads, where the pairs fit
// maxTexelBufferElements. Checked as splat_ranges.comp is.
#define TEXEL_KEYS
#include "splat_ranges_body.glsl"
