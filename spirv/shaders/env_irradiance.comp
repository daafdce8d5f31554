#version 460
// Diffuse irradiance E(n) = ∫ L(ω) max(n·ω, 0) dω, one invocation per output
// texel, summed over every texel of a small pyramid level with its exact
// solid angle; normalised by the discrete ∫ max(n·ω, 0) dω so a uniform
// environment L gives exactly πL. CPU twin: engine/src/shade/cpu.rs `irradiance_cpu`.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "latlong.glsl"

// Keep in sync with engine/src/shade/env.rs `IrradiancePush`.
layout(push_constant) uniform DownsamplePush {
    uvec2 src;       // source level
    uvec2 dst;       // irradiance map
    uvec2 src_size;
    uvec2 dst_size;
} push;

void main() {
    uint i = linear_index();
    if (i >= push.dst_size.x * push.dst_size.y) return;
    vec3 n = latlong_direction(uvec2(i % push.dst_size.x, i / push.dst_size.x), push.dst_size);
    vec3 sum = vec3(0.0);
    float weight = 0.0;
    float dphi = 2.0 * PI / float(push.src_size.x);
    for (uint y = 0u; y < push.src_size.y; ++y) {
        float top = (0.5 - float(y) / float(push.src_size.y)) * PI;
        float bottom = (0.5 - float(y + 1u) / float(push.src_size.y)) * PI;
        float solid_angle = dphi * (sin(top) - sin(bottom));
        for (uint x = 0u; x < push.src_size.x; ++x) {
            vec3 w = latlong_direction(uvec2(x, y), push.src_size);
            float c = max(dot(n, w), 0.0) * solid_angle;
            if (c == 0.0) continue;
            sum += c * latlong_texel(push.src, 0u, push.src_size, int(x), int(y));
            weight += c;
        }
    }
    vec3 e = weight > 0.0 ? sum * (PI / weight) : vec3(0.0);
    FloatsOut o = FloatsOut(push.dst);
    o.v[3u * i] = e.x;
    o.v[3u * i + 1u] = e.y;
    o.v[3u * i + 2u] = e.z;
}
