// Shared helpers for every srug kernel. Include after #version.
#ifndef SRUG_COMMON_GLSL
#define SRUG_COMMON_GLSL

// 1D work is dispatched as a 2D grid so counts above 65535 workgroups fit;
// the host side is `Recording::dispatch_1d` (keep in sync).
uint linear_index() {
    return gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x;
}

#endif
