#version 460
// The sigmoid shadow test, one invocation per receiver pixel: the world point
// from the camera G-buffer's depth, projected into light space; z_s sampled
// bilinearly from the shadow map; V_e = σ(k·(z_s − z + bias)) in fp32 with
// the logit clamped; with FILTER = 1 (PCF) V_e = Σ w_i·σ(k·(z_i − z + bias))
// over the four texels instead. Points outside the map and pixels without a
// surface are lit.
// CPU twin: engine/src/shadow/cpu.rs `sigmoid_visibility_cpu`.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "shadow.glsl"

void main() {
    uint p = linear_index();
    if (p >= shadow.size.x * shadow.size.y) return;
    float v = 1.0;
    vec3 from_camera;
    float bias;
    if (receiver_point(p, from_camera, bias)) {
        vec3 l = light_coords(from_camera);
        if (inside_map(l.xy)) {
            ivec2 t[4];
            vec4 w;
            bilinear(l.xy, t, w);
            if (FILTER == 1u) {
                v = w.x * stable_sigmoid(shadow_logit(texel_depth(t[0]), l.z, bias))
                  + w.y * stable_sigmoid(shadow_logit(texel_depth(t[1]), l.z, bias))
                  + w.z * stable_sigmoid(shadow_logit(texel_depth(t[2]), l.z, bias))
                  + w.w * stable_sigmoid(shadow_logit(texel_depth(t[3]), l.z, bias));
            } else {
                float zs = w.x * texel_depth(t[0]) + w.y * texel_depth(t[1]) + w.z * texel_depth(t[2])
                         + w.w * texel_depth(t[3]);
                v = stable_sigmoid(shadow_logit(zs, l.z, bias));
            }
        }
    }
    FloatsOut(shadow.visibility).v[p] = v;
}
