#version 460
// splat_keys.comp reading each splat's record through an RGBA32UI texel view
// (binding 1) and the scanned tile counts through an R32UI one (binding 2)
// instead of device addresses: on lavapipe a texelFetch is one vector gather,
// a device-address load a loop over the lanes. Used where the splats and
// counts fit maxTexelBufferElements. Outputs are written by address.
#define TEXEL_SPLATS
#include "splat_keys_body.glsl"
