#version 460
// The sigmoid shadow test's backward, one invocation per receiver pixel.
// x = k·(z_s − z + bias). With upstream gradients (LOSS = 0), dL/dx =
// dL/dV·σ'(x), zero beyond the ±30 clamp where V is constant. With the
// paper's visibility loss (LOSS = 1), L = mean BCE(σ(x), V_f) over receivers
// with a surface inside the map and V_f ≥ 0 (a negative V_f marks a pixel out), in log-sigmoid form on x clamped to ±1e4,
// and dL/dx = (σ(x) − V_f)/N. Then dL/dz_s = k·dL/dx (spread over the four
// bilinear texels by the gather kernel), dL/dz = −k·dL/dx, dL/dk = (z_s − z +
// bias)·dL/dx, and the receiver's camera depth gets dL/dz·∂z/∂depth plus
// dL/dz_s·∂z_s/∂uv·∂uv/∂depth (its world point slides along the pixel ray).
// A slope bias and normal offset depend only on the receiver's normal, which
// is held fixed (no gradient flows to the normals): the world point's
// derivative along the pixel ray is unchanged.
// PASS 0 only counts the receivers (N); PASS 1 does the rest.
// CPU twin: engine/src/shadow/cpu.rs `sigmoid_backward_cpu`.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "shadow.glsl"
#include "shadow_backward.glsl"

layout(constant_id = 0) const uint LOSS = 0;
layout(push_constant) uniform Push { uint pass_index; } push;
const float BCE_LOGIT_LIMIT = 1e4;

// log σ(x) = −(max(−x, 0) + log(1 + exp(−|x|))).
float log_sigmoid(float x) {
    float e = exp(-abs(x));
    // log(1 + e) for e ≤ 1, accurate for tiny e.
    float l = e < 1e-4 ? e - 0.5 * e * e : log(1.0 + e);
    return -(max(-x, 0.0) + l);
}

void main() {
    uint p = linear_index();
    if (p >= sbw.counts.x) return;
    vec3 world;
    float bias;
    bool valid = receiver_point(p, world, bias);
    vec3 l = valid ? light_coords(world) : vec3(0.0);
    valid = valid && inside_map(l.xy);
    // A negative BCE target marks a pixel the loss ignores.
    if (LOSS != 0u) valid = valid && FloatsIn(sbw.upstream).v[p] >= 0.0;
    if (push.pass_index == 0u) {
        if (valid) atomicAdd(Uints(sbw.receiver_count).v[0], 1u);
        return;
    }
    float loss = 0.0, d_k = 0.0, d_z = 0.0, d_zs = 0.0, d_depth = 0.0;
    ivec2 t[4];
    vec4 w = vec4(0.0);
    uint key = sbw.counts.z;
    if (valid) {
        bilinear(l.xy, t, w);
        vec4 zt = vec4(texel_depth(t[0]), texel_depth(t[1]), texel_depth(t[2]), texel_depth(t[3]));
        float zs = dot(w, zt);
        float delta = zs - l.z + bias;
        float raw = shadow.params.x * delta;
        float d_logit = 0.0;
        if (LOSS == 0u) {
            if (abs(raw) < LOGIT_LIMIT) {
                float s = stable_sigmoid(raw);
                d_logit = FloatsIn(sbw.upstream).v[p] * s * (1.0 - s);
            }
        } else {
            float n = float(max(Uints(sbw.receiver_count).v[0], 1u));
            float x = clamp(raw, -BCE_LOGIT_LIMIT, BCE_LOGIT_LIMIT);
            float vf = FloatsIn(sbw.upstream).v[p];
            loss = -(vf * log_sigmoid(x) + (1.0 - vf) * log_sigmoid(-x)) / n;
            if (abs(raw) < BCE_LOGIT_LIMIT) d_logit = (stable_sigmoid(x) - vf) / n;
        }
        float k = shadow.params.x;
        d_zs = d_logit * k;
        d_z = -d_logit * k;
        d_k = d_logit * delta;
        // ∂/∂(camera depth): the world point moves along R·(ray at depth 1).
        vec3 ray = camera_ray(shadow.camera, pixel_centre(p, shadow.size.x));
        vec3 dl = vec3(dot(shadow.light_rot0.xyz, ray), dot(shadow.light_rot1.xyz, ray),
                       dot(shadow.light_rot2.xyz, ray));
        vec2 duv = shadow.light_intr.xy * dl.xy;
        vec2 s = l.xy - 0.5;
        vec2 f = s - floor(s);
        float dzs_du = (zt.y - zt.x) * (1.0 - f.y) + (zt.w - zt.z) * f.y;
        float dzs_dv = (zt.z - zt.x) * (1.0 - f.x) + (zt.w - zt.y) * f.x;
        d_depth = d_z * dl.z + d_zs * (dzs_du * duv.x + dzs_dv * duv.y);
        key = uint(t[0].y) * shadow.size.z + uint(t[0].x);
    }
    if (LOSS != 0u) FloatsOut(sbw.loss).v[p] = loss;
    FloatsOut(sbw.dk).v[p] = d_k;
    FloatsOut(sbw.light_depth).v[p] = d_z;
    // Receiver G-buffer: median depth directly, or z = Σwz / alpha.
    float g_depth = 0.0, g_alpha = 0.0;
    if (valid) {
        if (shadow.modes.y == 1u) {
            g_depth = d_depth;
        } else {
            float a = FloatsIn(shadow.receiver_alpha).v[p];
            g_depth = d_depth / a;
            g_alpha = -d_depth * FloatsIn(shadow.receiver_depth).v[p] / (a * a);
        }
    }
    FloatsOut(sbw.d_receiver_depth).v[p] = g_depth;
    if (shadow.modes.y == 0u) FloatsOut(sbw.d_receiver_alpha).v[p] = g_alpha;
    // Bin by the footprint's first texel for the deterministic gather.
    Uvec2sOut(sbw.bin_keys).v[p] = uvec2(d_zs != 0.0 ? key : sbw.counts.z, 0u);
    UintsOut(sbw.bin_pixels).v[p] = p;
    Vec4s(sbw.records).v[p] = vec4(l.xy, d_zs, 0.0);
}
