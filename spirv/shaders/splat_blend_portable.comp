#version 460
// splat_blend.comp without subgroup operations, for devices whose compute
// stage lacks subgroup ballot. Same inputs, outputs and CPU twin.
#include "splat_blend_body.glsl"
