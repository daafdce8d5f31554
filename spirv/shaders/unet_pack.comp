#version 460
// The indirect network's input from the deferred buffers, one invocation per
// pixel: CHW channels normal (normalised), albedo, roughness, metallic (each
// alpha-normalised and clamped as the shading reads them), L_sun, L_sky.
// Pixels without a surface get zeros. CPU twin: engine/src/indirect/cpu.rs `pack_cpu`.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "address.glsl"

// Keep in sync with engine/src/indirect/mod.rs `PackPush`.
layout(push_constant) uniform PackPush {
    uvec2 normal;     // Σw·n, 3 per pixel
    uvec2 albedo;     // Σw·a, 3 per pixel
    uvec2 roughness;  // Σw·r (0: 1)
    uvec2 metallic;   // Σw·m (0: 0)
    uvec2 alpha;
    uvec2 sun;        // L_sun, 3 per pixel
    uvec2 sky;        // L_sky, 3 per pixel
    uvec2 o;          // 14 × pixels
    uint pixels;
    float min_alpha;
} pc;

void main() {
    uint p = linear_index();
    if (p >= pc.pixels) return;
    float v[14];
    for (uint c = 0u; c < 14u; ++c) v[c] = 0.0;
    float a = FloatsIn(pc.alpha).v[p];
    if (a >= pc.min_alpha) {
        float ia = 1.0 / a;
        FloatsIn n = FloatsIn(pc.normal), al = FloatsIn(pc.albedo), sun = FloatsIn(pc.sun), sky = FloatsIn(pc.sky);
        vec3 nv = vec3(n.v[3u * p], n.v[3u * p + 1u], n.v[3u * p + 2u]);
        float len = length(nv);
        nv = len > 1e-12 ? nv / len : vec3(0.0);
        v[0] = nv.x; v[1] = nv.y; v[2] = nv.z;
        for (uint c = 0u; c < 3u; ++c) v[3u + c] = clamp(al.v[3u * p + c] * ia, 0.0, 1.0);
        v[6] = pc.roughness != uvec2(0u) ? clamp(FloatsIn(pc.roughness).v[p] * ia, 0.0, 1.0) : 1.0;
        v[7] = pc.metallic != uvec2(0u) ? clamp(FloatsIn(pc.metallic).v[p] * ia, 0.0, 1.0) : 0.0;
        for (uint c = 0u; c < 3u; ++c) {
            v[8u + c] = sun.v[3u * p + c];
            v[11u + c] = sky.v[3u * p + c];
        }
    }
    FloatsOut o = FloatsOut(pc.o);
    for (uint c = 0u; c < 14u; ++c) o.v[c * pc.pixels + p] = v[c];
}
