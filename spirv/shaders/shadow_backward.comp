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
// With FILTER = 1 (PCF), V = Σ w_i σ(x_i), x_i = k·(z_i − z + bias) per
// texel: with upstream gradients dL/dx_i = dL/dV·w_i·σ'(x_i) (zero beyond the
// ±30 clamp); the BCE −(V_f·log V + (1 − V_f)·log(1 − V)) / N is taken in log
// space with 1 − V = Σ w_i σ(−x_i) and each x_i clamped to ±1e4, so
// dL/dx_i = (−V_f·r_i·σ(−x_i) + (1 − V_f)·q_i·σ(x_i)) / N with r_i = w_i σ_i / V,
// q_i = w_i σ(−x_i) / (1 − V): confidently wrong texels keep their gradient.
// The camera depth also moves the weights w_i. Each receiver records its
// footprint texels' dL/dz_i for the gather.
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
    vec3 from_camera;
    float bias;
    bool valid = receiver_point(p, from_camera, bias);
    vec3 l = valid ? light_coords(from_camera) : vec3(0.0);
    valid = valid && inside_map(l.xy);
    // A negative BCE target marks a pixel the loss ignores.
    if (LOSS != 0u) valid = valid && FloatsIn(sbw.upstream).v[p] >= 0.0;
    if (push.pass_index == 0u) {
        if (valid) atomicAdd(Uints(sbw.receiver_count).v[0], 1u);
        return;
    }
    float loss = 0.0, d_k = 0.0, d_z = 0.0, d_depth = 0.0;
    ivec2 t[4];
    vec4 w = vec4(0.0);
    uint key = sbw.counts.z;
    // Gather records: (u, v, 0, 0) and each footprint texel's dL/dz_i.
    vec4 grads = vec4(0.0);
    if (valid) {
        bilinear(l.xy, t, w);
        vec4 zt = vec4(texel_depth(t[0]), texel_depth(t[1]), texel_depth(t[2]), texel_depth(t[3]));
        float k = shadow.params.x;
        // ∂/∂(camera depth): the world point moves along R·(ray at depth 1).
        vec3 ray = camera_ray(shadow.camera, pixel_centre(p, shadow.size.x));
        vec3 dl = vec3(dot(shadow.light_rot0.xyz, ray), dot(shadow.light_rot1.xyz, ray),
                       dot(shadow.light_rot2.xyz, ray));
        vec2 duv = shadow.light_intr.xy * dl.xy;
        vec2 s = l.xy - 0.5;
        vec2 f = s - floor(s);
        if (FILTER == 1u) {
            vec4 raw = k * (zt - vec4(l.z) + vec4(bias));
            vec4 d_x = vec4(0.0);  // dL/dx_i
            vec4 h = vec4(0.0);    // dL/dw_i
            if (LOSS == 0u) {
                float g = FloatsIn(sbw.upstream).v[p];
                for (int i = 0; i < 4; i++) {
                    float xc = clamp(raw[i], -LOGIT_LIMIT, LOGIT_LIMIT);
                    float sg = stable_sigmoid(xc);
                    h[i] = g * sg;
                    if (abs(raw[i]) < LOGIT_LIMIT) d_x[i] = g * w[i] * sg * stable_sigmoid(-xc);
                }
            } else {
                // In log space: log V = log Σ w_i σ(x_i), log(1 − V) = log Σ w_i σ(−x_i),
                // x_i clamped to ±BCE_LOGIT_LIMIT; r_i = w_i σ_i / V, q_i = w_i σ̄_i / (1 − V).
                float n = float(max(Uints(sbw.receiver_count).v[0], 1u));
                float vf = FloatsIn(sbw.upstream).v[p];
                vec4 x = clamp(raw, -BCE_LOGIT_LIMIT, BCE_LOGIT_LIMIT);
                vec4 a, b;
                float ma = -3.0e38, mb = -3.0e38;
                for (int i = 0; i < 4; i++) {
                    a[i] = w[i] > 0.0 ? log(w[i]) + log_sigmoid(x[i]) : -3.0e38;
                    b[i] = w[i] > 0.0 ? log(w[i]) + log_sigmoid(-x[i]) : -3.0e38;
                    ma = max(ma, a[i]);
                    mb = max(mb, b[i]);
                }
                float sa = 0.0, sb = 0.0;
                for (int i = 0; i < 4; i++) {
                    sa += w[i] > 0.0 ? exp(a[i] - ma) : 0.0;
                    sb += w[i] > 0.0 ? exp(b[i] - mb) : 0.0;
                }
                float log_v = ma + log(sa), log_u = mb + log(sb);
                loss = -(vf * log_v + (1.0 - vf) * log_u) / n;
                for (int i = 0; i < 4; i++) {
                    float sg = stable_sigmoid(x[i]), sn = stable_sigmoid(-x[i]);
                    h[i] = -(vf * exp(log_sigmoid(x[i]) - log_v) + (1.0 - vf) * exp(log_sigmoid(-x[i]) - log_u)) / n;
                    if (w[i] > 0.0 && abs(raw[i]) < BCE_LOGIT_LIMIT) {
                        float r = exp(a[i] - log_v), q = exp(b[i] - log_u);
                        d_x[i] = (-vf * r * sn + (1.0 - vf) * q * sg) / n;
                    }
                }
            }
            grads = k * d_x;
            d_z = -(grads.x + grads.y + grads.z + grads.w);
            d_k = dot(d_x, zt - vec4(l.z) + vec4(bias));
            float dl_du = (h.y - h.x) * (1.0 - f.y) + (h.w - h.z) * f.y;
            float dl_dv = (h.z - h.x) * (1.0 - f.x) + (h.w - h.y) * f.x;
            d_depth = d_z * dl.z + dl_du * duv.x + dl_dv * duv.y;
        } else {
            float zs = dot(w, zt);
            float delta = zs - l.z + bias;
            float raw = k * delta;
            float d_logit = 0.0;
            if (LOSS == 0u) {
                if (abs(raw) < LOGIT_LIMIT) {
                    float sg = stable_sigmoid(raw);
                    d_logit = FloatsIn(sbw.upstream).v[p] * sg * (1.0 - sg);
                }
            } else {
                float n = float(max(Uints(sbw.receiver_count).v[0], 1u));
                float x = clamp(raw, -BCE_LOGIT_LIMIT, BCE_LOGIT_LIMIT);
                float vf = FloatsIn(sbw.upstream).v[p];
                loss = -(vf * log_sigmoid(x) + (1.0 - vf) * log_sigmoid(-x)) / n;
                if (abs(raw) < BCE_LOGIT_LIMIT) d_logit = (stable_sigmoid(x) - vf) / n;
            }
            float d_zs = d_logit * k;
            grads = w * d_zs;
            d_z = -d_logit * k;
            d_k = d_logit * delta;
            float dzs_du = (zt.y - zt.x) * (1.0 - f.y) + (zt.w - zt.z) * f.y;
            float dzs_dv = (zt.z - zt.x) * (1.0 - f.x) + (zt.w - zt.y) * f.x;
            d_depth = d_z * dl.z + d_zs * (dzs_du * duv.x + dzs_dv * duv.y);
        }
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
    bool passes = grads != vec4(0.0);
    Uvec2sOut(sbw.bin_keys).v[p] = uvec2(passes ? key : sbw.counts.z, 0u);
    UintsOut(sbw.bin_pixels).v[p] = p;
    Vec4s(sbw.records).v[2u * p] = vec4(l.xy, 0.0, 0.0);
    Vec4s(sbw.records).v[2u * p + 1u] = grads;
}
