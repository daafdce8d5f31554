#version 460
// Cascaded shadow maps, one invocation per receiver pixel: the visibility of
// the cascade whose slice of the view holds the receiver's camera depth z;
// over the last part of a slice (from its blend start to its far end) a
// linear ramp hands over to the next cascade, so no seam shows where the
// texel size changes. Beyond the last slice, and where there is no surface,
// a cascade's own V stands (the last one's, the first one's: 1).
// CPU twin: engine/src/shadow/cascades.rs `blend_cascades_cpu`.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "shadow.glsl"

// Host mirror: engine/src/shadow/cascades.rs `CascadePush` (its layout is checked against this block).
layout(push_constant) uniform CascadePush {
    uvec4 visibility01;   // cascades 0 and 1: V per pixel, by device address (low, high)
    uvec4 visibility23;   // cascades 2 and 3
    uvec2 blended;        // out
    uint count;           // cascades, 1 to 4
    uint pixels;
    vec4 far;             // each slice's far end, camera z
    vec4 blend_start;     // where each hands over to the next
} push;

float cascade_visibility(uint c, uint p) {
    uvec2 a = c == 0u ? push.visibility01.xy
            : c == 1u ? push.visibility01.zw
            : c == 2u ? push.visibility23.xy : push.visibility23.zw;
    return FloatsIn(a).v[p];
}

void main() {
    uint p = linear_index();
    if (p >= push.pixels) return;
    float v = cascade_visibility(0u, p);
    float z;
    if (resolve_depth(shadow.modes.y, shadow.receiver_depth, shadow.receiver_alpha, p, z)) {
        uint last = push.count - 1u;
        uint c = 0u;
        while (c < last && z > push.far[c]) c++;
        v = cascade_visibility(c, p);
        if (c < last && z > push.blend_start[c]) {
            float t = (z - push.blend_start[c]) / (push.far[c] - push.blend_start[c]);
            v = mix(v, cascade_visibility(c + 1u, p), t);
        }
    }
    FloatsOut(push.blended).v[p] = v;
}
