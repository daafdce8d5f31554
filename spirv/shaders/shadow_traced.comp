#version 460
// The traced reference visibility, one invocation per receiver pixel:
// V_t = Π(1 − αᵢ) over the splats of the light-space splat that lie between
// the receiver and the sun. Sun rays are parallel, so the receiver's ray is a
// light-space pixel: it walks that pixel's tile list front to back (nearest
// the sun first) and stops at the first splat at or behind z − bias. α and
// its cut-offs are the blend's (min(0.99, o·G), skip α < 1/255); V_t is 0
// once T falls below 1e-4. Outside the map, or without a surface, V_t = 1.
// CPU twin: engine/src/shadow/cpu.rs `traced_visibility_cpu`.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "shadow.glsl"
#include "splat_types.glsl"

void main() {
    uint p = linear_index();
    if (p >= shadow.size.x * shadow.size.y) return;
    float T = 1.0;
    vec3 from_camera;
    float bias;
    if (receiver_point(p, from_camera, bias)) {
        vec3 l = light_coords(from_camera);
        if (inside_map(l.xy)) {
            uvec2 tile = uvec2(l.xy) / shadow.modes.w;  // the map's tile edge
            uvec2 range = Uvec2s(shadow.ranges).v[tile.y * shadow.modes.z + tile.x];
            Splats splats = Splats(shadow.splats);
            Uints order = Uints(shadow.sorted_gaussians);
            vec2 centre = l.xy;  // the ray itself, not its texel centre
            float limit = l.z - bias;
            for (uint j = range.x; j < range.y; j++) {
                uint g = order.v[j];
                vec4 head = splats.v[g].head;
                if (head.z >= limit) break;
                float alpha, gauss;
                vec2 d;
                if (!splat_alpha(head, splats.v[g].conic, centre, alpha, gauss, d)) continue;
                T *= 1.0 - alpha;
                if (T < 1e-4) { T = 0.0; break; }
            }
        }
    }
    FloatsOut(shadow.visibility).v[p] = T;
}
