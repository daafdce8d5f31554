//! Lens models: how a camera-space direction lands on the normalized image
//! plane (before fx, fy, cx, cy), as COLMAP defines them (`colmap/sensor/models.h`)
//! and OpenCV's `projectPoints` / `fisheye::projectPoints` compute them.
//!
//! Parsed from COLMAP models and transforms.json and checked against
//! pycolmap's and OpenCV's projections. The splatting stage renders through
//! the radial-tangential and fisheye models (`camera.glsl`, `lens_project`)
//! and its CPU twin uses these functions; all arithmetic here is f64.

/// A lens model with its coefficients.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Lens {
    #[default]
    /// No distortion: (x/z, y/z).
    Pinhole,
    /// OpenCV radial-tangential: radial (1 + k1 r² + k2 r⁴ + k3 r⁶) / (1 + k4 r² + k5 r⁴ + k6 r⁶)
    /// and tangential p1, p2 (COLMAP SIMPLE_RADIAL, RADIAL, OPENCV, FULL_OPENCV).
    RadialTangential {
        /// k1..k6 (k4..k6 the rational denominator; zero for the plain model).
        k: [f64; 6],
        /// p1, p2.
        p: [f64; 2],
    },
    /// OpenCV fisheye (Kannala-Brandt): θ_d = θ (1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸) along the
    /// image radius, θ the angle from the optical axis (COLMAP OPENCV_FISHEYE,
    /// SIMPLE_RADIAL_FISHEYE, RADIAL_FISHEYE, SIMPLE_FISHEYE, FISHEYE).
    Fisheye {
        /// k1..k4.
        k: [f64; 4],
    },
    /// The FOV model of Devernay and Faugeras with field of view ω (COLMAP FOV).
    Fov {
        /// ω in radians.
        omega: f64,
    },
    /// The enhanced unified camera model: (x, y) / (α √(β (x² + y²) + z²) + (1 − α) z) (COLMAP EUCM).
    Eucm {
        /// α.
        alpha: f64,
        /// β.
        beta: f64,
    },
    /// The division model: undistorted = distorted / (1 + k r_d²) (COLMAP SIMPLE_DIVISION, DIVISION).
    Division {
        /// k.
        k: f64,
    },
    /// COLMAP's RAD_TAN_THIN_PRISM_FISHEYE (Project Aria's model): the angle
    /// θ_d = θ (1 + k0 θ² + … + k5 θ¹²) along the radius, then tangential
    /// p0, p1 and thin prism s0..s3 (in r² and r⁴) on those coordinates.
    RadTanThinPrismFisheye {
        /// k0..k5.
        k: [f64; 6],
        /// p0, p1.
        p: [f64; 2],
        /// s0..s3.
        s: [f64; 4],
    },
    /// COLMAP's THIN_PRISM_FISHEYE: the equidistant angle (θ/r)·(x/z, y/z), then radial
    /// k1..k4 in its squared radius, tangential p1, p2 and thin prism sx1, sy1 on it.
    ThinPrismFisheye {
        /// k1..k4.
        k: [f64; 4],
        /// p1, p2.
        p: [f64; 2],
        /// sx1, sy1.
        s: [f64; 2],
    },
    /// Equirectangular (COLMAP EQUIRECTANGULAR): longitude θ = atan2(x, z) and
    /// latitude φ = atan2(y, √(x² + z²)) (y down) as the normalized
    /// coordinates, so that u = fx·θ + cx, v = fy·φ + cy; every direction but
    /// the camera centre is imaged, behind the camera too. With fx = width / 2π
    /// the image is a full 360° panorama and wraps at its left and right edges.
    Equirectangular,
}

/// The Jacobian (rows) of (u, v) ↦ (u, v)·g(u² + v²), given g and dg/d(r²).
fn radial_jacobian(u: f64, v: f64, g: f64, dg: f64) -> [[f64; 2]; 2] {
    [[g + 2.0 * u * u * dg, 2.0 * u * v * dg], [2.0 * u * v * dg, g + 2.0 * v * v * dg]]
}

/// The angle off axis θ with θ (1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸) = `rd`
/// (Newton's method from θ = rd; any angle, past 90° too).
pub(crate) fn fisheye_theta(k: [f64; 4], rd: f64) -> f64 {
    let mut theta = rd;
    for _ in 0..100 {
        let t2 = theta * theta;
        let f = theta * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3])))) - rd;
        let df = 1.0 + t2 * (3.0 * k[0] + t2 * (5.0 * k[1] + t2 * (7.0 * k[2] + t2 * 9.0 * k[3])));
        let step = f / df;
        theta -= step;
        if step.abs() < 1e-15 {
            break;
        }
    }
    theta
}

/// Focal lengths, principal point and lens of a camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Intrinsics {
    /// fx, fy in pixels.
    pub focal: [f64; 2],
    /// cx, cy in pixels (pixel centres at +0.5).
    pub centre: [f64; 2],
    /// The lens.
    pub lens: Lens,
}

impl Intrinsics {
    /// The intrinsics of a COLMAP camera model with its parameters in COLMAP's
    /// order (EQUIRECTANGULAR's w, h give fx = w / 2π, fy = h / π, cx = w / 2,
    /// cy = h / 2); `None` for unknown models or a wrong parameter count.
    pub fn from_colmap(model: &str, p: &[f64]) -> Option<Intrinsics> {
        let single = |lens: Lens| Intrinsics { focal: [p[0], p[0]], centre: [p[1], p[2]], lens };
        let double = |lens: Lens| Intrinsics { focal: [p[0], p[1]], centre: [p[2], p[3]], lens };
        let rt = |k1, k2, p1, p2| Lens::RadialTangential { k: [k1, k2, 0.0, 0.0, 0.0, 0.0], p: [p1, p2] };
        Some(match (model, p.len()) {
            ("SIMPLE_PINHOLE", 3) => single(Lens::Pinhole),
            ("PINHOLE", 4) => double(Lens::Pinhole),
            ("SIMPLE_RADIAL", 4) => single(rt(p[3], 0.0, 0.0, 0.0)),
            ("RADIAL", 5) => single(rt(p[3], p[4], 0.0, 0.0)),
            ("OPENCV", 8) => double(rt(p[4], p[5], p[6], p[7])),
            ("FULL_OPENCV", 12) => {
                double(Lens::RadialTangential { k: [p[4], p[5], p[8], p[9], p[10], p[11]], p: [p[6], p[7]] })
            }
            ("OPENCV_FISHEYE", 8) => double(Lens::Fisheye { k: [p[4], p[5], p[6], p[7]] }),
            ("SIMPLE_RADIAL_FISHEYE", 4) => single(Lens::Fisheye { k: [p[3], 0.0, 0.0, 0.0] }),
            ("RADIAL_FISHEYE", 5) => single(Lens::Fisheye { k: [p[3], p[4], 0.0, 0.0] }),
            ("SIMPLE_FISHEYE", 3) => single(Lens::Fisheye { k: [0.0; 4] }),
            ("FISHEYE", 4) => double(Lens::Fisheye { k: [0.0; 4] }),
            ("FOV", 5) => double(Lens::Fov { omega: p[4] }),
            ("EUCM", 6) => double(Lens::Eucm { alpha: p[4], beta: p[5] }),
            ("SIMPLE_DIVISION", 4) => single(Lens::Division { k: p[3] }),
            ("DIVISION", 5) => double(Lens::Division { k: p[4] }),
            ("RAD_TAN_THIN_PRISM_FISHEYE", 16) => double(Lens::RadTanThinPrismFisheye {
                k: [p[4], p[5], p[6], p[7], p[8], p[9]],
                p: [p[10], p[11]],
                s: [p[12], p[13], p[14], p[15]],
            }),
            ("THIN_PRISM_FISHEYE", 12) => {
                double(Lens::ThinPrismFisheye { k: [p[4], p[5], p[8], p[9]], p: [p[6], p[7]], s: [p[10], p[11]] })
            }
            ("EQUIRECTANGULAR", 2) => Intrinsics {
                focal: [p[0] / std::f64::consts::TAU, p[1] / std::f64::consts::PI],
                centre: [p[0] * 0.5, p[1] * 0.5],
                lens: Lens::Equirectangular,
            },
            _ => return None,
        })
    }

    /// The pixel a camera-space point lands on; `None` where the lens cannot
    /// image it (behind a perspective lens, on the optical axis's antipode).
    pub fn project(&self, point: [f64; 3]) -> Option<[f64; 2]> {
        let [x, y] = self.lens.distort(point)?;
        Some([self.focal[0] * x + self.centre[0], self.focal[1] * y + self.centre[1]])
    }

    /// The normalized undistorted coordinates (x/z, y/z) of the ray through a pixel.
    pub fn unproject(&self, pixel: [f64; 2]) -> Option<[f64; 2]> {
        let d = [(pixel[0] - self.centre[0]) / self.focal[0], (pixel[1] - self.centre[1]) / self.focal[1]];
        self.lens.undistort(d)
    }
}

impl Lens {
    /// The kind number the shaders switch on (`lens2.x` in `camera.glsl`):
    /// 0 pinhole, 2 radial-tangential, 3 fisheye, 4 FOV (every model here
    /// renders; `Option` for models added later that may not).
    pub fn gpu_kind(&self) -> Option<u32> {
        match self {
            Lens::Pinhole => Some(0),
            Lens::RadialTangential { .. } => Some(2),
            Lens::Fisheye { .. } => Some(3),
            Lens::Fov { .. } => Some(4),
            Lens::Eucm { .. } => Some(5),
            Lens::Division { .. } => Some(6),
            Lens::ThinPrismFisheye { .. } => Some(7),
            Lens::RadTanThinPrismFisheye { .. } => Some(8),
            Lens::Equirectangular => Some(9),
        }
    }

    /// The coefficients as the shaders take them: `lens0`, `lens1` (radial-tangential:
    /// (k1, k2, k3, k4) and (k5, k6, p1, p2)) and `lens3` (the rad-tan thin-prism
    /// fisheye's s0..s3; its k0..k3 in `lens0`, k4, k5, p0, p1 in `lens1`).
    pub fn gpu_coefficients3(&self) -> [[f32; 4]; 3] {
        match *self {
            Lens::RadTanThinPrismFisheye { k, p, s } => [
                [k[0], k[1], k[2], k[3]].map(|v| v as f32),
                [k[4], k[5], p[0], p[1]].map(|v| v as f32),
                s.map(|v| v as f32),
            ],
            _ => {
                let [a, b] = self.gpu_coefficients();
                [a, b, [0.0; 4]]
            }
        }
    }

    /// The coefficients as the shaders take them: (k1, k2, k3, k4) and (k5, k6, p1, p2).
    pub fn gpu_coefficients(&self) -> [[f32; 4]; 2] {
        match *self {
            Lens::RadTanThinPrismFisheye { .. } => {
                let [a, b, _] = self.gpu_coefficients3();
                [a, b]
            }
            Lens::RadialTangential { k, p } => {
                [[k[0], k[1], k[2], k[3]].map(|v| v as f32), [k[4], k[5], p[0], p[1]].map(|v| v as f32)]
            }
            Lens::Fisheye { k } => [k.map(|v| v as f32), [0.0; 4]],
            Lens::Fov { omega } => [[omega as f32, 0.0, 0.0, 0.0], [0.0; 4]],
            Lens::Eucm { alpha, beta } => [[alpha as f32, beta as f32, 0.0, 0.0], [0.0; 4]],
            Lens::Division { k } => [[k as f32, 0.0, 0.0, 0.0], [0.0; 4]],
            Lens::ThinPrismFisheye { k, p, s } => [k.map(|v| v as f32), [p[0], p[1], s[0], s[1]].map(|v| v as f32)],
            Lens::Pinhole | Lens::Equirectangular => [[0.0; 4]; 2],
        }
    }

    /// The largest undistorted normalized radius (radial-tangential) or
    /// angle off axis in radians (fisheye) that splatting images through this
    /// lens for an image of `size` pixels with `focal` lengths and `centre`:
    /// 1.5× (fisheye: 1.25×) what the image's corners and edge midpoints
    /// reach, and never past the radius where a radial polynomial folds back
    /// (beyond it, far-off points would land in the image). Pinhole: infinite.
    pub fn imaging_limit(&self, focal: [f64; 2], centre: [f64; 2], size: [f64; 2]) -> f64 {
        let intr = Intrinsics { focal, centre, lens: *self };
        let edge = [
            [0.0, 0.0],
            [size[0], 0.0],
            [0.0, size[1]],
            [size[0], size[1]],
            [size[0] * 0.5, 0.0],
            [size[0] * 0.5, size[1]],
            [0.0, size[1] * 0.5],
            [size[0], size[1] * 0.5],
        ];
        let reach = edge
            .iter()
            .filter_map(|px| intr.unproject(*px))
            .map(|[u, v]| (u * u + v * v).sqrt())
            .fold(0.0f64, f64::max);
        match *self {
            Lens::Pinhole | Lens::Equirectangular => f64::INFINITY,
            // r·g(r) grows without folding: as far as the image reaches, with margin.
            Lens::Fov { .. }
            | Lens::Eucm { .. }
            | Lens::ThinPrismFisheye { .. }
            | Lens::RadTanThinPrismFisheye { .. } => reach * 1.5,
            // k > 0: real only while 4 k r² < 1.
            Lens::Division { k } if k > 0.0 => (reach * 1.5).min(0.999 / (2.0 * k.sqrt())),
            Lens::Division { .. } => reach * 1.5,
            Lens::Fisheye { k } => {
                // Angles off axis of the edge pixels, past 90° too.
                let theta = edge
                    .iter()
                    .map(|px| {
                        let d = [(px[0] - centre[0]) / focal[0], (px[1] - centre[1]) / focal[1]];
                        fisheye_theta(k, (d[0] * d[0] + d[1] * d[1]).sqrt())
                    })
                    .fold(0.0f64, f64::max);
                (theta * 1.25).min(std::f64::consts::PI)
            }
            Lens::RadialTangential { .. } => (reach * 1.5).min(self.fold().map_or(100.0, |(r, _)| r)),
        }
    }

    /// For a radial-tangential lens: the undistorted radius where r·radial(r)
    /// stops growing along the axes (the polynomial folds back past it) and
    /// the distorted radius it reaches there; `None` when it grows out to 100.
    pub fn fold(&self) -> Option<(f64, f64)> {
        let Lens::RadialTangential { .. } = self else { return None };
        let mut last = 0.0;
        for i in 1..=10_000 {
            let r = f64::from(i) * 0.01;
            let d = self.distort_plane([r, 0.0])[0].min(self.distort_plane([0.0, r])[1]);
            if d <= last {
                return Some((r - 0.01, last));
            }
            last = d;
        }
        None
    }

    /// The unit camera-space direction of equirectangular coordinates (θ, φ).
    pub fn equirectangular_direction([theta, phi]: [f64; 2]) -> [f64; 3] {
        let (st, ct) = theta.sin_cos();
        let (sp, cp) = phi.sin_cos();
        [cp * st, sp, cp * ct]
    }

    /// Whether it is the plain pinhole.
    pub fn is_pinhole(&self) -> bool {
        *self == Lens::Pinhole
    }

    /// ∂(distorted normalized coordinates)/∂(camera-space point), 2 rows of 3,
    /// where [`Lens::distort`] is defined (FOV: `None`).
    pub fn jacobian(&self, p: [f64; 3]) -> Option<[[f64; 3]; 2]> {
        let [x, y, z] = p;
        match *self {
            Lens::Equirectangular => {
                let h2 = x * x + z * z;
                let rho2 = h2 + y * y;
                let h = h2.sqrt();
                if h <= 1e-12 * rho2.sqrt() || rho2 == 0.0 {
                    return None;
                }
                // θ = atan2(x, z), φ = atan2(y, h), h = √(x² + z²).
                Some([[z / h2, 0.0, -x / h2], [-x * y / (rho2 * h), h / rho2, -z * y / (rho2 * h)]])
            }
            Lens::Eucm { alpha, beta } => {
                let rho = (beta * (x * x + y * y) + z * z).sqrt();
                let den = alpha * rho + (1.0 - alpha) * z;
                if z <= 0.0 || den <= 0.0 {
                    return None;
                }
                let dden = [alpha * beta * x / rho, alpha * beta * y / rho, alpha * z / rho + 1.0 - alpha];
                let d2 = den * den;
                Some([
                    [1.0 / den - x * dden[0] / d2, -x * dden[1] / d2, -x * dden[2] / d2],
                    [-y * dden[0] / d2, 1.0 / den - y * dden[1] / d2, -y * dden[2] / d2],
                ])
            }
            Lens::Pinhole
            | Lens::RadialTangential { .. }
            | Lens::Fov { .. }
            | Lens::Division { .. }
            | Lens::ThinPrismFisheye { .. }
            | Lens::RadTanThinPrismFisheye { .. } => {
                if z <= 0.0 {
                    return None;
                }
                let (u, v) = (x / z, y / z);
                let d = self.plane_jacobian([u, v]);
                if d.iter().flatten().any(|v| !v.is_finite()) {
                    return None;
                }
                // ∂(u, v)/∂p = [[1/z, 0, −u/z], [0, 1/z, −v/z]].
                let row = |r: [f64; 2]| [r[0] / z, r[1] / z, -(r[0] * u + r[1] * v) / z];
                Some([row(d[0]), row(d[1])])
            }
            Lens::Fisheye { k } => {
                let r2 = x * x + y * y;
                let r = r2.sqrt();
                let rho2 = r2 + z * z;
                if r <= 1e-9 * z.abs().max(1e-30) {
                    return (z > 0.0).then_some([[1.0 / z, 0.0, 0.0], [0.0, 1.0 / z, 0.0]]);
                }
                let theta = r.atan2(z);
                let t2 = theta * theta;
                let thetad = theta * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))));
                let dthetad = 1.0 + t2 * (3.0 * k[0] + t2 * (5.0 * k[1] + t2 * (7.0 * k[2] + t2 * 9.0 * k[3])));
                let s = thetad / r;
                let dtheta = [z * x / (r * rho2), z * y / (r * rho2), -r / rho2];
                let ds = [
                    dthetad * dtheta[0] / r - thetad * x / (r2 * r),
                    dthetad * dtheta[1] / r - thetad * y / (r2 * r),
                    dthetad * dtheta[2] / r,
                ];
                Some([[s + x * ds[0], x * ds[1], x * ds[2]], [y * ds[0], s + y * ds[1], y * ds[2]]])
            }
        }
    }

    /// The division model's radial factor g(r²) (distorted = undistorted · g,
    /// the root of g = 1 + k g² r² near 1) and dg/d(r²); `None` where no root is real.
    fn division_factor(k: f64, r2: f64) -> Option<(f64, f64)> {
        let x = 4.0 * k * r2;
        if x.abs() < 1e-8 {
            return Some((1.0 + k * r2, k));
        }
        if x >= 1.0 {
            return None;
        }
        let s = (1.0 - x).sqrt();
        let g = (1.0 - s) / (2.0 * k * r2);
        let dg = (4.0 * k * k * r2 / s - 2.0 * k * (1.0 - s)) / (4.0 * k * k * r2 * r2);
        Some((g, dg))
    }

    /// atan(r)/r and its derivative in r²: the equidistant normalization (θ/r)·(u, v).
    fn equidistant_factor(r2: f64) -> (f64, f64) {
        if r2 < 1e-8 {
            return (1.0 - r2 / 3.0, -1.0 / 3.0);
        }
        let r = r2.sqrt();
        let g = r.atan() / r;
        (g, (1.0 / (1.0 + r2) - g) / (2.0 * r2))
    }

    /// θ_d(atan r)/r for the six-coefficient angle polynomial and its derivative in r².
    fn kb6_factor(k: [f64; 6], r2: f64) -> (f64, f64) {
        if r2 < 1e-12 {
            return (1.0 + (k[0] - 1.0 / 3.0) * r2, k[0] - 1.0 / 3.0);
        }
        let r = r2.sqrt();
        let t = r.atan();
        let t2 = t * t;
        let poly = 1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * (k[3] + t2 * (k[4] + t2 * k[5])))));
        let dpoly = 1.0
            + t2 * (3.0 * k[0]
                + t2 * (5.0 * k[1] + t2 * (7.0 * k[2] + t2 * (9.0 * k[3] + t2 * (11.0 * k[4] + t2 * 13.0 * k[5])))));
        let g = t * poly / r;
        let dg_dr = dpoly / (1.0 + r2) / r - t * poly / r2;
        (g, dg_dr / (2.0 * r))
    }

    /// RAD_TAN_THIN_PRISM_FISHEYE's tangential and thin-prism terms on (uu, vv), and their Jacobian.
    fn rad_tan_thin_prism(q: [f64; 2], p: [f64; 2], s: [f64; 4]) -> ([f64; 2], [[f64; 2]; 2]) {
        let [u, v] = q;
        let r2 = u * u + v * v;
        let d = [
            u + p[0] * (r2 + 2.0 * u * u) + 2.0 * p[1] * u * v + s[0] * r2 + s[1] * r2 * r2,
            v + 2.0 * p[0] * u * v + p[1] * (r2 + 2.0 * v * v) + s[2] * r2 + s[3] * r2 * r2,
        ];
        let j = [
            [
                1.0 + 6.0 * p[0] * u + 2.0 * p[1] * v + 2.0 * s[0] * u + 4.0 * s[1] * r2 * u,
                2.0 * p[0] * v + 2.0 * p[1] * u + 2.0 * s[0] * v + 4.0 * s[1] * r2 * v,
            ],
            [
                2.0 * p[0] * v + 2.0 * p[1] * u + 2.0 * s[2] * u + 4.0 * s[3] * r2 * u,
                1.0 + 2.0 * p[0] * u + 6.0 * p[1] * v + 2.0 * s[2] * v + 4.0 * s[3] * r2 * v,
            ],
        ];
        (d, j)
    }

    /// THIN_PRISM_FISHEYE's distortion of equidistant coordinates (uu, vv) and its 2×2 Jacobian.
    fn thin_prism(q: [f64; 2], k: [f64; 4], p: [f64; 2], s: [f64; 2]) -> ([f64; 2], [[f64; 2]; 2]) {
        let [u, v] = q;
        let r2 = u * u + v * v;
        let radial = r2 * (k[0] + r2 * (k[1] + r2 * (k[2] + r2 * k[3])));
        let dr = k[0] + r2 * (2.0 * k[1] + r2 * (3.0 * k[2] + r2 * 4.0 * k[3]));
        let d = [
            u + u * radial + 2.0 * p[0] * u * v + p[1] * (r2 + 2.0 * u * u) + s[0] * r2,
            v + v * radial + 2.0 * p[1] * u * v + p[0] * (r2 + 2.0 * v * v) + s[1] * r2,
        ];
        let j = [
            [
                1.0 + radial + 2.0 * u * u * dr + 2.0 * p[0] * v + 6.0 * p[1] * u + 2.0 * s[0] * u,
                2.0 * u * v * dr + 2.0 * p[0] * u + 2.0 * p[1] * v + 2.0 * s[0] * v,
            ],
            [
                2.0 * u * v * dr + 2.0 * p[1] * v + 2.0 * p[0] * u + 2.0 * s[1] * u,
                1.0 + radial + 2.0 * v * v * dr + 2.0 * p[1] * u + 6.0 * p[0] * v + 2.0 * s[1] * v,
            ],
        ];
        (d, j)
    }

    /// The FOV model's radial factor g(r²) (distorted = undistorted · g) and
    /// dg/d(r²), in COLMAP's three branches (small ω, small r, general).
    fn fov_factor(omega: f64, r2: f64) -> (f64, f64) {
        if omega * omega < 1e-4 {
            ((omega * omega * r2) / 3.0 - omega * omega / 12.0 + 1.0, omega * omega / 3.0)
        } else if r2 < 1e-4 {
            let t = (omega / 2.0).tan();
            ((-2.0 * t * (4.0 * r2 * t * t - 3.0)) / (3.0 * omega), -8.0 * t * t * t / (3.0 * omega))
        } else {
            let r = r2.sqrt();
            let t2 = 2.0 * (omega / 2.0).tan();
            let g = (r * t2).atan() / (r * omega);
            let dg_dr = t2 / (1.0 + r * r * t2 * t2) / (r * omega) - (r * t2).atan() / (r * r * omega);
            (g, dg_dr / (2.0 * r))
        }
    }

    /// ∂(distorted)/∂(u, v) of the perspective models, 2 rows of 2.
    fn plane_jacobian(&self, [u, v]: [f64; 2]) -> [[f64; 2]; 2] {
        match *self {
            Lens::RadialTangential { k, p } => {
                let r2 = u * u + v * v;
                let num = 1.0 + r2 * (k[0] + r2 * (k[1] + r2 * k[2]));
                let den = 1.0 + r2 * (k[3] + r2 * (k[4] + r2 * k[5]));
                let dnum = k[0] + r2 * (2.0 * k[1] + r2 * 3.0 * k[2]);
                let dden = k[3] + r2 * (2.0 * k[4] + r2 * 3.0 * k[5]);
                let radial = num / den;
                let dradial = (dnum * den - num * dden) / (den * den);
                [
                    [
                        radial + 2.0 * u * u * dradial + 2.0 * p[0] * v + 6.0 * p[1] * u,
                        2.0 * u * v * dradial + 2.0 * p[0] * u + 2.0 * p[1] * v,
                    ],
                    [
                        2.0 * u * v * dradial + 2.0 * p[1] * v + 2.0 * p[0] * u,
                        radial + 2.0 * v * v * dradial + 2.0 * p[1] * u + 6.0 * p[0] * v,
                    ],
                ]
            }
            Lens::ThinPrismFisheye { .. } | Lens::RadTanThinPrismFisheye { .. } => {
                let r2 = u * u + v * v;
                let (g, dg) = match *self {
                    Lens::RadTanThinPrismFisheye { k, .. } => Self::kb6_factor(k, r2),
                    _ => Self::equidistant_factor(r2),
                };
                let n = radial_jacobian(u, v, g, dg);
                let (_, t) = match *self {
                    Lens::ThinPrismFisheye { k, p, s } => Self::thin_prism([u * g, v * g], k, p, s),
                    Lens::RadTanThinPrismFisheye { p, s, .. } => Self::rad_tan_thin_prism([u * g, v * g], p, s),
                    _ => ([u, v], [[1.0, 0.0], [0.0, 1.0]]),
                };
                [
                    [t[0][0] * n[0][0] + t[0][1] * n[1][0], t[0][0] * n[0][1] + t[0][1] * n[1][1]],
                    [t[1][0] * n[0][0] + t[1][1] * n[1][0], t[1][0] * n[0][1] + t[1][1] * n[1][1]],
                ]
            }
            Lens::Fov { .. } | Lens::Division { .. } => {
                let r2 = u * u + v * v;
                let (g, dg) = match *self {
                    Lens::Fov { omega } => Self::fov_factor(omega, r2),
                    Lens::Division { k } => Self::division_factor(k, r2).unwrap_or((f64::NAN, f64::NAN)),
                    _ => (1.0, 0.0),
                };
                radial_jacobian(u, v, g, dg)
            }
            _ => [[1.0, 0.0], [0.0, 1.0]],
        }
    }

    /// The normalized distorted image coordinates of a camera-space point.
    pub fn distort(&self, p: [f64; 3]) -> Option<[f64; 2]> {
        self.distort_within(p, f64::INFINITY)
    }

    /// [`Lens::distort`] for points within `limit` ([`Lens::imaging_limit`]); `None` beyond.
    pub fn distort_within(&self, p: [f64; 3], limit: f64) -> Option<[f64; 2]> {
        let [x, y, z] = p;
        match *self {
            Lens::Equirectangular => {
                let h = x.hypot(z);
                (h + y.abs() > 0.0).then(|| [x.atan2(z), y.atan2(h)])
            }
            Lens::Pinhole
            | Lens::RadialTangential { .. }
            | Lens::Fov { .. }
            | Lens::Division { .. }
            | Lens::ThinPrismFisheye { .. }
            | Lens::RadTanThinPrismFisheye { .. } => {
                if z <= 0.0 || (x * x + y * y) > limit * limit * z * z {
                    return None;
                }
                let d = self.distort_plane([x / z, y / z]);
                d.iter().all(|v| v.is_finite()).then_some(d)
            }
            Lens::Eucm { alpha, beta } => {
                if z <= 0.0 || (x * x + y * y) > limit * limit * z * z {
                    return None;
                }
                let den = alpha * (beta * (x * x + y * y) + z * z).sqrt() + (1.0 - alpha) * z;
                (den > 0.0).then(|| [x / den, y / den])
            }
            Lens::Fisheye { k } => {
                let r = (x * x + y * y).sqrt();
                if r <= f64::EPSILON * z.abs().max(1.0) {
                    return (z > 0.0).then_some([0.0, 0.0]);
                }
                let theta = r.atan2(z);
                if theta > limit {
                    return None;
                }
                let t2 = theta * theta;
                let thetad = theta * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))));
                Some([x / r * thetad, y / r * thetad])
            }
        }
    }

    /// Distortion of normalized perspective coordinates (u, v) = (x/z, y/z) (not for fisheye).
    fn distort_plane(&self, [u, v]: [f64; 2]) -> [f64; 2] {
        match *self {
            Lens::Pinhole | Lens::Fisheye { .. } => [u, v],
            Lens::Equirectangular => [u.atan(), v.atan2(u.hypot(1.0))],
            Lens::RadialTangential { k, p } => {
                let (u2, v2, uv) = (u * u, v * v, u * v);
                let r2 = u2 + v2;
                let radial =
                    (1.0 + r2 * (k[0] + r2 * (k[1] + r2 * k[2]))) / (1.0 + r2 * (k[3] + r2 * (k[4] + r2 * k[5])));
                [
                    u * radial + 2.0 * p[0] * uv + p[1] * (r2 + 2.0 * u2),
                    v * radial + 2.0 * p[1] * uv + p[0] * (r2 + 2.0 * v2),
                ]
            }
            Lens::Fov { omega } => {
                let (factor, _) = Self::fov_factor(omega, u * u + v * v);
                [u * factor, v * factor]
            }
            Lens::Division { k } => {
                let g = Self::division_factor(k, u * u + v * v).map_or(f64::NAN, |(g, _)| g);
                [u * g, v * g]
            }
            Lens::ThinPrismFisheye { k, p, s } => {
                let (g, _) = Self::equidistant_factor(u * u + v * v);
                Self::thin_prism([u * g, v * g], k, p, s).0
            }
            Lens::RadTanThinPrismFisheye { k, p, s } => {
                let (g, _) = Self::kb6_factor(k, u * u + v * v);
                Self::rad_tan_thin_prism([u * g, v * g], p, s).0
            }
            Lens::Eucm { alpha, beta } => {
                let den = alpha * (beta * (u * u + v * v) + 1.0).sqrt() + 1.0 - alpha;
                [u / den, v / den]
            }
        }
    }

    /// The normalized undistorted coordinates (x/z, y/z) whose distortion is `d`
    /// (Newton's method with a central-difference Jacobian, as COLMAP's
    /// iterative undistortion; the fisheye inverts θ_d(θ) along the radius).
    pub fn undistort(&self, d: [f64; 2]) -> Option<[f64; 2]> {
        match *self {
            Lens::Pinhole => Some(d),
            Lens::Equirectangular => {
                // In front of the camera only ([`Lens::equirectangular_direction`] gives every ray).
                let [x, y, z] = Self::equirectangular_direction(d);
                (z > 1e-12).then(|| [x / z, y / z])
            }
            Lens::Division { k } => {
                let s = 1.0 + k * (d[0] * d[0] + d[1] * d[1]);
                (s > 0.0).then(|| [d[0] / s, d[1] / s])
            }
            Lens::Eucm { alpha, beta } => {
                let r2 = d[0] * d[0] + d[1] * d[1];
                let root = 1.0 - (2.0 * alpha - 1.0) * beta * r2;
                if root < 0.0 {
                    return None;
                }
                let mz = (1.0 - beta * alpha * alpha * r2) / (alpha * root.sqrt() + 1.0 - alpha);
                (mz > 0.0).then(|| [d[0] / mz, d[1] / mz])
            }
            Lens::Fisheye { k } => {
                let rd = (d[0] * d[0] + d[1] * d[1]).sqrt();
                if rd < f64::EPSILON {
                    return Some([0.0, 0.0]);
                }
                let theta = fisheye_theta(k, rd);
                if !(0.0..std::f64::consts::FRAC_PI_2).contains(&theta) {
                    return None;
                }
                let s = theta.tan() / rd;
                Some([d[0] * s, d[1] * s])
            }
            _ => {
                let mut x = d;
                for _ in 0..100 {
                    let f = self.distort_plane(x);
                    let r = [f[0] - d[0], f[1] - d[1]];
                    let h = 1e-7 * x[0].abs().max(x[1].abs()).max(1e-3);
                    let col = |i: usize| {
                        let (mut a, mut b) = (x, x);
                        a[i] += h;
                        b[i] -= h;
                        let (fa, fb) = (self.distort_plane(a), self.distort_plane(b));
                        [(fa[0] - fb[0]) / (2.0 * h), (fa[1] - fb[1]) / (2.0 * h)]
                    };
                    let (j0, j1) = (col(0), col(1));
                    let det = j0[0] * j1[1] - j1[0] * j0[1];
                    if det.abs() < 1e-300 {
                        return None;
                    }
                    let step = [(j1[1] * r[0] - j1[0] * r[1]) / det, (-j0[1] * r[0] + j0[0] * r[1]) / det];
                    x = [x[0] - step[0], x[1] - step[1]];
                    if step[0].abs().max(step[1].abs()) < 1e-14 {
                        break;
                    }
                }
                x.iter().all(|v| v.is_finite()).then_some(x)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "a failed unwrap is a failed test")]
    use super::*;

    /// The analytic Jacobians agree with central differences of `distort`,
    /// for both lens families, off axis, near the axis and near 90° (fisheye).
    #[test]
    fn jacobians_match_central_differences() {
        let lenses = [
            Lens::RadialTangential { k: [-0.2, 0.05, 0.01, 0.05, 0.01, 0.002], p: [0.001, -0.002] },
            Lens::RadialTangential { k: [0.1, 0.0, 0.0, 0.0, 0.0, 0.0], p: [0.0, 0.0] },
            Lens::Fisheye { k: [0.01, -0.002, 0.0003, -0.00004] },
            Lens::Fov { omega: 0.9 },
            Lens::Fov { omega: 0.005 },
            Lens::Eucm { alpha: 0.6, beta: 1.1 },
            Lens::ThinPrismFisheye { k: [0.01, -0.002, 0.0003, -0.00004], p: [0.001, -0.0005], s: [0.0008, -0.0006] },
            Lens::RadTanThinPrismFisheye {
                k: [0.01, -0.002, 0.0003, -0.00004, 0.00001, -0.000002],
                p: [0.001, -0.0005],
                s: [0.0008, -0.0006, 0.0002, -0.0001],
            },
            Lens::Division { k: -0.2 },
            Lens::Division { k: 0.05 },
            Lens::Pinhole,
            Lens::Equirectangular,
        ];
        let points = [[0.3, -0.2, 1.5], [1e-7, 2e-7, 3.0], [-2.0, 1.0, 0.4], [5.0, 0.1, 0.05], [-1.0, 3.0, -2.0]];
        let mut tested = 0;
        for lens in lenses {
            for p in points {
                if !matches!(lens, Lens::Fisheye { .. } | Lens::Equirectangular) && p[2] < 0.1 {
                    continue;
                }
                // Outside a model's domain both are undefined (the division model past 4 k r² = 1).
                let Some(j) = lens.jacobian(p) else {
                    assert!(lens.distort(p).is_none(), "{lens:?} at {p:?}: a projection without a Jacobian");
                    continue;
                };
                tested += 1;
                for c in 0..3 {
                    let h = 1e-6 * p[c].abs().max(1e-3);
                    let (mut a, mut b) = (p, p);
                    a[c] += h;
                    b[c] -= h;
                    let (da, db) = (lens.distort(a).unwrap(), lens.distort(b).unwrap());
                    for r in 0..2 {
                        let fd = (da[r] - db[r]) / (2.0 * h);
                        let scale = j[r][c].abs().max(1.0);
                        assert!(
                            (fd - j[r][c]).abs() <= 1e-6 * scale,
                            "{lens:?} at {p:?}: ∂{r}/∂{c} {} vs {fd}",
                            j[r][c]
                        );
                    }
                }
            }
        }
        assert!(tested >= 28, "only {tested} lens-point pairs had a Jacobian");
    }
}
