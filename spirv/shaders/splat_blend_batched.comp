#version 460
// splat_blend.comp staging splats in shared-memory batches (up to 256), with the
// whole tile stopping once all its pixels are done. Same inputs, outputs and
// CPU twin. Barrier-heavy: measure it against the other variants per device.
#define SHARED_BATCHES
#include "splat_blend_body.glsl"
