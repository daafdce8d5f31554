#version 460
// Activates stored Gaussian parameters: opacity = sigmoid(logit),
// scale = exp(log_scale), q = normalize(rot), and the world covariance
// Sigma = R S S^T R^T as (xx, xy, xz, yy, yz, zz).
// CPU twin: engine/src/scene/activate.rs `activate_cpu`.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "address.glsl"


// Keep in sync with engine/src/scene/activate.rs `ActivatePush`.
layout(push_constant) uniform ActivatePush {
    uvec2 log_scales;      // float[3N]
    uvec2 rotations;       // float[4N], w x y z, not normalized
    uvec2 opacity_logits;  // float[N]
    uvec2 covariances;     // out float[6N]
    uvec2 opacities;       // out float[N]
    uint count;
    uint pad;
} pc;

void main() {
    uint i = linear_index();
    if (i >= pc.count) return;
    FloatsIn ls = FloatsIn(pc.log_scales);
    FloatsIn rot = FloatsIn(pc.rotations);
    vec3 s = exp(vec3(ls.v[3 * i], ls.v[3 * i + 1], ls.v[3 * i + 2]));
    vec4 q = vec4(rot.v[4 * i], rot.v[4 * i + 1], rot.v[4 * i + 2], rot.v[4 * i + 3]);
    // Scale first so tiny quaternions do not underflow to a zero length.
    q /= max(max(abs(q.x), abs(q.y)), max(abs(q.z), abs(q.w)));
    q /= length(q);
    float w = q.x, x = q.y, y = q.z, z = q.w;
    // Column-major: R[c] is column c.
    mat3 R = mat3(
        1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + w * z), 2.0 * (x * z - w * y),
        2.0 * (x * y - w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z + w * x),
        2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y));
    mat3 M = R * mat3(s.x, 0.0, 0.0, 0.0, s.y, 0.0, 0.0, 0.0, s.z);
    mat3 S = M * transpose(M);
    FloatsOut cov = FloatsOut(pc.covariances);
    cov.v[6 * i + 0] = S[0][0];
    cov.v[6 * i + 1] = S[1][0];
    cov.v[6 * i + 2] = S[2][0];
    cov.v[6 * i + 3] = S[1][1];
    cov.v[6 * i + 4] = S[2][1];
    cov.v[6 * i + 5] = S[2][2];
    float logit = FloatsIn(pc.opacity_logits).v[i];
    // Stable sigmoid: never exp of a large positive number.
    float e = exp(-abs(logit));
    FloatsOut(pc.opacities).v[i] = logit >= 0.0 ? 1.0 / (1.0 + e) : e / (1.0 + e);
}
