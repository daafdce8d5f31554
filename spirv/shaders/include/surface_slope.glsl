// The surface-depth slope and its backward, shared by the preprocess (which
// stores the slope) and the backward's projection kernel (which takes its
// gradient back to the Gaussian). CPU twin: engine/src/splat/cpu.rs
// `SlopeInputs` (`slope`, `backward`).
#ifndef SRUG_SURFACE_SLOPE_GLSL
#define SRUG_SURFACE_SLOPE_GLSL

// The plane through the splat's camera-space mean t with normal n (its
// shortest axis) seen from pixel offsets Δ from the mean: pinhole cameras,
// the relative inverse depth per pixel s (1/z = (1/z₀)(1 + s·Δ)); orthographic,
// the depth per pixel (z = z₀ + s·Δ). k.xy: pixels per unit (focal, or scale).
// Limited so that over the splat's own 3σ footprint (`cov`: JΣJᵀ, before the
// dilation) the depth moves at most 1.5× its 3σ extent along the view
// (`extent`; a flat splat's plane stays within it by itself) and, pinhole,
// over the dilated footprint (`cov` + 0.3) at most half of z₀.

// The slope before the limit; `guarded`: n·t (pinhole) or n.z (orthographic)
// kept at least 1e-6 (× z) from zero.
vec2 slope_unlimited(vec3 n, vec3 t, vec2 k, bool ortho, out float guarded) {
    if (ortho) {
        guarded = abs(n.z) < 1e-6 ? (n.z < 0.0 ? -1e-6 : 1e-6) : n.z;
        return -n.xy / (guarded * k);
    }
    float nt = dot(n, t);
    guarded = abs(nt) < 1e-6 * t.z ? (nt < 0.0 ? -1e-6 : 1e-6) * t.z : nt;
    return n.xy * (t.z / guarded) / k;
}

// 3·√(sᵀ(C + da·I)s): the largest s·Δ over the ellipse ΔᵀC⁻¹Δ ≤ 9.
float slope_spread(vec2 s, vec3 cov, float da) {
    return 3.0 * sqrt(max(s.x * s.x * (cov.x + da) + 2.0 * s.x * s.y * cov.y + s.y * s.y * (cov.z + da), 0.0));
}

// The limit's terms (1, the extent's, the dilated footprint's); the smallest binds.
vec3 slope_limits(vec2 s, vec3 t, bool ortho, float extent, vec3 cov) {
    float own = slope_spread(s, cov, 0.0);
    if (ortho) return vec3(1.0, 1.5 * extent / own, 1.0 / 0.0);
    return vec3(1.0, 1.5 * extent / (t.z * own), 0.5 / slope_spread(s, cov, 0.3));
}

bool slope_finite(vec2 s) { return !any(isnan(s)) && !any(isinf(s)); }

// The limited slope (zero where it is not finite).
vec2 surface_slope(vec3 n, vec3 t, vec2 k, bool ortho, float extent, vec3 cov) {
    float guarded;
    vec2 s = slope_unlimited(n, t, k, ortho, guarded);
    vec3 l = slope_limits(s, t, ortho, extent, cov);
    vec2 slope = s * min(min(l.x, l.y), l.z);
    return slope_finite(slope) ? slope : vec2(0.0);
}

// Backward of `surface_slope`: `d` is dL/d slope; adds dL/d n, t, extent and
// cov (a, b, c of the undilated 2D covariance). The binding term of the limit
// is differentiated (a tie takes the first), the guards pass no gradient to n,
// and a slope that was not finite none at all.
void surface_slope_backward(vec3 n, vec3 t, vec2 k, bool ortho, float extent, vec3 cov, vec2 d,
                            inout vec3 d_n, inout vec3 d_t, inout float d_extent, inout vec3 d_cov) {
    float guarded;
    vec2 s = slope_unlimited(n, t, k, ortho, guarded);
    vec3 l = slope_limits(s, t, ortho, extent, cov);
    int which = 0;
    float scale = l.x;
    if (l.y < scale) { which = 1; scale = l.y; }
    if (l.z < scale) { which = 2; scale = l.z; }
    if (!slope_finite(s * scale)) return;
    vec2 ds = d * scale;
    float d_scale = dot(d, s);
    if (which != 0) {
        // spread(s, da) = 3√q: dq/ds = 2(C + da·I)s, dq/d(a, b, c) = (sx², 2·sx·sy, sy²).
        float da = which == 1 ? 0.0 : 0.3;
        float spread = slope_spread(s, cov, da);
        if (which == 1) {
            d_extent += d_scale * scale / extent;
            if (!ortho) d_t.z -= d_scale * scale / t.z;
        }
        if (spread > 0.0) {
            float dq = -d_scale * scale / spread * 4.5 / spread;
            ds += dq * 2.0 * vec2(s.x * (cov.x + da) + s.y * cov.y, s.x * cov.y + s.y * (cov.z + da));
            d_cov += dq * vec3(s.x * s.x, 2.0 * s.x * s.y, s.y * s.y);
        }
    }
    if (ortho) {
        // s = −n.xy / (nz·k)
        d_n.xy -= ds / (guarded * k);
        if (abs(n.z) >= 1e-6) d_n.z += dot(ds, n.xy / k) / (guarded * guarded);
    } else {
        // s = n.xy·r / k, r = z / (n·t)
        float r = t.z / guarded;
        d_n.xy += ds * r / k;
        float dr = dot(ds, n.xy / k);
        if (abs(dot(n, t)) >= 1e-6 * t.z) {
            d_t.z += dr / guarded;
            float d_nt = -dr * t.z / (guarded * guarded);
            d_n += d_nt * t;
            d_t += d_nt * n;
        }
    }
}

#endif
