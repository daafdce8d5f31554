// Shared helpers for every srug kernel. Include after #version and after
// `#define WORKGROUP_SIZE_X n`; common.glsl declares the local size from it.
// (gl_WorkGroupSize read before the layout declaration is (1,1,1) in GLSL,
// which once silently broke 2D grids; a macro cannot be read too early.)
#ifndef SRUG_COMMON_GLSL
#define SRUG_COMMON_GLSL

#ifndef WORKGROUP_SIZE_X
#error "define WORKGROUP_SIZE_X before including common.glsl"
#endif
layout(local_size_x = WORKGROUP_SIZE_X) in;

// 1D work is dispatched as a 2D grid so counts above 65535 workgroups fit;
// the host side is `Recording::dispatch_1d` (keep in sync).
uint linear_index() {
    return gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * WORKGROUP_SIZE_X;
}

// Workgroup index in a 2D grid of workgroups (see linear_index).
uint block_index() {
    return gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x;
}

#endif
