//! Lens models: how a camera-space direction lands on the normalized image
//! plane (before fx, fy, cx, cy), as COLMAP defines them (`colmap/sensor/models.h`)
//! and OpenCV's `projectPoints` / `fisheye::projectPoints` compute them.
//!
//! Parsed from COLMAP models and transforms.json, checked here against
//! pycolmap's projection; rendering through a lens is not implemented yet
//! (the camera readers refuse lens cameras), so this is the CPU reference the
//! GPU lens path will be tested against. All arithmetic is f64.

/// A lens model with its coefficients.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Lens {
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
    /// order; `None` for models not implemented here (thin-prism fisheye,
    /// division, EUCM, equirectangular) or a wrong parameter count.
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
    /// The normalized distorted image coordinates of a camera-space point.
    pub fn distort(&self, p: [f64; 3]) -> Option<[f64; 2]> {
        let [x, y, z] = p;
        match *self {
            Lens::Pinhole | Lens::RadialTangential { .. } | Lens::Fov { .. } => {
                if z <= 0.0 {
                    return None;
                }
                Some(self.distort_plane([x / z, y / z]))
            }
            Lens::Fisheye { k } => {
                let r = (x * x + y * y).sqrt();
                if r <= f64::EPSILON * z.abs().max(1.0) {
                    return (z > 0.0).then_some([0.0, 0.0]);
                }
                let theta = r.atan2(z);
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
                let r2 = u * u + v * v;
                let factor = if omega * omega < 1e-4 {
                    (omega * omega * r2) / 3.0 - omega * omega / 12.0 + 1.0
                } else if r2 < 1e-4 {
                    let t = (omega / 2.0).tan();
                    (-2.0 * t * (4.0 * r2 * t * t - 3.0)) / (3.0 * omega)
                } else {
                    let r = r2.sqrt();
                    (r * 2.0 * (omega / 2.0).tan()).atan() / (r * omega)
                };
                [u * factor, v * factor]
            }
        }
    }

    /// The normalized undistorted coordinates (x/z, y/z) whose distortion is `d`
    /// (Newton's method with a central-difference Jacobian, as COLMAP's
    /// iterative undistortion; the fisheye inverts θ_d(θ) along the radius).
    pub fn undistort(&self, d: [f64; 2]) -> Option<[f64; 2]> {
        match *self {
            Lens::Pinhole => Some(d),
            Lens::Fisheye { k } => {
                let rd = (d[0] * d[0] + d[1] * d[1]).sqrt();
                if rd < f64::EPSILON {
                    return Some([0.0, 0.0]);
                }
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
