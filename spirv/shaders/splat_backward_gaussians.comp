#version 460
// Splat backward, step 2, one invocation per Gaussian: sums the Gaussian's
// (tile, splat) records in order (deterministic), then takes the gradients of
// its projected centre, conic, opacity and depth back through the EWA
// projection (dilated 2D covariance, clamped Jacobian, camera transform,
// R·S·Sᵀ·Rᵀ) to its stored mean, log-scale, quaternion and opacity logit;
// normal gradients reach the quaternion where the normal is the shortest axis;
// with surface depths the slope's gradient goes back through surface_slope.glsl
// to the shortest axis, the mean and the covariances.
// Blended-value gradients (rgb, features) are written per Gaussian as they are.
// Culled Gaussians get zeros. CPU twin: engine/src/splat/cpu_backward.rs `project_backward`.
#define WORKGROUP_SIZE_X 64
#include "common.glsl"
#include "splat.glsl"
#include "splat_backward.glsl"
#include "surface_slope.glsl"

void main() {
    uint i = linear_index();
    if (i >= frame.counts.x) return;
    Splat sp = Splats(frame.splats).v[i];
    uint first = Uints(frame.tile_counts).v[i];
    uint count = Uints(frame.tile_counts).v[i + 1u] - first;
    float sum[MAX_STRIDE];
    for (uint c = 0u; c < MAX_STRIDE; c++) sum[c] = 0.0;
    FloatsIn pairs = FloatsIn(bwd.pairs);
    for (uint k = 0u; k < count; k++) {
        for (uint c = 0u; c < STRIDE; c++) sum[c] += pairs.v[(first + k) * STRIDE + c];
    }
    vec2 d_mean2 = vec2(sum[0], sum[1]);
    vec3 d_conic = vec3(sum[2], sum[3], sum[4]);
    float d_opacity = sum[5];
    float d_depth = sum[6];
    vec3 d_normal = vec3(0.0);
    if (GRAD_FEATURES) {
        uint o = GRAD_RGB ? 12u : 8u;
        d_normal = vec3(sum[o], sum[o + 1u], sum[o + 2u]);
    }
    if ((bwd.d_values.x | bwd.d_values.y) != 0u) {
        Floats values = Floats(bwd.d_values);
        for (uint c = 0u; c < 16u; c++) values.v[16u * i + c] = 0.0;
        if (GRAD_RGB) for (uint c = 0u; c < 3u; c++) values.v[16u * i + c] = sum[8u + c];
        if (GRAD_FEATURES) {
            uint o = GRAD_RGB ? 12u : 8u;
            for (uint c = 0u; c < 10u; c++) values.v[16u * i + 4u + c] = sum[o + c];
        }
    }

    vec3 d_p = vec3(0.0), d_ls = vec3(0.0);
    vec4 d_q = vec4(0.0);
    float d_logit = 0.0;
    if (count > 0u) {
        // Recompute the forward quantities (as splat_preprocess.comp).
        FloatsIn means = FloatsIn(frame.means);
        vec3 p = vec3(means.v[3 * i], means.v[3 * i + 1], means.v[3 * i + 2]);
        mat3 W = world_to_camera_rotation(frame.camera);
        vec3 t = W * (p - frame.camera.position.xyz);
        bool ortho = frame.camera.position.w != 0.0;
        FloatsIn ls = FloatsIn(frame.log_scales);
        FloatsIn rot = FloatsIn(frame.rotations);
        vec3 s = exp(vec3(ls.v[3 * i], ls.v[3 * i + 1], ls.v[3 * i + 2]));
        vec4 q_raw = vec4(rot.v[4 * i], rot.v[4 * i + 1], rot.v[4 * i + 2], rot.v[4 * i + 3]);
        float q_scale = max(max(abs(q_raw.x), abs(q_raw.y)), max(abs(q_raw.z), abs(q_raw.w)));
        vec4 q = q_raw / q_scale;
        float q_len = length(q);
        q /= q_len;
        float qw = q.x, qx = q.y, qy = q.z, qz = q.w;
        mat3 R = mat3(
            1.0 - 2.0 * (qy * qy + qz * qz), 2.0 * (qx * qy + qw * qz), 2.0 * (qx * qz - qw * qy),
            2.0 * (qx * qy - qw * qz), 1.0 - 2.0 * (qx * qx + qz * qz), 2.0 * (qy * qz + qw * qx),
            2.0 * (qx * qz + qw * qy), 2.0 * (qy * qz - qw * qx), 1.0 - 2.0 * (qx * qx + qy * qy));
        mat3 M = R * mat3(s.x, 0.0, 0.0, 0.0, s.y, 0.0, 0.0, 0.0, s.z);
        mat3 cov_cam = W * (M * transpose(M)) * transpose(W);
        vec4 k = frame.camera.intrinsics;
        mat3 J;
        if (ortho) {
            J = mat3(k.x, 0.0, 0.0, 0.0, k.y, 0.0, 0.0, 0.0, 0.0);
        } else {
            float tx = clamp(t.x / t.z, -frame.clip.z, frame.clip.z) * t.z;
            float ty = clamp(t.y / t.z, -frame.clip.w, frame.clip.w) * t.z;
            J = mat3(k.x / t.z, 0.0, 0.0, 0.0, k.y / t.z, 0.0, -k.x * tx / (t.z * t.z), -k.y * ty / (t.z * t.z), 0.0);
        }
        vec3 conic = sp.conic.xyz;
        float opacity = sp.head.w;

        // Conic = Σ2⁻¹: dΣ2 = −C·G·C with G symmetric (b is both off-diagonals).
        mat2 C = mat2(conic.x, conic.y, conic.y, conic.z);
        mat2 G = mat2(d_conic.x, 0.5 * d_conic.y, 0.5 * d_conic.y, d_conic.z);
        mat2 d_cov2 = -(C * G * C);

        // The surface-depth slope (as the preprocess computes it): from the
        // shortest axis, the mean, 3σ along the view and the undilated JΣJᵀ.
        int axis = s.x <= s.y && s.x <= s.z ? 0 : (s.y <= s.z ? 1 : 2);
        vec3 d_n = vec3(0.0), d_t = vec3(0.0, 0.0, d_depth), d_cov_own = vec3(0.0);
        float d_extent = 0.0;
        vec2 d_slope = SURFACE_DEPTH ? vec2(sum[SLOPE_AT], sum[SLOPE_AT + 1u]) : vec2(0.0);
        if (SURFACE_DEPTH && frame.camera.lens2.x == 0.0 && (d_slope.x != 0.0 || d_slope.y != 0.0)) {
            mat3 cov2 = J * cov_cam * transpose(J);
            vec3 own = vec3(cov2[0][0], cov2[1][0], cov2[1][1]);
            float extent = 3.0 * sqrt(max(cov_cam[2][2], 0.0));
            surface_slope_backward(W * R[axis], t, k.xy, ortho, extent, own, d_slope, d_n, d_t, d_extent, d_cov_own);
            d_cov2 += mat2(d_cov_own.x, 0.5 * d_cov_own.y, 0.5 * d_cov_own.y, d_cov_own.z);
        }
        mat3 g2 = mat3(d_cov2[0][0], d_cov2[0][1], 0.0, d_cov2[1][0], d_cov2[1][1], 0.0, 0.0, 0.0, 0.0);
        mat3 d_cov_cam = transpose(J) * g2 * J;
        mat3 d_J = 2.0 * g2 * J * cov_cam;
        // extent = 3√Σc[z][z]
        if (d_extent != 0.0 && cov_cam[2][2] > 0.0) d_cov_cam[2][2] += d_extent * 1.5 / sqrt(cov_cam[2][2]);

        if (ortho) {
            d_t.xy += d_mean2 * k.xy;
        } else {
            float z2 = t.z * t.z;
            d_t.x += d_mean2.x * k.x / t.z;
            d_t.y += d_mean2.y * k.y / t.z;
            d_t.z -= d_mean2.x * k.x * t.x / z2 + d_mean2.y * k.y * t.y / z2;
            d_t.z += d_J[0][0] * (-k.x / z2) + d_J[1][1] * (-k.y / z2);
            // J[2][row] = −f·tc/z² inside the limit, −f·(±lim)/z beyond it.
            for (int row = 0; row < 2; row++) {
                float f = row == 0 ? k.x : k.y;
                float lim = row == 0 ? frame.clip.z : frame.clip.w;
                float tc = row == 0 ? t.x : t.y;
                float dj = d_J[2][row];
                float ratio = tc / t.z;
                if (abs(ratio) <= lim) {
                    d_t[row] += dj * (-f / z2);
                    d_t.z += dj * (2.0 * f * tc / (z2 * t.z));
                } else {
                    d_t.z += dj * (f * sign(ratio) * lim / z2);
                }
            }
        }

        // Σw = M Mᵀ, M = R·S, Σc = W Σw Wᵀ.
        mat3 d_cov_world = transpose(W) * d_cov_cam * W;
        mat3 d_M = (d_cov_world + transpose(d_cov_world)) * M;
        mat3 d_R = mat3(d_M[0] * s.x, d_M[1] * s.y, d_M[2] * s.z);
        // The slope's normal n = W·R[axis].
        d_R[axis] += transpose(W) * d_n;
        d_ls = vec3(dot(R[0], d_M[0]), dot(R[1], d_M[1]), dot(R[2], d_M[2])) * s;

        // Shortest-axis normal turned toward the camera (when it is the normal used).
        bool stored = frame.counts.z == 1u && (frame.normals.x | frame.normals.y) != 0u;
        if (stored) {
            FloatsIn nb = FloatsIn(frame.normals);
            stored = dot(vec3(nb.v[3 * i], nb.v[3 * i + 1], nb.v[3 * i + 2]),
                         vec3(nb.v[3 * i], nb.v[3 * i + 1], nb.v[3 * i + 2])) != 0.0;
        }
        if (GRAD_FEATURES && !stored) {
            vec3 toward = ortho ? -frame.view_dir.xyz : frame.eye.xyz - p;
            d_R[axis] += (dot(R[axis], toward) < 0.0 ? -1.0 : 1.0) * d_normal;
        }

        // Quaternion (w, x, y, z): ∂R/∂q̂, then through q̂ = q/|q|.
        vec4 dqn = vec4(0.0);
        dqn += d_R[0][0] * vec4(0.0, 0.0, -4.0 * qy, -4.0 * qz);
        dqn += d_R[0][1] * vec4(2.0 * qz, 2.0 * qy, 2.0 * qx, 2.0 * qw);
        dqn += d_R[0][2] * vec4(-2.0 * qy, 2.0 * qz, -2.0 * qw, 2.0 * qx);
        dqn += d_R[1][0] * vec4(-2.0 * qz, 2.0 * qy, 2.0 * qx, -2.0 * qw);
        dqn += d_R[1][1] * vec4(0.0, -4.0 * qx, 0.0, -4.0 * qz);
        dqn += d_R[1][2] * vec4(2.0 * qx, 2.0 * qw, 2.0 * qz, 2.0 * qy);
        dqn += d_R[2][0] * vec4(2.0 * qy, 2.0 * qz, 2.0 * qw, 2.0 * qx);
        dqn += d_R[2][1] * vec4(-2.0 * qx, -2.0 * qw, 2.0 * qz, 2.0 * qy);
        dqn += d_R[2][2] * vec4(0.0, -4.0 * qx, -4.0 * qy, 0.0);
        d_q = (dqn - q * dot(q, dqn)) / (q_len * q_scale);

        d_p = transpose(W) * d_t;
        d_logit = d_opacity * opacity * (1.0 - opacity);
    }
    Floats dm = Floats(bwd.d_means), dls = Floats(bwd.d_log_scales), dr = Floats(bwd.d_rotations);
    for (uint c = 0u; c < 3u; c++) {
        dm.v[3u * i + c] = d_p[c];
        dls.v[3u * i + c] = d_ls[c];
    }
    for (uint c = 0u; c < 4u; c++) dr.v[4u * i + c] = d_q[c];
    Floats(bwd.d_opacity_logits).v[i] = d_logit;
}
