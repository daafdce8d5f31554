//! An analytic city block for measuring shadows against the truth.
//!
//! A ground and box buildings (and a thin pole, for contact shadows), their
//! surfaces sampled with flat Gaussians as a trained scene holds them, three
//! street cameras at 704×192 and three suns. Because the geometry is exact,
//! the true sun visibility of every pixel comes from ray casting: the pixel's
//! ray meets the first surface, and a ray from there toward the sun meets a
//! box or not ([`BlockCity::true_visibility`]). Nothing of srug's splatting
//! enters the truth, so [`crate::shadow::accuracy`] measures srug's whole
//! shadow chain (receiver depth, map depth, bias, filtering) against it.
//!
//! Two samplings: [`BlockSplats::Ideal`] puts identical discs on a regular
//! grid, exactly on the surfaces; [`BlockSplats::Rough`] jitters positions
//! in and off the plane, tilts normals, varies sizes, anisotropy and opacity,
//! as optimisation leaves them.

use glam::{Mat3, Quat, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

use super::demo::Aabb;
use super::Scene;
use crate::camera::Camera;
use crate::error::{Error, Result};

/// How the surfaces are sampled with Gaussians.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BlockSplats {
    /// Identical discs on a regular grid, exactly on the surfaces.
    Ideal,
    /// Jittered in and off the plane, tilted, of varied size, shape and opacity.
    Rough,
}

/// What to generate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlockOptions {
    /// Surface sampling.
    pub splats: BlockSplats,
    /// Distance between neighbouring Gaussians, metres (0.05 to 2).
    pub spacing: f32,
    /// Random seed of the rough sampling.
    pub seed: u64,
}

impl Default for BlockOptions {
    fn default() -> Self {
        Self { splats: BlockSplats::Ideal, spacing: 0.25, seed: 11 }
    }
}

/// A named sun: a unit vector toward it.
#[derive(Clone, Debug, PartialEq)]
pub struct BlockSun {
    /// "low", "afternoon" or "high".
    pub name: &'static str,
    /// Unit vector toward the sun.
    pub direction: Vec3,
}

/// The block's Gaussians, exact geometry, cameras and suns.
#[derive(Clone, Debug)]
pub struct BlockCity {
    /// The Gaussians (SH degree 0, grey).
    pub scene: Scene,
    /// The ground rectangle at z = 0: (x min, y min), (x max, y max).
    pub ground: ([f32; 2], [f32; 2]),
    /// The buildings and the pole.
    pub boxes: Vec<Aabb>,
    /// Three street cameras, 704×192.
    pub cameras: Vec<Camera>,
    /// Suns at 15°, 35° and 60° elevation.
    pub suns: Vec<BlockSun>,
}

const GROUND: ([f32; 2], [f32; 2]) = ([-30.0, -20.0], [50.0, 20.0]);

/// A unit vector toward a sun at `azimuth` (degrees from +x toward +y) and `elevation` degrees.
fn toward(azimuth: f32, elevation: f32) -> Vec3 {
    let (a, e) = (azimuth.to_radians(), elevation.to_radians());
    Vec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin())
}

/// Generates the block.
pub fn block_city(options: &BlockOptions) -> Result<BlockCity> {
    if !(0.05..=2.0).contains(&options.spacing) {
        return Err(Error::invalid(format!("block spacing {} m", options.spacing), "is not in [0.05, 2]"));
    }
    let boxes = vec![
        Aabb { min: Vec3::new(-5.0, -18.0, 0.0), max: Vec3::new(10.0, -7.0, 12.0) },
        Aabb { min: Vec3::new(14.0, -18.0, 0.0), max: Vec3::new(30.0, -7.0, 20.0) },
        Aabb { min: Vec3::new(0.0, 7.0, 0.0), max: Vec3::new(12.0, 16.0, 8.0) },
        Aabb { min: Vec3::new(18.0, 7.0, 0.0), max: Vec3::new(36.0, 16.0, 25.0) },
        // A pole on the pavement: a thin occluder whose shadow starts at its foot.
        Aabb { min: Vec3::new(20.0, -4.15, 0.0), max: Vec3::new(20.3, -3.85, 6.0) },
    ];
    // Rectangles origin + a·u + b·v, normal u × v: the ground and each box's walls and roof.
    let (g0, g1) = GROUND;
    let mut rects =
        vec![(Vec3::new(g0[0], g0[1], 0.0), Vec3::new(g1[0] - g0[0], 0.0, 0.0), Vec3::new(0.0, g1[1] - g0[1], 0.0))];
    for b in &boxes {
        let (a, d) = (b.min, b.max - b.min);
        let (x, y, z) = (Vec3::new(d.x, 0.0, 0.0), Vec3::new(0.0, d.y, 0.0), Vec3::new(0.0, 0.0, d.z));
        rects.extend([(a, x, z), (a + y + x, -x, z), (a + y, -y, z), (a + x, y, z), (a + z, x, y)]);
    }
    let s = options.spacing;
    let mut rng = Pcg64Mcg::seed_from_u64(options.seed);
    let mut scene = Scene { sh_degree: 0, ..Scene::default() };
    let mut normals = Vec::new();
    // Mid grey: colour 0.5 − 0.5 is a zero DC coefficient.
    let grey = 0.0f32;
    for (origin, u, v) in rects {
        let (cols, rows) = ((u.length() / s).round().max(1.0) as usize, (v.length() / s).round().max(1.0) as usize);
        let (ud, vd) = (u.normalize(), v.normalize());
        let normal = u.cross(v).normalize();
        for j in 0..rows {
            for i in 0..cols {
                let (mut a, mut b) = ((i as f32 + 0.5) / cols as f32, (j as f32 + 0.5) / rows as f32);
                let (mut n, mut tangent, mut scale, mut opacity) =
                    (normal, ud, Vec3::new(0.6 * s, 0.6 * s, 0.01 * s), 0.95);
                let mut offset = 0.0;
                if options.splats == BlockSplats::Rough {
                    a = (a + rng.random_range(-0.35..0.35f32) / cols as f32).clamp(0.0, 1.0);
                    b = (b + rng.random_range(-0.35..0.35f32) / rows as f32).clamp(0.0, 1.0);
                    offset = rng.random_range(-0.1..0.1f32) * s;
                    let tilt = rng.random_range(0.0..8.0f32).to_radians();
                    let around = rng.random_range(0.0..std::f32::consts::TAU);
                    let axis = ud * around.cos() + vd * around.sin();
                    n = Quat::from_axis_angle(axis, tilt) * normal;
                    let spin = rng.random_range(0.0..std::f32::consts::PI);
                    tangent = Quat::from_axis_angle(n, spin) * (ud - n * ud.dot(n)).normalize();
                    scale = Vec3::new(
                        rng.random_range(0.45..0.9f32) * s,
                        rng.random_range(0.3..0.7f32) * s,
                        rng.random_range(0.02..0.08f32) * s,
                    );
                    opacity = rng.random_range(0.5..0.99f32);
                }
                let p = origin + u * a + v * b + normal * offset;
                let q = Quat::from_mat3(&Mat3::from_cols(tangent, n.cross(tangent), n)).normalize();
                scene.means.push(p.to_array());
                normals.push(n.to_array());
                scene.log_scales.push(scale.to_array().map(f32::ln));
                scene.rotations.push([q.w, q.x, q.y, q.z]);
                scene.opacity_logits.push((opacity / (1.0 - opacity)).ln());
                scene.sh.extend([grey; 3]);
            }
        }
    }
    scene.normals = Some(normals);
    scene.validate("analytic block")?;
    let mut cameras = Vec::new();
    for (i, (eye, target)) in [
        (Vec3::new(-20.0, -2.0, 1.6), Vec3::new(10.0, -2.0, 1.3)),
        (Vec3::new(4.0, 2.0, 1.6), Vec3::new(28.0, -8.0, 4.0)),
        (Vec3::new(44.0, 1.0, 1.6), Vec3::new(14.0, 3.0, 1.0)),
    ]
    .into_iter()
    .enumerate()
    {
        let mut camera = Camera::look_at(eye, target, Vec3::Z, 90.0, 704, 192)?;
        camera.name = format!("block_{i:02}");
        cameras.push(camera);
    }
    let suns = vec![
        BlockSun { name: "low", direction: toward(-150.0, 15.0) },
        BlockSun { name: "afternoon", direction: toward(-120.0, 35.0) },
        BlockSun { name: "high", direction: toward(-70.0, 60.0) },
    ];
    Ok(BlockCity { scene, ground: GROUND, boxes, cameras, suns })
}

impl BlockCity {
    /// The first surface the ray `o + t·d` (t > 0) meets: its distance t
    /// (in units of |d|) and outward normal; `None` where it meets nothing.
    pub fn hit(&self, o: Vec3, d: Vec3) -> Option<(f32, Vec3)> {
        let mut best: Option<(f32, Vec3)> = None;
        if d.z.abs() > 1e-12 {
            let t = -o.z / d.z;
            let p = o + d * t;
            let (g0, g1) = self.ground;
            if t > 0.0 && (g0[0]..=g1[0]).contains(&p.x) && (g0[1]..=g1[1]).contains(&p.y) {
                best = Some((t, Vec3::Z));
            }
        }
        for b in &self.boxes {
            if let Some((t, n)) = box_entry(b, o, d) {
                if best.is_none_or(|(bt, _)| t < bt) {
                    best = Some((t, n));
                }
            }
        }
        best
    }

    /// The true sun visibility at each pixel centre of `camera` (row-major):
    /// `Some(true)` lit, `Some(false)` in shadow, `None` where the pixel sees
    /// no surface or one facing away from the sun (lit or not, it gets no
    /// sun light, so no shadow test can be wrong there). `sun` points toward the sun.
    pub fn true_visibility(&self, camera: &Camera, sun: Vec3) -> Vec<Option<bool>> {
        let (w, h) = (camera.width as usize, camera.height as usize);
        let mut out = vec![None; w * h];
        for (p, v) in out.iter_mut().enumerate() {
            let px = [(p % w) as f64 + 0.5, (p / w) as f64 + 0.5];
            let Some(dir) = camera.pixel_direction(px) else { continue };
            let d = camera.rotation * Vec3::new(dir[0] as f32, dir[1] as f32, dir[2] as f32);
            let Some((t, n)) = self.hit(camera.position, d) else { continue };
            if n.dot(sun) <= 0.0 {
                continue;
            }
            let point = camera.position + d * t + n * 1e-3;
            *v = Some(!self.boxes.iter().any(|b| box_entry(b, point, sun).is_some()));
        }
        out
    }
}

/// The block's shadow-completion problem: the tallest building (x 18–36,
/// y 7–16, 25 m) removed; four street cameras at y = 5.5 looking south, so
/// no camera sees where it stood; a northern sun (azimuth 100° from +x
/// toward +y, 40° up) throws its shadow across the street they see.
#[derive(Clone, Debug)]
pub struct BlockCompletion {
    /// The whole block (its truth has the building).
    pub city: BlockCity,
    /// The block's Gaussians without the building's (those within 0.3 m of it).
    pub without: Scene,
    /// The removed building.
    pub removed: Aabb,
    /// Unit vector toward the sun.
    pub sun: Vec3,
    /// The street cameras.
    pub cameras: Vec<Camera>,
}

/// Generates [`BlockCompletion`] with cameras of `width`×`height` (90° across).
pub fn block_completion(options: &BlockOptions, width: u32, height: u32) -> Result<BlockCompletion> {
    let city = block_city(options)?;
    let removed = city.boxes[3];
    let without = city.scene.without_box(&removed, 0.3);
    let mut cameras = Vec::new();
    for (i, (x, tx)) in [(6.0, 14.0), (14.0, 22.0), (22.0, 30.0), (30.0, 24.0)].into_iter().enumerate() {
        let mut c = Camera::look_at(Vec3::new(x, 5.5, 1.6), Vec3::new(tx, -7.0, 2.0), Vec3::Z, 90.0, width, height)?;
        c.name = format!("street_{i}");
        cameras.push(c);
    }
    Ok(BlockCompletion { city, without, removed, sun: toward(100.0, 40.0), cameras })
}

impl BlockCity {
    /// The true visibility as a shadow detector marks a photograph: lit 1,
    /// shadowed 0, surfaces facing away from the sun 0 (they are dark), the
    /// sky 1 (not shadow).
    pub fn shadow_target(&self, camera: &Camera, sun: Vec3) -> Vec<f32> {
        let w = camera.width as usize;
        let truth = self.true_visibility(camera, sun);
        truth
            .iter()
            .enumerate()
            .map(|(p, t)| match t {
                Some(lit) => f32::from(u8::from(*lit)),
                None => {
                    let Some(dir) = camera.pixel_direction([(p % w) as f64 + 0.5, (p / w) as f64 + 0.5]) else {
                        return 1.0;
                    };
                    let d = camera.rotation * Vec3::new(dir[0] as f32, dir[1] as f32, dir[2] as f32);
                    if self.hit(camera.position, d).is_some() {
                        0.0
                    } else {
                        1.0
                    }
                }
            })
            .collect()
    }
}

/// Where the ray `o + t·d` (t > 0) enters the box from outside: t and the
/// outward normal of the face it crosses.
fn box_entry(b: &Aabb, o: Vec3, d: Vec3) -> Option<(f32, Vec3)> {
    let mut near = f32::NEG_INFINITY;
    let mut far = f32::INFINITY;
    let mut normal = Vec3::ZERO;
    for axis in 0..3 {
        let (lo, hi, oa, da) = (b.min[axis], b.max[axis], o[axis], d[axis]);
        if da.abs() < 1e-12 {
            if oa < lo || oa > hi {
                return None;
            }
            continue;
        }
        let (t0, t1) = ((lo - oa) / da, (hi - oa) / da);
        let (ta, tb) = if t0 < t1 { (t0, t1) } else { (t1, t0) };
        if ta > near {
            near = ta;
            normal = Vec3::ZERO;
            normal[axis] = if da > 0.0 { -1.0 } else { 1.0 };
        }
        far = far.min(tb);
    }
    (near <= far && near > 0.0).then_some((near, normal))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, reason = "tests")]
    use super::*;

    #[test]
    fn rays_meet_the_ground_and_the_boxes_where_the_geometry_says() {
        let city = block_city(&BlockOptions { spacing: 1.0, ..BlockOptions::default() }).unwrap();
        // Straight down onto the ground in the street.
        let (t, n) = city.hit(Vec3::new(0.0, 0.0, 10.0), -Vec3::Z).unwrap();
        assert!((t - 10.0).abs() < 1e-5 && n == Vec3::Z);
        // Along +y into the first building's street-facing wall at y = -7.
        let (t, n) = city.hit(Vec3::new(0.0, 0.0, 5.0), -Vec3::Y).unwrap();
        assert!((t - 7.0).abs() < 1e-5 && n == Vec3::Y, "{t} {n}");
        // Up into the sky.
        assert!(city.hit(Vec3::new(0.0, 0.0, 5.0), Vec3::Z).is_none());
        // A point at the foot of the pole, on its far side from the sun, is shadowed.
        let sun = toward(180.0, 30.0);
        let behind = Vec3::new(20.4, -4.0, 1e-3);
        assert!(city.boxes.iter().any(|b| box_entry(b, behind, sun).is_some()));
        let before = Vec3::new(19.0, -4.0, 1e-3);
        assert!(!city.boxes.iter().any(|b| box_entry(b, before, sun).is_some()));
        assert!(block_city(&BlockOptions { spacing: 0.0, ..BlockOptions::default() }).is_err());
    }
}
