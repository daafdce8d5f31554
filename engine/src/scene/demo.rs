//! The built-in demo: a procedural urban street, generated from a seed and a
//! Gaussian count, with full relighting attributes and default cameras.
//!
//! World axes: z up, the street runs along +x. A road with lane markings,
//! raised sidewalks, building blocks on both sides (facades with metallic,
//! low-roughness windows), cars and trees. A tall tower stands behind every
//! default camera, out of view, and the default sun throws its shadow down the
//! street into view: the case the SRUG paper is about (shadows of geometry no
//! camera saw). Gaussians are flat discs on the surfaces, spread over them by
//! area, so the same layout scales from ten thousand to millions of Gaussians.
//!
//! Attributes: albedo, roughness and metallic come from the material; the
//! visibility V_f is exact (a ray toward the sun against the analytic boxes and
//! spheres); ambient occlusion is a simple height/proximity heuristic; the SH
//! colour bakes the sun and sky lighting in, as a capture under that sun would.

use glam::{Mat3, Quat, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

use super::{sh_coefficients, Materials, Scene, SH_C0};
use crate::camera::Camera;
use crate::error::{Error, Result};

/// What to generate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DemoOptions {
    /// Random seed; the same seed and count give the same scene, bit for bit.
    pub seed: u64,
    /// Number of Gaussians (at least 1000).
    pub gaussians: usize,
    /// SH degree, 0 to 3.
    pub sh_degree: u32,
}

impl Default for DemoOptions {
    fn default() -> Self {
        Self { seed: 7, gaussians: 200_000, sh_degree: 1 }
    }
}

/// An axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Minimum corner.
    pub min: Vec3,
    /// Maximum corner.
    pub max: Vec3,
}

impl Aabb {
    /// The eight corners.
    pub fn corners(&self) -> [Vec3; 8] {
        let (a, b) = (self.min, self.max);
        [0, 1, 2, 3, 4, 5, 6, 7].map(|i| {
            Vec3::new(
                if i & 1 == 0 { a.x } else { b.x },
                if i & 2 == 0 { a.y } else { b.y },
                if i & 4 == 0 { a.z } else { b.z },
            )
        })
    }

    /// Whether the ray `o + t·d`, t > 0, hits the box.
    pub fn hit(&self, o: Vec3, d: Vec3) -> bool {
        let inv = d.recip();
        let t0 = (self.min - o) * inv;
        let t1 = (self.max - o) * inv;
        let near = t0.min(t1).max_element();
        let far = t0.max(t1).min_element();
        far >= near.max(0.0)
    }
}

/// The demo scene with its cameras and lighting.
#[derive(Clone, Debug)]
pub struct DemoCity {
    /// The Gaussians.
    pub scene: Scene,
    /// Default cameras along the street, 704×192.
    pub cameras: Vec<Camera>,
    /// Unit vector toward the default sun.
    pub sun_direction: Vec3,
    /// The tall building outside every default camera's view.
    pub offscreen_tower: Aabb,
    /// Every occluding box (buildings, tower, cars, trunks).
    pub occluders: Vec<Aabb>,
}

#[derive(Clone, Copy, Debug)]
enum Material {
    Road,
    Sidewalk,
    Facade { color: Vec3, seed: u32 },
    Roof,
    Tower,
    CarBody { color: Vec3 },
    Trunk,
    Leaves,
}

#[derive(Clone, Copy, Debug)]
enum Shape {
    /// A rectangle `origin + a·u + b·v`, a, b ∈ [0, 1]; normal u × v.
    Rect { origin: Vec3, u: Vec3, v: Vec3 },
    /// A sphere.
    Sphere { center: Vec3, radius: f32 },
}

#[derive(Clone, Copy, Debug)]
struct Surface {
    shape: Shape,
    material: Material,
}

impl Surface {
    fn area(&self) -> f32 {
        match self.shape {
            Shape::Rect { u, v, .. } => u.cross(v).length(),
            Shape::Sphere { radius, .. } => 4.0 * std::f32::consts::PI * radius * radius,
        }
    }
}

/// Surface properties at a point: albedo, roughness, metallic.
fn shade(material: Material, p: Vec3, rng: &mut Pcg64Mcg) -> (Vec3, f32, f32) {
    let jitter = |rng: &mut Pcg64Mcg, c: Vec3, amount: f32| {
        (c * (1.0 + rng.random_range(-amount..amount))).clamp(Vec3::splat(0.01), Vec3::splat(0.98))
    };
    match material {
        Material::Road => {
            let marking = p.y.abs() < 0.12 && (p.x.rem_euclid(6.0)) < 3.0;
            if marking {
                (jitter(rng, Vec3::splat(0.8), 0.05), 0.6, 0.0)
            } else {
                (jitter(rng, Vec3::splat(0.08), 0.2), 0.9, 0.0)
            }
        }
        Material::Sidewalk => (jitter(rng, Vec3::new(0.45, 0.44, 0.42), 0.1), 0.8, 0.0),
        Material::Roof => (jitter(rng, Vec3::splat(0.25), 0.15), 0.85, 0.0),
        Material::Tower => (jitter(rng, Vec3::new(0.5, 0.52, 0.55), 0.05), 0.4, 0.3),
        Material::Facade { color, seed } => {
            // Windows: 1.4 m × 1.6 m every 3 m, from the first floor up.
            let along = if seed % 2 == 0 { p.x } else { p.x + p.y };
            let wx = (along + seed as f32 * 0.37).rem_euclid(3.0);
            let wz = (p.z - 1.0).rem_euclid(3.0);
            let window = p.z > 3.5 && (0.8..2.2).contains(&wx) && (0.7..2.3).contains(&wz);
            if window {
                (jitter(rng, Vec3::new(0.15, 0.2, 0.28), 0.1), 0.08, 0.9)
            } else {
                (jitter(rng, color, 0.08), 0.75, 0.0)
            }
        }
        Material::CarBody { color } => {
            if p.z > 1.0 {
                (jitter(rng, Vec3::new(0.05, 0.06, 0.08), 0.1), 0.05, 0.8)
            } else {
                (jitter(rng, color, 0.05), 0.3, 0.7)
            }
        }
        Material::Trunk => (jitter(rng, Vec3::new(0.25, 0.16, 0.1), 0.1), 0.9, 0.0),
        Material::Leaves => (jitter(rng, Vec3::new(0.12, 0.3, 0.08), 0.25), 0.7, 0.0),
    }
}

fn logit(p: f32) -> f32 {
    let p = p.clamp(1e-3, 1.0 - 1e-3);
    (p / (1.0 - p)).ln()
}

/// Adds the four walls and the roof of a box.
fn add_box(out: &mut Vec<Surface>, b: Aabb, walls: Material, roof: Material) {
    let (a, c) = (b.min, b.max);
    let d = c - a;
    let (x, y, z) = (Vec3::new(d.x, 0.0, 0.0), Vec3::new(0.0, d.y, 0.0), Vec3::new(0.0, 0.0, d.z));
    let rect = |origin: Vec3, u: Vec3, v: Vec3, material| Surface { shape: Shape::Rect { origin, u, v }, material };
    out.push(rect(a, x, z, walls)); // facing -y
    out.push(rect(a + y + x, -x, z, walls)); // facing +y
    out.push(rect(a + y, -y, z, walls)); // facing -x
    out.push(rect(a + x, y, z, walls)); // facing +x
    out.push(rect(a + z, x, y, roof)); // facing +z
}

/// Generates the demo city.
pub fn demo_city(options: &DemoOptions) -> Result<DemoCity> {
    if options.gaussians < 1000 {
        return Err(Error::invalid(format!("demo of {} Gaussians", options.gaussians), "needs at least 1000"));
    }
    if options.sh_degree > 3 {
        return Err(Error::invalid(format!("SH degree {}", options.sh_degree), "is not supported (0 to 3)"));
    }
    crate::io::limits()
        .gaussians(options.gaussians as u64)
        .map_err(|why| Error::invalid(format!("demo of {} Gaussians", options.gaussians), why))?;
    let mut rng = Pcg64Mcg::seed_from_u64(options.seed);
    let mut surfaces: Vec<Surface> = Vec::new();
    let mut occluders: Vec<Aabb> = Vec::new();
    let mut canopies: Vec<(Vec3, f32)> = Vec::new();
    let (x0, x1) = (-110.0f32, 160.0f32);

    // Ground: road and raised sidewalks.
    let rect = |origin: Vec3, u: Vec3, v: Vec3, material| Surface { shape: Shape::Rect { origin, u, v }, material };
    surfaces.push(rect(
        Vec3::new(x0, -5.0, 0.0),
        Vec3::new(x1 - x0, 0.0, 0.0),
        Vec3::new(0.0, 10.0, 0.0),
        Material::Road,
    ));
    for side in [-1.0f32, 1.0] {
        let y = if side > 0.0 { 5.0 } else { -8.0 };
        surfaces.push(rect(
            Vec3::new(x0, y, 0.15),
            Vec3::new(x1 - x0, 0.0, 0.0),
            Vec3::new(0.0, 3.0, 0.0),
            Material::Sidewalk,
        ));
    }

    // Building blocks on both sides.
    for side in [-1.0f32, 1.0] {
        let mut x = -75.0f32;
        while x < x1 - 10.0 {
            let width = rng.random_range(12.0..25.0f32).min(x1 - x);
            let depth = rng.random_range(12.0..18.0f32);
            let height = rng.random_range(10.0..35.0f32);
            let (ya, yb) = if side > 0.0 { (8.0, 8.0 + depth) } else { (-8.0 - depth, -8.0) };
            let b = Aabb { min: Vec3::new(x, ya, 0.0), max: Vec3::new(x + width, yb, height) };
            let color =
                Vec3::new(rng.random_range(0.35..0.75), rng.random_range(0.3..0.65), rng.random_range(0.25..0.6));
            add_box(&mut surfaces, b, Material::Facade { color, seed: rng.random_range(0..1000) }, Material::Roof);
            occluders.push(b);
            x += width + rng.random_range(2.0..4.0f32);
        }
    }

    // The tall tower behind the cameras, across the street's end.
    let tower = Aabb { min: Vec3::new(-100.0, -12.0, 0.0), max: Vec3::new(-85.0, 12.0, 80.0) };
    add_box(&mut surfaces, tower, Material::Tower, Material::Roof);
    occluders.push(tower);

    // Cars on the road.
    for i in 0..8 {
        let x = -30.0 + i as f32 * 18.0 + rng.random_range(-4.0..4.0f32);
        let y = if i % 2 == 0 { -2.5 } else { 2.5 };
        let body = Aabb { min: Vec3::new(x, y - 0.9, 0.2), max: Vec3::new(x + 4.2, y + 0.9, 1.5) };
        let color = [
            Vec3::new(0.7, 0.05, 0.05),
            Vec3::new(0.05, 0.15, 0.6),
            Vec3::new(0.8, 0.8, 0.8),
            Vec3::new(0.1, 0.1, 0.1),
        ][i % 4];
        add_box(&mut surfaces, body, Material::CarBody { color }, Material::CarBody { color });
        occluders.push(body);
    }

    // Trees on the sidewalks.
    for side in [-1.0f32, 1.0] {
        for i in 0..8 {
            let x = -35.0 + i as f32 * 22.0 + rng.random_range(-3.0..3.0f32);
            let y = side * 6.5;
            let trunk = Aabb { min: Vec3::new(x - 0.15, y - 0.15, 0.15), max: Vec3::new(x + 0.15, y + 0.15, 3.5) };
            add_box(&mut surfaces, trunk, Material::Trunk, Material::Trunk);
            occluders.push(trunk);
            let radius = rng.random_range(1.6..2.4f32);
            let center = Vec3::new(x, y, 3.5 + radius * 0.8);
            surfaces.push(Surface { shape: Shape::Sphere { center, radius }, material: Material::Leaves });
            canopies.push((center, radius));
        }
    }

    // Sun: from the west (behind the cameras), 25° up, slightly from the south.
    let elevation = 25.0f32.to_radians();
    let sun_direction = Vec3::new(-elevation.cos(), -0.05 * elevation.cos(), elevation.sin()).normalize();

    // Gaussians per surface, proportional to area (largest remainder).
    let total_area: f32 = surfaces.iter().map(Surface::area).sum();
    let n = options.gaussians;
    let shares: Vec<f64> = surfaces.iter().map(|s| f64::from(s.area() / total_area) * n as f64).collect();
    let mut counts: Vec<usize> = shares.iter().map(|s| s.floor() as usize).collect();
    let mut order: Vec<usize> = (0..surfaces.len()).collect();
    order.sort_by(|&a, &b| (shares[b] - shares[b].floor()).total_cmp(&(shares[a] - shares[a].floor())));
    let missing = n - counts.iter().sum::<usize>();
    for &i in order.iter().take(missing) {
        counts[i] += 1;
    }

    let k = sh_coefficients(options.sh_degree);
    let mut scene = Scene { sh_degree: options.sh_degree, ..Scene::default() };
    let mut normals = Vec::with_capacity(n);
    let mut m = Materials {
        albedo: Some(Vec::with_capacity(n)),
        roughness: Some(Vec::with_capacity(n)),
        metallic: Some(Vec::with_capacity(n)),
        ao: Some(Vec::with_capacity(n)),
        visibility: Some(Vec::with_capacity(n)),
    };
    scene.sh.reserve(n * k * 3);
    let occluded = |p: Vec3| {
        occluders.iter().any(|b| b.hit(p, sun_direction))
            || canopies.iter().any(|&(c, r)| {
                let oc = p - c;
                let b = oc.dot(sun_direction);
                let disc = b * b - (oc.length_squared() - r * r);
                disc >= 0.0 && -b + disc.sqrt() > 0.0
            })
    };
    for (surface, &count) in surfaces.iter().zip(&counts) {
        if count == 0 {
            continue;
        }
        let spacing = (surface.area() / count as f32).sqrt();
        let (cols, rows) = match surface.shape {
            Shape::Rect { u, v, .. } => {
                let cols = ((count as f32 * u.length() / v.length()).sqrt().ceil() as usize).clamp(1, count);
                (cols, count.div_ceil(cols))
            }
            Shape::Sphere { .. } => (count, 1),
        };
        for j in 0..count {
            let (p, normal, tangent) = match surface.shape {
                Shape::Rect { origin, u, v } => {
                    let (a, b) = (
                        ((j % cols) as f32 + rng.random::<f32>()) / cols as f32,
                        ((j / cols) as f32 + rng.random::<f32>()) / rows as f32,
                    );
                    (origin + u * a + v * b.min(1.0), u.cross(v).normalize(), u.normalize())
                }
                Shape::Sphere { center, radius } => {
                    // Fibonacci sphere with jitter.
                    let t = (j as f32 + 0.5) / count as f32;
                    let z = 1.0 - 2.0 * t;
                    let phi = j as f32 * 2.399_963 + rng.random::<f32>() * 0.2;
                    let r = (1.0 - z * z).max(0.0).sqrt();
                    let nrm = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                    (center + nrm * radius, nrm, nrm.any_orthonormal_vector())
                }
            };
            let bitangent = normal.cross(tangent);
            let (albedo, roughness, metallic) = shade(surface.material, p, &mut rng);
            let visible = !occluded(p + normal * 0.05);
            let ao = match surface.material {
                Material::Road | Material::Sidewalk => 0.7 + 0.3 * ((p.y.abs() - 5.0).abs().min(3.0) / 3.0),
                Material::Facade { .. } | Material::Tower => 0.55 + 0.45 * (p.z / 6.0).min(1.0),
                Material::Leaves => 0.6 + 0.4 * normal.z.max(0.0),
                _ => 0.85,
            };
            let sun = if visible { normal.dot(sun_direction).max(0.0) } else { 0.0 };
            let radiance = albedo * (0.9 * sun + 0.35 * ao);
            let color = radiance.max(Vec3::ZERO).powf(1.0 / 2.2).min(Vec3::ONE);

            let flat = match surface.shape {
                Shape::Rect { .. } => (spacing * 0.02).max(0.003),
                Shape::Sphere { .. } => spacing * 0.3,
            };
            let scale = Vec3::new(spacing * 0.6, spacing * 0.6, flat) * rng.random_range(0.9..1.1f32);
            let q = Quat::from_mat3(&Mat3::from_cols(tangent, bitangent, normal)).normalize();
            scene.means.push(p.to_array());
            normals.push(normal.to_array());
            scene.log_scales.push(scale.to_array().map(f32::ln));
            scene.rotations.push([q.w, q.x, q.y, q.z]);
            scene.opacity_logits.push(logit(rng.random_range(0.9..0.99f32)));
            for c in 0..3 {
                scene.sh.push((color[c] - 0.5) / SH_C0);
            }
            for _ in 1..k {
                let glint = if metallic > 0.5 { 0.06 } else { 0.01 };
                for _ in 0..3 {
                    scene.sh.push(rng.random_range(-glint..glint));
                }
            }
            if let (Some(a), Some(r), Some(mt), Some(o), Some(v)) =
                (&mut m.albedo, &mut m.roughness, &mut m.metallic, &mut m.ao, &mut m.visibility)
            {
                a.push(albedo.to_array().map(logit));
                r.push(logit(roughness));
                mt.push(logit(metallic));
                o.push(logit(ao));
                v.push(logit(if visible { 0.98 } else { 0.02 }));
            }
        }
    }
    scene.normals = Some(normals);
    scene.materials = m;
    scene.validate("demo city")?;

    let mut cameras = Vec::new();
    for (i, x) in [-40.0f32, -20.0, 0.0, 20.0].into_iter().enumerate() {
        let eye = Vec3::new(x, -2.0, 1.6);
        let mut cam = Camera::look_at(eye, eye + Vec3::new(30.0, 0.0, -0.3), Vec3::Z, 90.0, 704, 192)?;
        cam.name = format!("street_{i:02}");
        cameras.push(cam);
    }
    Ok(DemoCity { scene, cameras, sun_direction, offscreen_tower: tower, occluders })
}
