// The camera as every uniform block carries it, and the pixel/ray maths on it.
// Host mirror: engine/src/camera.rs `CameraToWorldBlock` and
// `WorldToCameraBlock` (packed once by `Camera::packed`; each block that
// embeds one is checked member by member against the host struct).
// Pixel centres sit at +0.5 (docs/conventions.md).
#ifndef SRUG_CAMERA_GLSL
#define SRUG_CAMERA_GLSL

// For unprojecting pixels: camera-to-world rotation and the camera centre.
struct CameraToWorld {
    vec4 rot0;        // camera-to-world rotation, rows
    vec4 rot1;
    vec4 rot2;
    vec4 position;    // camera centre; w: 0 pinhole, 1 orthographic
    vec4 intrinsics;  // fx, fy, cx, cy (orthographic: pixels per unit x, y, cx, cy)
    vec4 lens0;       // as WorldToCamera's
    vec4 lens1;
    vec4 lens2;
    vec4 lens3;
};

// For projecting points: world-to-camera rotation and the camera's position
// (a point goes to rotation · (point − position), never rotation · point +
// translation, whose two large terms cancel for a scene far from the origin).
struct WorldToCamera {
    vec4 rot0;         // world-to-camera rotation, rows
    vec4 rot1;
    vec4 rot2;
    vec4 position;     // the camera's position in the world; w: 0 pinhole, 1 orthographic
    vec4 intrinsics;   // fx, fy, cx, cy (orthographic: pixels per unit x, y, cx, cy)
    vec4 lens0;        // k1..k4 (radial-tangential and fisheye)
    vec4 lens1;        // k5, k6, p1, p2 (radial-tangential)
    vec4 lens2;        // x: 0 pinhole, 2 radial-tangential, 3 fisheye, 4 FOV (lens0.x: ω),
                       // 5 EUCM (lens0.xy: α, β), 6 division (lens0.x: k), 7 thin-prism
                       // fisheye (lens0: k1..k4, lens1: p1, p2, sx1, sy1), 8 rad-tan thin-prism
                       // fisheye (lens0: k0..k3, lens1: k4, k5, p0, p1, lens3: s0..s3),
                       // 9 equirectangular (no coefficients; depth is the distance);
                       // y: imaging limit (undistorted radius, or fisheye angle off axis)
    vec4 lens3;
};

// THIN_PRISM_FISHEYE's distortion of equidistant coordinates q and its
// Jacobian T (T[c][r] = ∂d_r/∂q_c).
vec2 thin_prism(vec2 q, vec4 k, vec4 ps, out mat2 T) {
    float u = q.x, v = q.y;
    float r2 = u * u + v * v;
    float radial = r2 * (k.x + r2 * (k.y + r2 * (k.z + r2 * k.w)));
    float dr = k.x + r2 * (2.0 * k.y + r2 * (3.0 * k.z + r2 * 4.0 * k.w));
    float p1 = ps.x, p2 = ps.y, s1 = ps.z, s2 = ps.w;
    T[0][0] = 1.0 + radial + 2.0 * u * u * dr + 2.0 * p1 * v + 6.0 * p2 * u + 2.0 * s1 * u;
    T[1][0] = 2.0 * u * v * dr + 2.0 * p1 * u + 2.0 * p2 * v + 2.0 * s1 * v;
    T[0][1] = 2.0 * u * v * dr + 2.0 * p2 * v + 2.0 * p1 * u + 2.0 * s2 * u;
    T[1][1] = 1.0 + radial + 2.0 * v * v * dr + 2.0 * p2 * u + 6.0 * p1 * v + 2.0 * s2 * v;
    return vec2(u + u * radial + 2.0 * p1 * u * v + p2 * (r2 + 2.0 * u * u) + s1 * r2,
                v + v * radial + 2.0 * p2 * u * v + p1 * (r2 + 2.0 * v * v) + s2 * r2);
}

// The Jacobian (M[c][r]) of (u, v) ↦ (u, v)·g(u² + v²), given g and dg/d(r²).
mat2 radial_jacobian(float u, float v, float g, float dg) {
    return mat2(g + 2.0 * u * u * dg, 2.0 * u * v * dg, 2.0 * u * v * dg, g + 2.0 * v * v * dg);
}

// RAD_TAN_THIN_PRISM_FISHEYE's tangential and thin-prism terms on q and their Jacobian.
vec2 rad_tan_thin_prism(vec2 q, vec2 p, vec4 s, out mat2 T) {
    float u = q.x, v = q.y;
    float r2 = u * u + v * v;
    T[0][0] = 1.0 + 6.0 * p.x * u + 2.0 * p.y * v + 2.0 * s.x * u + 4.0 * s.y * r2 * u;
    T[1][0] = 2.0 * p.x * v + 2.0 * p.y * u + 2.0 * s.x * v + 4.0 * s.y * r2 * v;
    T[0][1] = 2.0 * p.x * v + 2.0 * p.y * u + 2.0 * s.z * u + 4.0 * s.w * r2 * u;
    T[1][1] = 1.0 + 2.0 * p.x * u + 6.0 * p.y * v + 2.0 * s.z * v + 4.0 * s.w * r2 * v;
    return vec2(u + p.x * (r2 + 2.0 * u * u) + 2.0 * p.y * u * v + s.x * r2 + s.y * r2 * r2,
                v + 2.0 * p.x * u * v + p.y * (r2 + 2.0 * v * v) + s.z * r2 + s.w * r2 * r2);
}

// A camera-space point through the lens: its normalized distorted coordinates
// `d` and their Jacobian ∂d/∂t (2 rows of 3, as mat3 columns J[c][r], row 2
// unused); false where the lens cannot image it. CPU twin:
// engine/src/camera/lens.rs `Lens::distort` and `Lens::jacobian`.
bool lens_project(WorldToCamera c, vec3 t, out vec2 d, out mat3 J) {
    float kind = c.lens2.x;
    J = mat3(0.0);
    if (kind == 9.0) {
        // Equirectangular: θ = atan2(x, z), φ = atan2(y, h), h = √(x² + z²).
        float h2 = t.x * t.x + t.z * t.z;
        float rho2 = h2 + t.y * t.y;
        float h = sqrt(h2);
        if (!(h > 1e-12 * sqrt(rho2))) return false;
        d = vec2(atan(t.x, t.z), atan(t.y, h));
        J[0][0] = t.z / h2; J[2][0] = -t.x / h2;
        J[0][1] = -t.x * t.y / (rho2 * h); J[1][1] = h / rho2; J[2][1] = -t.z * t.y / (rho2 * h);
        return true;
    }
    if (kind == 3.0) {
        vec4 k = c.lens0;
        float r2 = t.x * t.x + t.y * t.y;
        float r = sqrt(r2);
        float rho2 = r2 + t.z * t.z;
        if (r <= 1e-9 * abs(t.z)) {
            if (!(t.z > 0.0)) return false;
            d = vec2(0.0);
            J[0][0] = 1.0 / t.z;
            J[1][1] = 1.0 / t.z;
            return true;
        }
        float theta = atan(r, t.z);
        if (theta > c.lens2.y) return false;
        float t2 = theta * theta;
        float thetad = theta * (1.0 + t2 * (k.x + t2 * (k.y + t2 * (k.z + t2 * k.w))));
        float dthetad = 1.0 + t2 * (3.0 * k.x + t2 * (5.0 * k.y + t2 * (7.0 * k.z + t2 * 9.0 * k.w)));
        float s = thetad / r;
        vec3 dtheta = vec3(t.z * t.x / (r * rho2), t.z * t.y / (r * rho2), -r / rho2);
        vec3 ds = vec3(dthetad * dtheta.x / r - thetad * t.x / (r2 * r),
                       dthetad * dtheta.y / r - thetad * t.y / (r2 * r),
                       dthetad * dtheta.z / r);
        d = t.xy * s;
        J[0][0] = s + t.x * ds.x; J[1][0] = t.x * ds.y; J[2][0] = t.x * ds.z;
        J[0][1] = t.y * ds.x;     J[1][1] = s + t.y * ds.y; J[2][1] = t.y * ds.z;
        return true;
    }
    if (!(t.z > 0.0)) return false;
    float u = t.x / t.z, v = t.y / t.z;
    if (u * u + v * v > c.lens2.y * c.lens2.y) return false;
    if (kind == 5.0) {
        // EUCM: (x, y) / (α ρ + (1 − α) z), ρ = √(β (x² + y²) + z²).
        float alpha = c.lens0.x, beta = c.lens0.y;
        float rho = sqrt(beta * (t.x * t.x + t.y * t.y) + t.z * t.z);
        float den = alpha * rho + (1.0 - alpha) * t.z;
        if (!(den > 0.0)) return false;
        vec3 dden = vec3(alpha * beta * t.x / rho, alpha * beta * t.y / rho, alpha * t.z / rho + 1.0 - alpha);
        float d2 = den * den;
        d = t.xy / den;
        J[0][0] = 1.0 / den - t.x * dden.x / d2; J[1][0] = -t.x * dden.y / d2; J[2][0] = -t.x * dden.z / d2;
        J[0][1] = -t.y * dden.x / d2; J[1][1] = 1.0 / den - t.y * dden.y / d2; J[2][1] = -t.y * dden.z / d2;
        return true;
    }
    mat2 D = mat2(1.0);  // D[c][r]
    d = vec2(u, v);
    if (kind == 4.0) {
        // FOV: distorted = undistorted · g(r²), COLMAP's three branches.
        float omega = c.lens0.x;
        float r2 = u * u + v * v;
        float g, dg;
        if (omega * omega < 1e-4) {
            g = omega * omega * r2 / 3.0 - omega * omega / 12.0 + 1.0;
            dg = omega * omega / 3.0;
        } else if (r2 < 1e-4) {
            float t = tan(0.5 * omega);
            g = -2.0 * t * (4.0 * r2 * t * t - 3.0) / (3.0 * omega);
            dg = -8.0 * t * t * t / (3.0 * omega);
        } else {
            float r = sqrt(r2);
            float t2 = 2.0 * tan(0.5 * omega);
            g = atan(r * t2) / (r * omega);
            dg = (t2 / (1.0 + r2 * t2 * t2) / (r * omega) - atan(r * t2) / (r2 * omega)) / (2.0 * r);
        }
        d = vec2(u, v) * g;
        D = radial_jacobian(u, v, g, dg);
    }
    if (kind == 8.0) {
        // Rad-tan thin-prism fisheye: g = θ_d(atan r)/r with six angle coefficients, then the terms.
        vec4 k = c.lens0;
        vec2 k45 = c.lens1.xy;
        float r2 = u * u + v * v;
        float g, dg;
        if (r2 < 1e-10) {
            g = 1.0 + (k.x - 1.0 / 3.0) * r2;
            dg = k.x - 1.0 / 3.0;
        } else {
            float r = sqrt(r2);
            float t = atan(r);
            float t2 = t * t;
            float poly = 1.0 + t2 * (k.x + t2 * (k.y + t2 * (k.z + t2 * (k.w + t2 * (k45.x + t2 * k45.y)))));
            float dpoly = 1.0 + t2 * (3.0 * k.x + t2 * (5.0 * k.y + t2 * (7.0 * k.z + t2 * (9.0 * k.w
                          + t2 * (11.0 * k45.x + t2 * 13.0 * k45.y)))));
            g = t * poly / r;
            dg = (dpoly / (1.0 + r2) / r - t * poly / r2) / (2.0 * r);
        }
        mat2 N = radial_jacobian(u, v, g, dg);
        mat2 T;
        d = rad_tan_thin_prism(vec2(u, v) * g, c.lens1.zw, c.lens3, T);
        D = T * N;
    }
    if (kind == 7.0) {
        // Thin-prism fisheye: equidistant normalization g = atan(r)/r, then the thin-prism distortion.
        float r2 = u * u + v * v;
        float g, dg;
        if (r2 < 1e-8) {
            g = 1.0 - r2 / 3.0;
            dg = -1.0 / 3.0;
        } else {
            float r = sqrt(r2);
            g = atan(r) / r;
            dg = (1.0 / (1.0 + r2) - g) / (2.0 * r2);
        }
        mat2 N = radial_jacobian(u, v, g, dg);
        mat2 T;
        d = thin_prism(vec2(u, v) * g, c.lens0, c.lens1, T);
        D = T * N;
    }
    if (kind == 6.0) {
        // Division: distorted = undistorted · g, g the root of g = 1 + k g² r² near 1.
        float k = c.lens0.x;
        float r2 = u * u + v * v;
        float x = 4.0 * k * r2;
        float g, dg;
        if (abs(x) < 1e-6) {
            g = 1.0 + k * r2;
            dg = k;
        } else {
            if (x >= 1.0) return false;
            float s = sqrt(1.0 - x);
            g = (1.0 - s) / (2.0 * k * r2);
            dg = (4.0 * k * k * r2 / s - 2.0 * k * (1.0 - s)) / (4.0 * k * k * r2 * r2);
        }
        d = vec2(u, v) * g;
        D = radial_jacobian(u, v, g, dg);
    }
    if (kind == 2.0) {
        vec4 k = c.lens0;
        vec4 q = c.lens1;  // k5, k6, p1, p2
        float r2 = u * u + v * v;
        float num = 1.0 + r2 * (k.x + r2 * (k.y + r2 * k.z));
        float den = 1.0 + r2 * (k.w + r2 * (q.x + r2 * q.y));
        float dnum = k.x + r2 * (2.0 * k.y + r2 * 3.0 * k.z);
        float dden = k.w + r2 * (2.0 * q.x + r2 * 3.0 * q.y);
        float radial = num / den;
        float dradial = (dnum * den - num * dden) / (den * den);
        float p1 = q.z, p2 = q.w;
        d = vec2(u * radial + 2.0 * p1 * u * v + p2 * (r2 + 2.0 * u * u),
                 v * radial + 2.0 * p2 * u * v + p1 * (r2 + 2.0 * v * v));
        D[0][0] = radial + 2.0 * u * u * dradial + 2.0 * p1 * v + 6.0 * p2 * u;
        D[1][0] = 2.0 * u * v * dradial + 2.0 * p1 * u + 2.0 * p2 * v;
        D[0][1] = 2.0 * u * v * dradial + 2.0 * p2 * v + 2.0 * p1 * u;
        D[1][1] = radial + 2.0 * v * v * dradial + 2.0 * p2 * u + 6.0 * p1 * v;
    }
    // ∂(u, v)/∂t = [[1/z, 0, −u/z], [0, 1/z, −v/z]].
    for (int row = 0; row < 2; row++) {
        vec2 dr = vec2(D[0][row], D[1][row]);
        J[0][row] = dr.x / t.z;
        J[1][row] = dr.y / t.z;
        J[2][row] = -(dr.x * u + dr.y * v) / t.z;
    }
    return true;
}

// The world-to-camera rotation as a matrix (its columns built from the rows).
mat3 world_to_camera_rotation(WorldToCamera c) {
    return transpose(mat3(c.rot0.xyz, c.rot1.xyz, c.rot2.xyz));
}

// Centre of pixel index p in an image `width` pixels wide.
vec2 pixel_centre(uint p, uint width) {
    return vec2(float(p % width), float(p / width)) + 0.5;
}

// A camera-space vector rotated into the world.
vec3 camera_vector_to_world(CameraToWorld c, vec3 v) {
    return vec3(dot(c.rot0.xyz, v), dot(c.rot1.xyz, v), dot(c.rot2.xyz, v));
}

// The undistorted normalized coordinates (x/z, y/z) whose lens image is the
// normalized distorted point d: Newton's method (2D with the analytic
// Jacobian for radial-tangential, along the radius for fisheye). CPU twin:
// engine/src/camera/lens.rs `Lens::undistort`.
vec2 lens_undistort(CameraToWorld c, vec2 d) {
    float kind = c.lens2.x;
    vec4 k = c.lens0;
    if (kind == 3.0) {
        float rd = length(d);
        if (rd < 1e-12) return vec2(0.0);
        float theta = rd;
        for (int i = 0; i < 20; i++) {
            float t2 = theta * theta;
            float f = theta * (1.0 + t2 * (k.x + t2 * (k.y + t2 * (k.z + t2 * k.w)))) - rd;
            float df = 1.0 + t2 * (3.0 * k.x + t2 * (5.0 * k.y + t2 * (7.0 * k.z + t2 * 9.0 * k.w)));
            theta -= f / df;
        }
        return d * (tan(theta) / rd);
    }
    if (kind == 6.0) return d / (1.0 + k.x * dot(d, d));
    if (kind == 8.0) {
        // Rad-tan thin-prism fisheye: Newton on the terms, then θ_d → θ → tan θ.
        vec2 q = d;
        for (int i = 0; i < 20; i++) {
            mat2 T;
            vec2 f = rad_tan_thin_prism(q, c.lens1.zw, c.lens3, T) - d;
            q -= inverse(T) * f;
        }
        float rd = length(q);
        if (rd < 1e-12) return q;
        vec2 k45 = c.lens1.xy;
        float theta = rd;
        for (int i = 0; i < 20; i++) {
            float t2 = theta * theta;
            float f = theta * (1.0 + t2 * (k.x + t2 * (k.y + t2 * (k.z + t2 * (k.w + t2 * (k45.x + t2 * k45.y)))))) - rd;
            float df = 1.0 + t2 * (3.0 * k.x + t2 * (5.0 * k.y + t2 * (7.0 * k.z + t2 * (9.0 * k.w
                       + t2 * (11.0 * k45.x + t2 * 13.0 * k45.y)))));
            theta -= f / df;
        }
        return q * (tan(theta) / rd);
    }
    if (kind == 7.0) {
        // Thin-prism fisheye: Newton on the thin-prism distortion, then θ → tan θ.
        vec2 q = d;
        for (int i = 0; i < 20; i++) {
            mat2 T;
            vec2 f = thin_prism(q, k, c.lens1, T) - d;
            q -= inverse(T) * f;
        }
        float theta = length(q);
        return theta < 1e-12 ? q : q * (tan(theta) / theta);
    }
    if (kind == 5.0) {
        // EUCM inverts in closed form.
        float alpha = k.x, beta = k.y;
        float r2 = dot(d, d);
        float mz = (1.0 - beta * alpha * alpha * r2) / (alpha * sqrt(max(0.0, 1.0 - (2.0 * alpha - 1.0) * beta * r2)) + 1.0 - alpha);
        return d / mz;
    }
    if (kind == 4.0) {
        // FOV inverts in closed form: r_u = tan(r_d ω) / (2 tan(ω/2)).
        float omega = k.x;
        float rd = length(d);
        if (rd < 1e-12 || omega * omega < 1e-4) return d;
        return d * (tan(rd * omega) / (2.0 * tan(0.5 * omega)) / rd);
    }
    vec4 q = c.lens1;
    vec2 x = d;
    for (int i = 0; i < 20; i++) {
        float u = x.x, v = x.y;
        float r2 = u * u + v * v;
        float num = 1.0 + r2 * (k.x + r2 * (k.y + r2 * k.z));
        float den = 1.0 + r2 * (k.w + r2 * (q.x + r2 * q.y));
        float dnum = k.x + r2 * (2.0 * k.y + r2 * 3.0 * k.z);
        float dden = k.w + r2 * (2.0 * q.x + r2 * 3.0 * q.y);
        float radial = num / den;
        float dradial = (dnum * den - num * dden) / (den * den);
        float p1 = q.z, p2 = q.w;
        vec2 f = vec2(u * radial + 2.0 * p1 * u * v + p2 * (r2 + 2.0 * u * u),
                      v * radial + 2.0 * p2 * u * v + p1 * (r2 + 2.0 * v * v)) - d;
        float a = radial + 2.0 * u * u * dradial + 2.0 * p1 * v + 6.0 * p2 * u;
        float b = 2.0 * u * v * dradial + 2.0 * p1 * u + 2.0 * p2 * v;
        float e = 2.0 * u * v * dradial + 2.0 * p2 * v + 2.0 * p1 * u;
        float g = radial + 2.0 * v * v * dradial + 2.0 * p2 * u + 6.0 * p1 * v;
        float det = a * g - b * e;
        x -= vec2(g * f.x - b * f.y, -e * f.x + a * f.y) / det;
    }
    return x;
}

// Camera-space direction through pixel px (pinhole and lenses): (u, v, 1)
// in front of the camera; a fisheye pixel past 90° off axis gets its true
// direction (sin θ · radial, cos θ), whose z is ≤ 0; an equirectangular
// pixel its unit direction (depth is the distance there). CPU twin:
// engine/src/camera/mod.rs `Camera::pixel_direction`.
vec3 camera_pixel_direction(CameraToWorld c, vec2 px) {
    vec4 k = c.intrinsics;
    vec2 d = (px - k.zw) / k.xy;
    if (c.lens2.x == 9.0) return vec3(cos(d.y) * sin(d.x), sin(d.y), cos(d.y) * cos(d.x));
    if (c.lens2.x == 3.0) {
        float rd = length(d);
        if (rd < 1e-12) return vec3(0.0, 0.0, 1.0);
        vec4 q = c.lens0;
        float theta = rd;
        for (int i = 0; i < 20; i++) {
            float t2 = theta * theta;
            float f = theta * (1.0 + t2 * (q.x + t2 * (q.y + t2 * (q.z + t2 * q.w)))) - rd;
            float df = 1.0 + t2 * (3.0 * q.x + t2 * (5.0 * q.y + t2 * (7.0 * q.z + t2 * 9.0 * q.w)));
            theta -= f / df;
        }
        vec3 dir = vec3(d / rd * sin(theta), cos(theta));
        return dir.z > 1e-6 ? dir / dir.z : dir;
    }
    if (c.lens2.x != 0.0) d = lens_undistort(c, d);
    return vec3(d, 1.0);
}

// World direction of the ray through pixel px, scaled to camera depth 1
// (pinhole, lenses) or the optical axis (orthographic); not normalised.
vec3 camera_ray(CameraToWorld c, vec2 px) {
    vec3 v = c.position.w == 0.0 ? camera_pixel_direction(c, px) : vec3(0.0, 0.0, 1.0);
    return camera_vector_to_world(c, v);
}

// The world point seen at pixel px at camera depth z, less the camera's
// position: small numbers however far the scene lies from the origin.
vec3 camera_unproject_from_camera(CameraToWorld c, vec2 px, float z) {
    vec4 k = c.intrinsics;
    vec3 v = c.position.w == 0.0 ? camera_pixel_direction(c, px) * z : vec3((px - k.zw) / k.xy, z);
    return camera_vector_to_world(c, v);
}

#endif
