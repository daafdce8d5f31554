//! Cameras: pinhole and orthographic projections (files of cameras are read
//! and written by [`crate::io`]).
//!
//! Conventions (docs/conventions.md §3): camera axes are OpenCV's (x right, y down,
//! z forward); `rotation` is camera-to-world (its columns are the camera axes in
//! world space) and `position` the camera centre; pixel centres are at +0.5.

pub mod lens;

use bytemuck::{Pod, Zeroable};
use glam::{Mat3, Vec2, Vec3};

use crate::error::{Error, Result};

/// How camera space maps to pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// Perspective: u = fx·x/z + cx, v = fy·y/z + cy.
    Pinhole {
        /// Focal length in pixels, x.
        fx: f32,
        /// Focal length in pixels, y.
        fy: f32,
        /// Principal point, x.
        cx: f32,
        /// Principal point, y.
        cy: f32,
    },
    /// Parallel: u = sx·x + cx, v = sy·y + cy (the sun's shadow-map camera).
    Orthographic {
        /// Pixels per world unit, x.
        sx: f32,
        /// Pixels per world unit, y.
        sy: f32,
        /// Pixel of the optical axis, x.
        cx: f32,
        /// Pixel of the optical axis, y.
        cy: f32,
    },
}

/// A camera: pose, image size and projection.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Name (the image name in cameras.json).
    pub name: String,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Camera-to-world rotation.
    pub rotation: Mat3,
    /// Camera centre in world space.
    pub position: Vec3,
    /// Projection.
    pub projection: Projection,
    /// Near plane distance (camera z; equirectangular: distance from the centre).
    pub near: f32,
    /// Far plane distance (camera z; equirectangular: distance from the centre).
    pub far: f32,
    /// The lens between the camera-space ray and [`Camera::projection`]'s
    /// intrinsics (pinhole cameras: [`lens::Lens::Pinhole`]). Splatting renders
    /// radial-tangential and fisheye lenses; the stages that unproject pixels
    /// (shadows, shading) refuse any other than the pinhole.
    pub lens: lens::Lens,
}

/// Default near plane (gsplat's; INRIA uses 0.2).
pub const DEFAULT_NEAR: f32 = 0.01;
/// Default far plane.
pub const DEFAULT_FAR: f32 = 1.0e4;

/// The camera as a uniform block embeds it to unproject pixels:
/// `CameraToWorld` in `camera.glsl` (checked against it wherever a block
/// embeds one).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub(crate) struct CameraToWorldBlock {
    /// Rows of the camera-to-world rotation (`w` 0).
    pub(crate) rot0: [f32; 4],
    pub(crate) rot1: [f32; 4],
    pub(crate) rot2: [f32; 4],
    /// The camera centre; `w`: 0 pinhole, 1 orthographic.
    pub(crate) position: [f32; 4],
    /// fx, fy, cx, cy (orthographic: pixels per unit x, y, cx, cy).
    pub(crate) intrinsics: [f32; 4],
    /// Lens coefficients k1..k4, as in [`WorldToCameraBlock::lens0`].
    pub(crate) lens0: [f32; 4],
    /// Lens coefficients k5, k6, p1, p2.
    pub(crate) lens1: [f32; 4],
    /// `x`: the lens kind, `y`: its imaging limit.
    pub(crate) lens2: [f32; 4],
    /// More lens coefficients (the rad-tan thin-prism fisheye's s0..s3).
    pub(crate) lens3: [f32; 4],
}

/// The camera as a uniform block embeds it to project points:
/// `WorldToCamera` in `camera.glsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub(crate) struct WorldToCameraBlock {
    /// Rows of the world-to-camera rotation (`w` 0).
    pub(crate) rot0: [f32; 4],
    pub(crate) rot1: [f32; 4],
    pub(crate) rot2: [f32; 4],
    /// The camera's position in the world (shaders take a point to
    /// rotation · (point − position), which keeps its precision far from the
    /// origin); `w`: 0 pinhole, 1 orthographic.
    pub(crate) position: [f32; 4],
    /// fx, fy, cx, cy (orthographic: pixels per unit x, y, cx, cy).
    pub(crate) intrinsics: [f32; 4],
    /// Lens coefficients k1..k4 (fisheye: its k1..k4).
    pub(crate) lens0: [f32; 4],
    /// Lens coefficients k5, k6, p1, p2.
    pub(crate) lens1: [f32; 4],
    /// `x`: the lens kind ([`lens::Lens::gpu_kind`]), `y`: its imaging limit.
    pub(crate) lens2: [f32; 4],
    /// More lens coefficients (the rad-tan thin-prism fisheye's s0..s3).
    pub(crate) lens3: [f32; 4],
}

/// A camera packed once for the shaders, in both directions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PackedCamera {
    pub(crate) to_world: CameraToWorldBlock,
    pub(crate) to_camera: WorldToCameraBlock,
}

impl Camera {
    /// The camera-space direction through pixel position `px`: (u, v, 1), the
    /// pixel's undistorted normalized coordinates, in front of the camera
    /// (orthographic: (0, 0, 1)); a fisheye pixel past 90° off axis gets its
    /// true direction (sin θ · radial, cos θ), whose z is ≤ 0; an
    /// equirectangular pixel its unit direction (its depth is the ray
    /// distance). `None` where the lens sends no ray through the pixel.
    pub fn pixel_direction(&self, px: [f64; 2]) -> Option<[f64; 3]> {
        match self.projection {
            Projection::Orthographic { .. } => Some([0.0, 0.0, 1.0]),
            Projection::Pinhole { fx, fy, cx, cy } if self.lens == lens::Lens::Equirectangular => {
                let d = [(px[0] - f64::from(cx)) / f64::from(fx), (px[1] - f64::from(cy)) / f64::from(fy)];
                Some(lens::Lens::equirectangular_direction(d))
            }
            Projection::Pinhole { fx, fy, cx, cy } if matches!(self.lens, lens::Lens::Fisheye { .. }) => {
                let lens::Lens::Fisheye { k } = self.lens else { return None };
                let d = [(px[0] - f64::from(cx)) / f64::from(fx), (px[1] - f64::from(cy)) / f64::from(fy)];
                let rd = (d[0] * d[0] + d[1] * d[1]).sqrt();
                if rd < 1e-12 {
                    return Some([0.0, 0.0, 1.0]);
                }
                let theta = lens::fisheye_theta(k, rd);
                let dir = [d[0] / rd * theta.sin(), d[1] / rd * theta.sin(), theta.cos()];
                Some(if dir[2] > 1e-6 { dir.map(|v| v / dir[2]) } else { dir })
            }
            Projection::Pinhole { fx, fy, cx, cy } => {
                let intr = lens::Intrinsics {
                    focal: [f64::from(fx), f64::from(fy)],
                    centre: [f64::from(cx), f64::from(cy)],
                    lens: self.lens,
                };
                let [u, v] = intr.unproject(px)?;
                Some([u, v, 1.0])
            }
        }
    }

    /// The distance along the ray through pixel position `px` per unit of
    /// camera depth: √(u² + v² + 1) with (u, v) the pixel's undistorted
    /// normalized coordinates (1 for orthographic and equirectangular cameras,
    /// whose depth is the ray distance); `None` where the lens sends no ray
    /// through it. Multiplies a depth channel into a ray-distance (range)
    /// channel, as lidar measures.
    pub fn ray_length_per_depth(&self, px: [f64; 2]) -> Option<f64> {
        match self.projection {
            Projection::Orthographic { .. } => Some(1.0),
            Projection::Pinhole { .. } if self.lens == lens::Lens::Equirectangular => Some(1.0),
            Projection::Pinhole { .. } => {
                let [u, v, w] = self.pixel_direction(px)?;
                // Past 90° off axis no depth reaches the pixel.
                (w > 0.0).then(|| (u * u + v * v + w * w).sqrt() / w)
            }
        }
    }

    /// For a full 360° equirectangular camera (2π·fx within half a pixel of
    /// the width): the width, the period at which its image wraps; `None` otherwise.
    pub fn wrap_period(&self) -> Option<f32> {
        match self.projection {
            Projection::Pinhole { fx, .. } if self.lens == lens::Lens::Equirectangular => {
                let period = std::f32::consts::TAU * fx;
                ((period - self.width as f32).abs() <= 0.5).then_some(self.width as f32)
            }
            _ => None,
        }
    }

    /// Whether depth is the distance from the camera centre rather than camera
    /// z (equirectangular cameras, which see behind themselves).
    pub fn depth_is_distance(&self) -> bool {
        self.lens == lens::Lens::Equirectangular && matches!(self.projection, Projection::Pinhole { .. })
    }

    /// How far off axis splatting images through the lens ([`lens::Lens::imaging_limit`]).
    pub fn lens_limit(&self) -> f64 {
        match self.projection {
            Projection::Pinhole { fx, fy, cx, cy } => self.lens.imaging_limit(
                [f64::from(fx), f64::from(fy)],
                [f64::from(cx), f64::from(cy)],
                [f64::from(self.width), f64::from(self.height)],
            ),
            Projection::Orthographic { .. } => f64::INFINITY,
        }
    }

    /// An error unless the camera is a plain pinhole or orthographic one:
    /// for the stages that unproject pixels (`what` names the stage).
    pub(crate) fn require_no_lens(&self, what: &str) -> Result<()> {
        if self.lens.is_pinhole() {
            Ok(())
        } else {
            Err(Error::invalid(
                format!("camera \"{}\" with lens {:?}", self.name, self.lens),
                format!(
                    "{what} handles pinhole cameras only so far (splatting, shadows and shading render \
                     every lens model)"
                ),
            ))
        }
    }

    /// The camera packed for the shaders.
    pub(crate) fn packed(&self) -> PackedCamera {
        let r = self.rotation;
        let w = r.transpose();
        let rows = |m: Mat3| [0, 1, 2].map(|i| [m.x_axis[i], m.y_axis[i], m.z_axis[i], 0.0]);
        let (intrinsics, kind) = match self.projection {
            Projection::Pinhole { fx, fy, cx, cy } => ([fx, fy, cx, cy], 0.0),
            Projection::Orthographic { sx, sy, cx, cy } => ([sx, sy, cx, cy], 1.0),
        };
        let p = self.position;
        let [rot0, rot1, rot2] = rows(r);
        let [lens0, lens1, lens3] = self.lens.gpu_coefficients3();
        let limit = self.lens_limit().min(f64::from(f32::MAX)) as f32;
        let lens2 = [self.lens.gpu_kind().unwrap_or(0) as f32, limit, 0.0, 0.0];
        let to_world = CameraToWorldBlock {
            rot0,
            rot1,
            rot2,
            position: [p.x, p.y, p.z, kind],
            intrinsics,
            lens0,
            lens1,
            lens2,
            lens3,
        };
        let [rot0, rot1, rot2] = rows(w);
        let to_camera = WorldToCameraBlock {
            rot0,
            rot1,
            rot2,
            position: [p.x, p.y, p.z, kind],
            intrinsics,
            lens0,
            lens1,
            lens2,
            lens3,
        };
        PackedCamera { to_world, to_camera }
    }

    /// Checks the camera in the precision the GPU uses (f32), naming the first
    /// rule that fails: a non-empty size, finite positive focal lengths (or
    /// scales) and a finite principal point, 0 < near < far < ∞, an
    /// orthonormal right-handed rotation, a finite position, and a packing
    /// whose every value is finite.
    pub fn validate(&self) -> Result<()> {
        let (f, c) = match self.projection {
            Projection::Pinhole { fx, fy, cx, cy } | Projection::Orthographic { sx: fx, sy: fy, cx, cy } => {
                ([fx, fy], [cx, cy])
            }
        };
        let rotation = self.rotation;
        let orthonormality = (rotation.transpose() * rotation - Mat3::IDENTITY)
            .to_cols_array()
            .iter()
            .fold(0.0f32, |m, v| m.max(v.abs()));
        let rules: [(bool, String, &str); 7] = [
            (self.width > 0 && self.height > 0, format!("image size {}x{}", self.width, self.height), "is empty"),
            (
                f.iter().all(|v| v.is_finite() && *v > 0.0),
                format!("focal lengths {} / {}", f[0], f[1]),
                "must be finite and positive in f32",
            ),
            (c.iter().all(|v| v.is_finite()), format!("principal point {} / {}", c[0], c[1]), "must be finite"),
            (
                self.near > 0.0 && self.near < self.far && self.far.is_finite(),
                format!("near {} and far {}", self.near, self.far),
                "need 0 < near < far < ∞",
            ),
            (
                rotation.is_finite() && orthonormality <= 1e-3 && rotation.determinant() > 0.0,
                format!("rotation (|RᵀR − I| = {orthonormality:.2e}, det = {:.3})", rotation.determinant()),
                "is not a rotation",
            ),
            (self.position.is_finite(), format!("position {}", self.position), "must be finite in f32"),
            (
                self.lens.gpu_coefficients3().iter().flatten().all(|v| v.is_finite()),
                format!("lens {:?}", self.lens),
                "must have coefficients finite in f32",
            ),
        ];
        let name = if self.name.is_empty() { "camera".to_string() } else { format!("camera \"{}\"", self.name) };
        if let Some((_, what, why)) = rules.into_iter().find(|(ok, ..)| !ok) {
            return Err(Error::invalid(format!("{name}: {what}"), why));
        }
        // A radial polynomial that folds back inside the image: some pixels see two places, some none.
        if let (Some((r, d_max)), Projection::Pinhole { fx, fy, cx, cy }) = (self.lens.fold(), self.projection) {
            let (w, h) = (self.width as f32, self.height as f32);
            let corner = [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)]
                .iter()
                .map(|(x, y)| f64::from(((x - cx) / fx).hypot((y - cy) / fy)))
                .fold(0.0, f64::max);
            if corner > d_max {
                return Err(Error::invalid(
                    format!("{name}: lens {:?}", self.lens),
                    format!(
                        "folds the image: its radial distortion stops growing at undistorted radius {r:.3} \
                         (distorted {d_max:.3}), inside the image, whose corners reach {corner:.3}"
                    ),
                ));
            }
        }
        Ok(())
    }

    /// A pinhole camera at `eye` looking at `target`, with `up` roughly up in
    /// the image and `fov_x_degrees` horizontal field of view.
    pub fn look_at(eye: Vec3, target: Vec3, up: Vec3, fov_x_degrees: f32, width: u32, height: u32) -> Result<Self> {
        let rotation = look_rotation(eye, target, up)?;
        if !(fov_x_degrees > 0.0 && fov_x_degrees < 180.0) || width == 0 || height == 0 {
            return Err(Error::invalid(
                format!("camera with fov {fov_x_degrees}° and size {width}x{height}"),
                "needs a fov in (0°, 180°) and a non-empty size",
            ));
        }
        let fx = width as f32 * 0.5 / (fov_x_degrees.to_radians() * 0.5).tan();
        let camera = Self {
            name: String::new(),
            width,
            height,
            rotation,
            position: eye,
            projection: Projection::Pinhole { fx, fy: fx, cx: width as f32 * 0.5, cy: height as f32 * 0.5 },
            near: DEFAULT_NEAR,
            far: DEFAULT_FAR,
            lens: lens::Lens::Pinhole,
        };
        camera.validate().map_err(|_| {
            Error::invalid(
                format!("look-at camera from {eye} with fov {fov_x_degrees}° and size {width}x{height}"),
                "gives a focal length or position that is not finite in f32",
            )
        })?;
        Ok(camera)
    }

    /// A full 360° × 180° equirectangular panorama `width` × `width / 2`
    /// pixels at `eye`, its centre column looking along `rotation`'s z axis
    /// (camera-to-world, OpenCV axes: y down), as COLMAP's EQUIRECTANGULAR
    /// with w = width, h = height.
    pub fn panorama(eye: Vec3, rotation: Mat3, width: u32) -> Result<Self> {
        let height = width / 2;
        let (w, h) = (width as f32, height as f32);
        let camera = Self {
            name: String::new(),
            width,
            height,
            rotation,
            position: eye,
            projection: Projection::Pinhole {
                fx: w / std::f32::consts::TAU,
                fy: h / std::f32::consts::PI,
                cx: w * 0.5,
                cy: h * 0.5,
            },
            near: DEFAULT_NEAR,
            far: DEFAULT_FAR,
            lens: lens::Lens::Equirectangular,
        };
        camera
            .validate()
            .map_err(|e| Error::invalid(format!("panorama {width} pixels wide at {eye}"), e.to_string()))?;
        Ok(camera)
    }

    /// An orthographic camera at `eye` looking along `direction`, covering
    /// `extent_x` × `extent_y` world units with a `width` × `height` image
    /// (the sun's shadow-map camera). Depth runs from `near` to `far` along `direction`.
    #[allow(clippy::too_many_arguments, reason = "a camera is defined by this many independent quantities")]
    pub fn orthographic(
        eye: Vec3,
        direction: Vec3,
        up: Vec3,
        extent_x: f32,
        extent_y: f32,
        width: u32,
        height: u32,
        near: f32,
        far: f32,
    ) -> Result<Self> {
        let rotation = look_rotation(eye, eye + direction, up)?;
        let valid = extent_x > 0.0 && extent_y > 0.0 && extent_x.is_finite() && extent_y.is_finite() && near < far;
        if !valid || width == 0 || height == 0 {
            return Err(Error::invalid(
                format!("orthographic camera {extent_x}x{extent_y}, size {width}x{height}, depth {near}..{far}"),
                "needs a positive finite extent, a non-empty size and near < far",
            ));
        }
        Ok(Self {
            name: String::new(),
            width,
            height,
            rotation,
            position: eye,
            projection: Projection::Orthographic {
                sx: width as f32 / extent_x,
                sy: height as f32 / extent_y,
                cx: width as f32 * 0.5,
                cy: height as f32 * 0.5,
            },
            near,
            far,
            lens: lens::Lens::Pinhole,
        })
    }

    /// The same camera with its image resized to `width`×`height` (intrinsics scaled).
    pub fn resized(&self, width: u32, height: u32) -> Self {
        let (kx, ky) = (width as f32 / self.width as f32, height as f32 / self.height as f32);
        let projection = match self.projection {
            Projection::Pinhole { fx, fy, cx, cy } => {
                Projection::Pinhole { fx: fx * kx, fy: fy * ky, cx: cx * kx, cy: cy * ky }
            }
            Projection::Orthographic { sx, sy, cx, cy } => {
                Projection::Orthographic { sx: sx * kx, sy: sy * ky, cx: cx * kx, cy: cy * ky }
            }
        };
        Self { width, height, projection, ..self.clone() }
    }

    /// World to camera coordinates.
    pub fn world_to_camera(&self, p: Vec3) -> Vec3 {
        self.rotation.transpose() * (p - self.position)
    }

    /// Camera coordinates to pixel coordinates (no clipping), through the lens
    /// (NaN where the lens images nothing).
    pub fn project(&self, p: Vec3) -> Vec2 {
        match self.projection {
            Projection::Pinhole { fx, fy, cx, cy } if !self.lens.is_pinhole() => {
                let intr = lens::Intrinsics {
                    focal: [f64::from(fx), f64::from(fy)],
                    centre: [f64::from(cx), f64::from(cy)],
                    lens: self.lens,
                };
                intr.project(p.as_dvec3().to_array()).map_or(Vec2::NAN, |[u, v]| Vec2::new(u as f32, v as f32))
            }
            Projection::Pinhole { fx, fy, cx, cy } => Vec2::new(fx * p.x / p.z + cx, fy * p.y / p.z + cy),
            Projection::Orthographic { sx, sy, cx, cy } => Vec2::new(sx * p.x + cx, sy * p.y + cy),
        }
    }

    /// Horizontal field of view in degrees (pinhole only).
    pub fn fov_x_degrees(&self) -> Option<f32> {
        match self.projection {
            Projection::Pinhole { fx, .. } => Some((2.0 * (self.width as f32 * 0.5 / fx).atan()).to_degrees()),
            Projection::Orthographic { .. } => None,
        }
    }

    /// Whether a world point projects inside the image and in front of the
    /// camera (between the near and far planes).
    pub fn sees(&self, p: Vec3) -> bool {
        let c = self.world_to_camera(p);
        let depth = if self.depth_is_distance() { c.length() } else { c.z };
        if depth <= self.near || depth >= self.far {
            return false;
        }
        let px = self.project(c);
        px.x >= 0.0 && px.y >= 0.0 && px.x < self.width as f32 && px.y < self.height as f32
    }
}

/// The centre −Rᵀ·t of a world-to-camera transform [R | t], given Rᵀ (the
/// camera-to-world rotation), in f64 and rounded once: the shaders take a
/// camera's centre as it is, so its rounding is all a far scene sees.
pub fn centre_of(camera_to_world: Mat3, translation: Vec3) -> Vec3 {
    (-(camera_to_world.as_dmat3() * translation.as_dvec3())).as_vec3()
}

/// Camera-to-world rotation for OpenCV axes looking from `eye` at `target`.
pub fn look_rotation(eye: Vec3, target: Vec3, up: Vec3) -> Result<Mat3> {
    let what = || format!("look-at from {eye} to {target} with up {up}");
    let forward = (target - eye).normalize_or_zero();
    if forward == Vec3::ZERO || !forward.is_finite() {
        return Err(Error::invalid(what(), "has no view direction (eye and target coincide or are not finite)"));
    }
    // Within ~0.06° of the view direction the roll would be arbitrary.
    let side = forward.cross(up.normalize_or_zero());
    if !side.is_finite() || side.length() < 1e-3 {
        return Err(Error::invalid(what(), "has an up vector zero or parallel to the view direction"));
    }
    let right = side.normalize();
    let down = forward.cross(right);
    Ok(Mat3::from_cols(right, down, forward))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "a failed unwrap is a failed test")]
    use super::*;

    /// Depth times the ray length per unit depth is the distance to the point,
    /// for a pinhole, a barrel lens and a fisheye (the pixel found by projecting the point).
    #[test]
    fn ray_length_turns_depth_into_distance() {
        use lens::Lens;
        let base = Camera::look_at(Vec3::ZERO, Vec3::Z, -Vec3::Y, 80.0, 320, 200).unwrap();
        for lens in [
            Lens::Pinhole,
            Lens::RadialTangential { k: [-0.2, 0.05, 0.0, 0.0, 0.0, 0.0], p: [0.001, -0.002] },
            Lens::Fisheye { k: [0.01, -0.002, 0.0, 0.0] },
        ] {
            let cam = Camera { lens, ..base.clone() };
            let Projection::Pinhole { fx, fy, cx, cy } = cam.projection else { unreachable!() };
            let intr = lens::Intrinsics {
                focal: [f64::from(fx), f64::from(fy)],
                centre: [f64::from(cx), f64::from(cy)],
                lens,
            };
            for p in [[0.0, 0.0, 5.0], [1.5, -0.8, 4.0], [-2.5, 1.2, 3.0]] {
                let px = intr.project(p).unwrap();
                let distance = cam.ray_length_per_depth(px).unwrap() * p[2];
                let truth = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
                assert!((distance - truth).abs() < 1e-9 * truth, "{lens:?} {p:?}: {distance} vs {truth}");
            }
        }
    }

    /// A fisheye pixel past 90° off axis gets its true direction (the sky a
    /// 200° fisheye shows), and no ray length per depth.
    #[test]
    fn fisheye_pixels_past_ninety_degrees_look_backward() {
        let base = Camera::look_at(Vec3::ZERO, Vec3::Z, -Vec3::Y, 80.0, 400, 400).unwrap();
        let k = [0.01, -0.002, 0.0, 0.0];
        let cam = Camera { lens: lens::Lens::Fisheye { k }, ..base };
        let Projection::Pinhole { fx, cx, cy, .. } = cam.projection else { unreachable!() };
        for degrees in [30.0f64, 89.0, 120.0] {
            let theta = degrees.to_radians();
            let t2 = theta * theta;
            let rd = theta * (1.0 + t2 * (k[0] + t2 * k[1]));
            let px = [f64::from(cx) + rd * f64::from(fx), f64::from(cy)];
            let d = cam.pixel_direction(px).unwrap();
            let angle = (d[2] / (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()).acos().to_degrees();
            assert!((angle - degrees).abs() < 1e-6, "{degrees}°: direction {d:?} is {angle}° off axis");
            assert_eq!(cam.ray_length_per_depth(px).is_some(), degrees < 90.0);
        }
    }

    /// A centre recovered from world-to-camera translations 1e5 m out is
    /// −Rᵀt rounded once to f32: f32 arithmetic misses it by steps of 8 mm
    /// there, which the shaders, taking the centre as it is, would show.
    #[test]
    fn centres_from_translations_are_rounded_once() {
        let mut rounded_once = 0;
        for i in 0..50 {
            let eye = Vec3::new(1.0e5 + 0.37 * i as f32, -7.0e4 - 0.11 * i as f32, 31.5);
            let r = look_rotation(eye, eye + Vec3::new(0.3, 0.9 - 0.01 * i as f32, -0.1), Vec3::Z).unwrap();
            let t = (-(r.transpose().as_dmat3() * eye.as_dvec3())).as_vec3();
            let centre = centre_of(r, t);
            let exact = -(r.as_dmat3() * t.as_dvec3());
            rounded_once += usize::from(centre == exact.as_vec3());
        }
        assert_eq!(rounded_once, 50, "centres not −Rᵀt rounded once");
    }

    /// The packed rows are the two rotations, and both directions carry the
    /// camera's position as it is.
    #[test]
    fn packed_camera_is_consistent() {
        let c = Camera::look_at(Vec3::new(3.0, -4.0, 1.5), Vec3::new(0.5, 2.0, 0.0), Vec3::Z, 70.0, 64, 32).unwrap();
        let p = c.packed();
        let (w, v) = (p.to_world, p.to_camera);
        let (to_world, to_camera) = ([w.rot0, w.rot1, w.rot2], [v.rot0, v.rot1, v.rot2]);
        for i in 0..3 {
            for j in 0..3 {
                assert_eq!(to_world[i][j], to_camera[j][i]);
            }
        }
        let row = |r: [f32; 4]| Vec3::new(r[0], r[1], r[2]);
        assert_eq!((v.position[3], w.position[3]), (0.0, 0.0));
        assert_eq!(row(w.position), c.position);
        assert_eq!(row(v.position), c.position);
        assert_eq!(v.intrinsics, w.intrinsics);
        assert_eq!(v.intrinsics[2..], [32.0, 16.0]);
    }
}
