//! COLMAP sparse models: `cameras` and `images`, text (`.txt`) or binary
//! (`.bin`), as COLMAP and pycolmap write them.
//!
//! `cameras` lists each camera's model, image size and parameters; `images`
//! lists each registered image's pose (the world-to-camera rotation as a
//! quaternion w, x, y, z and translation) and its camera. COLMAP's camera
//! axes and pixel convention (x right, y down, z forward; pixel centres at
//! +0.5) are srug's, so a pose converts exactly: rotation Rᵀ, centre −Rᵀt.
//! Every COLMAP camera model (ids 0-17, as COLMAP 4 writes them) is parsed
//! and becomes a srug camera with its [`Lens`] (EQUIRECTANGULAR's w, h become
//! fx = w / 2π, fy = h / π, cx = w / 2, cy = h / 2); an unknown model or a
//! wrong parameter count is refused naming the camera and its model.
//! Images come out sorted by name.

use std::path::{Path, PathBuf};

use glam::{DMat3, DQuat, DVec3, Mat3, Vec3};

use crate::camera::lens::{Intrinsics, Lens};
use crate::camera::{Camera, Projection, DEFAULT_FAR, DEFAULT_NEAR};
use crate::error::{Error, Result};
use crate::scene::SceneError;

/// A COLMAP camera model: its id in binary files, name, and parameter names in order.
struct Model {
    id: i32,
    name: &'static str,
    params: &'static [&'static str],
}

/// COLMAP's camera models (`colmap/sensor/models.h`), ids as written in `cameras.bin`.
const MODELS: &[Model] = &[
    Model { id: 0, name: "SIMPLE_PINHOLE", params: &["f", "cx", "cy"] },
    Model { id: 1, name: "PINHOLE", params: &["fx", "fy", "cx", "cy"] },
    Model { id: 2, name: "SIMPLE_RADIAL", params: &["f", "cx", "cy", "k"] },
    Model { id: 3, name: "RADIAL", params: &["f", "cx", "cy", "k1", "k2"] },
    Model { id: 4, name: "OPENCV", params: &["fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2"] },
    Model { id: 5, name: "OPENCV_FISHEYE", params: &["fx", "fy", "cx", "cy", "k1", "k2", "k3", "k4"] },
    Model {
        id: 6,
        name: "FULL_OPENCV",
        params: &["fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"],
    },
    Model { id: 7, name: "FOV", params: &["fx", "fy", "cx", "cy", "omega"] },
    Model { id: 8, name: "SIMPLE_RADIAL_FISHEYE", params: &["f", "cx", "cy", "k"] },
    Model { id: 9, name: "RADIAL_FISHEYE", params: &["f", "cx", "cy", "k1", "k2"] },
    Model {
        id: 10,
        name: "THIN_PRISM_FISHEYE",
        params: &["fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "sx1", "sy1"],
    },
    Model {
        id: 11,
        name: "RAD_TAN_THIN_PRISM_FISHEYE",
        params: &["fx", "fy", "cx", "cy", "k0", "k1", "k2", "k3", "k4", "k5", "p0", "p1", "s0", "s1", "s2", "s3"],
    },
    Model { id: 12, name: "SIMPLE_DIVISION", params: &["f", "cx", "cy", "k"] },
    Model { id: 13, name: "DIVISION", params: &["fx", "fy", "cx", "cy", "k"] },
    Model { id: 14, name: "SIMPLE_FISHEYE", params: &["f", "cx", "cy"] },
    Model { id: 15, name: "FISHEYE", params: &["fx", "fy", "cx", "cy"] },
    Model { id: 16, name: "EUCM", params: &["fx", "fy", "cx", "cy", "alpha", "beta"] },
    Model { id: 17, name: "EQUIRECTANGULAR", params: &["w", "h"] },
];

/// One camera of `cameras.txt`/`.bin`.
struct ColmapCamera {
    id: i64,
    model: &'static Model,
    width: u64,
    height: u64,
    params: Vec<f64>,
}

/// One image of `images.txt`/`.bin`.
struct ColmapImage {
    id: i64,
    q: [f64; 4],
    t: [f64; 3],
    camera: i64,
    name: String,
}

fn err(origin: &str, field: &str, message: impl std::fmt::Display) -> SceneError {
    SceneError { path: origin.into(), row: None, property: Some(field.into()), message: format!("COLMAP: {message}") }
}

/// The model files of a sparse model given as its folder or as one of its files.
fn model_files(path: &Path) -> Option<(PathBuf, PathBuf, bool)> {
    let dir = if path.is_dir() { path.to_path_buf() } else { path.parent()?.to_path_buf() };
    for (ext, binary) in [("bin", true), ("txt", false)] {
        let (c, i) = (dir.join(format!("cameras.{ext}")), dir.join(format!("images.{ext}")));
        let named = path.is_dir() || path.extension().is_some_and(|e| e == ext);
        if named && c.is_file() && i.is_file() {
            return Some((c, i, binary));
        }
    }
    None
}

/// Whether `path` is a COLMAP sparse model (its folder, or its `cameras`/`images` file).
pub(crate) fn is_model(path: &Path) -> bool {
    model_files(path).is_some()
}

/// Reads the registered images of a COLMAP sparse model as srug cameras, sorted by image name.
pub fn read_colmap(path: impl AsRef<Path>) -> Result<Vec<Camera>> {
    let path = path.as_ref();
    let (cameras_path, images_path, binary) = model_files(path).ok_or_else(|| {
        Error::invalid(
            path.display().to_string(),
            "is not a COLMAP sparse model (a folder with cameras.txt and images.txt, or cameras.bin and images.bin)",
        )
    })?;
    let (c_origin, i_origin) = (cameras_path.display().to_string(), images_path.display().to_string());
    let (cameras, images) = if binary {
        (
            parse_cameras_bin(&super::read_file(&cameras_path)?, &c_origin)?,
            parse_images_bin(&super::read_file(&images_path)?, &i_origin)?,
        )
    } else {
        (
            parse_cameras_txt(&super::read_text(&cameras_path)?, &c_origin)?,
            parse_images_txt(&super::read_text(&images_path)?, &i_origin)?,
        )
    };
    Ok(to_cameras(&cameras, images, &c_origin, &i_origin)?)
}

/// Parses a COLMAP model held in memory: `cameras` and `images` file
/// contents, binary or text (UTF-8).
pub fn parse_colmap(cameras: &[u8], images: &[u8], binary: bool) -> Result<Vec<Camera>, SceneError> {
    let (c_origin, i_origin) = if binary { ("cameras.bin", "images.bin") } else { ("cameras.txt", "images.txt") };
    let (cams, ims) = if binary {
        (parse_cameras_bin(cameras, c_origin)?, parse_images_bin(images, i_origin)?)
    } else {
        let text =
            |b: &[u8], o: &str| std::str::from_utf8(b).map(str::to_owned).map_err(|_| err(o, "text", "is not UTF-8"));
        (parse_cameras_txt(&text(cameras, c_origin)?, c_origin)?, parse_images_txt(&text(images, i_origin)?, i_origin)?)
    };
    to_cameras(&cams, ims, c_origin, i_origin)
}

fn model_by_name(name: &str) -> Option<&'static Model> {
    MODELS.iter().find(|m| m.name == name)
}

fn check_camera(c: &ColmapCamera, origin: &str) -> Result<(), SceneError> {
    let at = |m: String| err(origin, &format!("camera {}", c.id), m);
    if c.params.len() != c.model.params.len() {
        return Err(at(format!(
            "{} takes {} parameters, {} given",
            c.model.name,
            c.model.params.len(),
            c.params.len()
        )));
    }
    if c.width == 0 || c.height == 0 || c.width > u64::from(u32::MAX) || c.height > u64::from(u32::MAX) {
        return Err(at(format!("image size {}x{} is empty or too large", c.width, c.height)));
    }
    if let Some((name, v)) = c.model.params.iter().zip(&c.params).find(|(_, v)| !v.is_finite()) {
        return Err(at(format!("parameter {name} is {v}")));
    }
    Ok(())
}

fn parse_cameras_txt(text: &str, origin: &str) -> Result<Vec<ColmapCamera>, SceneError> {
    let mut out = Vec::new();
    for (no, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let w: Vec<&str> = line.split_whitespace().collect();
        let at = |m: String| err(origin, &format!("line {}", no + 1), m);
        if w.len() < 4 {
            return Err(at(format!("\"{line}\" is not CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]")));
        }
        let model = model_by_name(w[1]).ok_or_else(|| at(format!("unknown camera model {}", w[1])))?;
        let num = |s: &str, what: &str| s.parse::<f64>().map_err(|_| at(format!("{what} \"{s}\" is not a number")));
        let int =
            |s: &str, what: &str| s.parse::<u64>().map_err(|_| at(format!("{what} \"{s}\" is not a whole number")));
        let c = ColmapCamera {
            id: w[0].parse().map_err(|_| at(format!("camera id \"{}\" is not a number", w[0])))?,
            model,
            width: int(w[2], "width")?,
            height: int(w[3], "height")?,
            params: w[4..].iter().map(|s| num(s, "parameter")).collect::<Result<_, _>>()?,
        };
        check_camera(&c, origin)?;
        out.push(c);
    }
    Ok(out)
}

fn parse_images_txt(text: &str, origin: &str) -> Result<Vec<ColmapImage>, SceneError> {
    let mut out = Vec::new();
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim_start().starts_with('#'));
    while let Some((no, line)) = lines.next() {
        if line.trim().is_empty() {
            continue;
        }
        let at = |m: String| err(origin, &format!("line {}", no + 1), m);
        let w: Vec<&str> = line.split_whitespace().collect();
        if w.len() < 10 {
            return Err(at(format!("\"{}\" is not IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME", line.trim())));
        }
        let num = |i: usize| w[i].parse::<f64>().map_err(|_| at(format!("\"{}\" is not a number", w[i])));
        out.push(ColmapImage {
            id: w[0].parse().map_err(|_| at(format!("image id \"{}\" is not a number", w[0])))?,
            q: [num(1)?, num(2)?, num(3)?, num(4)?],
            t: [num(5)?, num(6)?, num(7)?],
            camera: w[8].parse().map_err(|_| at(format!("camera id \"{}\" is not a number", w[8])))?,
            // Names may hold spaces.
            name: w[9..].join(" "),
        });
        // The image's 2D points follow on the next line (possibly empty).
        lines.next();
    }
    Ok(out)
}

/// A little-endian reader over a binary model file that names the file on a short read.
struct Bin<'a> {
    b: &'a [u8],
    at: usize,
    origin: &'a str,
}

impl Bin<'_> {
    fn take(&mut self, n: usize, what: &str) -> Result<&[u8], SceneError> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.b.len()).ok_or_else(|| {
            err(self.origin, what, format!("the file is truncated (at byte {}, {n} more needed)", self.at))
        })?;
        let s = &self.b[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn u64(&mut self, what: &str) -> Result<u64, SceneError> {
        let s = self.take(8, what)?;
        Ok(u64::from_le_bytes([s[0], s[1], s[2], s[3], s[4], s[5], s[6], s[7]]))
    }
    fn i32(&mut self, what: &str) -> Result<i32, SceneError> {
        let s = self.take(4, what)?;
        Ok(i32::from_le_bytes([s[0], s[1], s[2], s[3]]))
    }
    fn f64(&mut self, what: &str) -> Result<f64, SceneError> {
        Ok(f64::from_bits(self.u64(what)?))
    }
    /// A count of records of at least `min_bytes` each, checked against the bytes left.
    fn count(&mut self, min_bytes: usize, what: &str) -> Result<usize, SceneError> {
        let n = self.u64(what)?;
        let left = (self.b.len() - self.at) as u64;
        if n.saturating_mul(min_bytes as u64) > left {
            return Err(err(self.origin, what, format!("{n} records cannot fit the {left} bytes left")));
        }
        Ok(n as usize)
    }
}

fn parse_cameras_bin(b: &[u8], origin: &str) -> Result<Vec<ColmapCamera>, SceneError> {
    let mut r = Bin { b, at: 0, origin };
    let n = r.count(24, "number of cameras")?;
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let what = format!("camera record {i}");
        let id = i64::from(r.i32(&what)?);
        let model_id = r.i32(&what)?;
        let model = MODELS
            .iter()
            .find(|m| m.id == model_id)
            .ok_or_else(|| err(origin, &format!("camera {id}"), format!("unknown camera model id {model_id}")))?;
        let width = r.u64(&what)?;
        let height = r.u64(&what)?;
        let params = (0..model.params.len()).map(|_| r.f64(&what)).collect::<Result<_, _>>()?;
        let c = ColmapCamera { id, model, width, height, params };
        check_camera(&c, origin)?;
        out.push(c);
    }
    if r.at != b.len() {
        return Err(err(origin, "file size", format!("{} bytes follow the {n} cameras", b.len() - r.at)));
    }
    Ok(out)
}

fn parse_images_bin(b: &[u8], origin: &str) -> Result<Vec<ColmapImage>, SceneError> {
    let mut r = Bin { b, at: 0, origin };
    let n = r.count(4 + 7 * 8 + 4 + 1 + 8, "number of images")?;
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let what = format!("image record {i}");
        let id = i64::from(r.i32(&what)?);
        let q = [r.f64(&what)?, r.f64(&what)?, r.f64(&what)?, r.f64(&what)?];
        let t = [r.f64(&what)?, r.f64(&what)?, r.f64(&what)?];
        let camera = i64::from(r.i32(&what)?);
        let rest = &b[r.at..];
        let len = rest
            .iter()
            .position(|&c| c == 0)
            .ok_or_else(|| err(origin, &what, "the image name is not NUL-terminated"))?;
        let name = String::from_utf8_lossy(&rest[..len]).into_owned();
        r.at += len + 1;
        let points = r.count(24, &format!("image {id} points"))?;
        r.take(points * 24, &what)?;
        out.push(ColmapImage { id, q, t, camera, name });
    }
    if r.at != b.len() {
        return Err(err(origin, "file size", format!("{} bytes follow the {n} images", b.len() - r.at)));
    }
    Ok(out)
}

/// Focal lengths, principal point and lens of a camera; an error naming it
/// and its model where srug does not render the model.
fn intrinsics(c: &ColmapCamera, origin: &str) -> Result<(f64, f64, f64, f64, Lens), SceneError> {
    let at = |m: String| err(origin, &format!("camera {}", c.id), m);
    let named: Vec<String> = c.model.params.iter().zip(&c.params).map(|(n, v)| format!("{n}={v}")).collect();
    let refuse = || {
        at(format!(
            "model {} ({}) is a lens srug does not render; undistort the images first (colmap \
             image_undistorter writes PINHOLE cameras)",
            c.model.name,
            named.join(", ")
        ))
    };
    let i = Intrinsics::from_colmap(c.model.name, &c.params).ok_or_else(refuse)?;
    let lens = match i.lens {
        Lens::Fov { omega: 0.0 } => Lens::Pinhole,
        Lens::RadialTangential { k, p } if k.iter().chain(&p).all(|v| *v == 0.0) => Lens::Pinhole,
        lens => lens,
    };
    let ([fx, fy], [cx, cy]) = (i.focal, i.centre);
    if !(fx > 0.0 && fy > 0.0) {
        return Err(at(format!("focal lengths {fx} / {fy} must be positive")));
    }
    Ok((fx, fy, cx, cy, lens))
}

fn to_cameras(
    cameras: &[ColmapCamera],
    mut images: Vec<ColmapImage>,
    c_origin: &str,
    i_origin: &str,
) -> Result<Vec<Camera>, SceneError> {
    if images.is_empty() {
        return Err(err(i_origin, "images", "the model registers no image"));
    }
    images.sort_by(|a, b| a.name.cmp(&b.name));
    let mut out = Vec::with_capacity(images.len());
    for im in &images {
        let at = |m: String| err(i_origin, &format!("image {} ({})", im.id, im.name), m);
        let c = cameras
            .iter()
            .find(|c| c.id == im.camera)
            .ok_or_else(|| at(format!("camera {} is not in {c_origin}", im.camera)))?;
        let (fx, fy, cx, cy, lens) = intrinsics(c, c_origin)?;
        let norm = im.q.iter().map(|v| v * v).sum::<f64>().sqrt();
        if !norm.is_finite() || (norm - 1.0).abs() > 1e-3 || im.t.iter().any(|v| !v.is_finite()) {
            return Err(at(format!(
                "pose q={:?} t={:?} is not a rotation (|q| = {norm:.6}) and a finite translation",
                im.q, im.t
            )));
        }
        let q = DQuat::from_xyzw(im.q[1], im.q[2], im.q[3], im.q[0]).normalize();
        let world_to_camera = DMat3::from_quat(q);
        let rotation = world_to_camera.transpose();
        let centre = -(rotation * DVec3::from(im.t));
        let camera = Camera {
            name: im.name.clone(),
            width: c.width as u32,
            height: c.height as u32,
            rotation: Mat3::from_cols(rotation.x_axis.as_vec3(), rotation.y_axis.as_vec3(), rotation.z_axis.as_vec3()),
            position: Vec3::new(centre.x as f32, centre.y as f32, centre.z as f32),
            projection: Projection::Pinhole { fx: fx as f32, fy: fy as f32, cx: cx as f32, cy: cy as f32 },
            near: DEFAULT_NEAR,
            far: DEFAULT_FAR,
            lens,
        };
        camera.validate().map_err(|e| at(format!("in f32: {e}")))?;
        out.push(camera);
    }
    Ok(out)
}
