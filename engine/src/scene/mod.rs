//! Scenes of 3D Gaussians: the data model, its GPU upload and the demo city
//! (files are read and written by [`crate::io`]).
//!
//! Parameters are stored the way trainers write them, **before activation**:
//! opacity as a logit, scale as a log, rotation as an unnormalized quaternion
//! (w first), colour as spherical-harmonic coefficients, and the optional
//! relighting attributes as logits (activated with a sigmoid). The stages that
//! consume a scene activate on the GPU ([`activate`]).
//!
//! Invariant: a [`Scene`] that passed [`Scene::validate`] has consistent array
//! lengths, finite values and non-zero quaternions; every loader validates.

pub mod activate;
pub mod blocks;
pub mod demo;
mod layout;
pub mod order;

use std::fmt;

pub use crate::camera::{Camera, Projection};

/// A malformed scene or camera file: what is wrong and where.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SceneError {
    /// The file (or `"<memory>"`).
    pub path: String,
    /// Zero-based data row (Gaussian or camera index), when one is at fault.
    pub row: Option<usize>,
    /// The property or field at fault, when one is.
    pub property: Option<String>,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path)?;
        if let Some(row) = self.row {
            write!(f, ": row {row}")?;
        }
        if let Some(p) = &self.property {
            write!(f, ", property {p}")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for SceneError {}

impl SceneError {
    /// An error about the whole file.
    pub fn file(path: &str, message: impl Into<String>) -> Self {
        Self { path: path.to_string(), row: None, property: None, message: message.into() }
    }

    /// An error about one value.
    pub fn at(path: &str, row: usize, property: &str, message: impl Into<String>) -> Self {
        Self { path: path.to_string(), row: Some(row), property: Some(property.to_string()), message: message.into() }
    }
}

/// Optional per-Gaussian relighting attributes, stored as logits.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Materials {
    /// Base colour (diffuse albedo), RGB logits.
    pub albedo: Option<Vec<[f32; 3]>>,
    /// Roughness logit.
    pub roughness: Option<Vec<f32>>,
    /// Metallic logit.
    pub metallic: Option<Vec<f32>>,
    /// Ambient-occlusion logit.
    pub ao: Option<Vec<f32>>,
    /// Fixed sun-visibility logit (the paper's V_f).
    pub visibility: Option<Vec<f32>>,
}

/// Which attribute groups a scene has, so later stages run only what it requires.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AttributeGroups {
    /// Stored normals (nx, ny, nz).
    pub normals: bool,
    /// Albedo.
    pub albedo: bool,
    /// Roughness.
    pub roughness: bool,
    /// Metallic.
    pub metallic: bool,
    /// Ambient occlusion.
    pub ao: bool,
    /// Fixed visibility.
    pub visibility: bool,
}

impl AttributeGroups {
    /// Whether the scene can be shaded (needs at least an albedo).
    pub fn shadeable(&self) -> bool {
        self.albedo
    }

    /// Names of the groups present, for summaries.
    pub fn names(&self) -> Vec<&'static str> {
        [
            (self.normals, "normals"),
            (self.albedo, "albedo"),
            (self.roughness, "roughness"),
            (self.metallic, "metallic"),
            (self.ao, "ao"),
            (self.visibility, "visibility"),
        ]
        .into_iter()
        .filter_map(|(on, n)| on.then_some(n))
        .collect()
    }
}

/// Number of SH coefficients per channel for a degree.
pub fn sh_coefficients(degree: u32) -> usize {
    ((degree + 1) * (degree + 1)) as usize
}

/// The SH band-0 constant: colour = C0·dc + 0.5.
pub const SH_C0: f32 = 0.282_094_8;

/// A scene of 3D Gaussians, parameters stored before activation.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Scene {
    /// Centres.
    pub means: Vec<[f32; 3]>,
    /// Stored normals, when the file has them.
    pub normals: Option<Vec<[f32; 3]>>,
    /// Spherical-harmonic degree, 0 to 3.
    pub sh_degree: u32,
    /// SH coefficients, coefficient-major with RGB innermost:
    /// `sh[(g * K + k) * 3 + c]` with `K = (degree + 1)²`.
    pub sh: Vec<f32>,
    /// Opacity logits.
    pub opacity_logits: Vec<f32>,
    /// Log scales along the local axes.
    pub log_scales: Vec<[f32; 3]>,
    /// Rotations as quaternions (w, x, y, z), not necessarily normalized.
    pub rotations: Vec<[f32; 4]>,
    /// Relighting attributes.
    pub materials: Materials,
    /// Names of properties a loader found but does not use.
    pub extra_properties: Vec<String>,
}

/// Axis-aligned bounds of the Gaussian centres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    /// Minimum corner.
    pub min: [f32; 3],
    /// Maximum corner.
    pub max: [f32; 3],
}

impl Bounds {
    /// The smallest bounds holding both.
    pub fn union(&self, other: &Bounds) -> Bounds {
        let pick = |a: [f32; 3], b: [f32; 3], f: fn(f32, f32) -> f32| [f(a[0], b[0]), f(a[1], b[1]), f(a[2], b[2])];
        Bounds { min: pick(self.min, other.min, f32::min), max: pick(self.max, other.max, f32::max) }
    }
}

impl Scene {
    /// A copy keeping spherical harmonics up to `degree` only (no change when
    /// `degree` is at least the scene's).
    pub fn with_sh_degree(&self, degree: u32) -> Scene {
        if degree >= self.sh_degree {
            return self.clone();
        }
        let (k_old, k_new) = (sh_coefficients(self.sh_degree), sh_coefficients(degree));
        let sh = self.sh.chunks_exact(3 * k_old).flat_map(|g| g[..3 * k_new].iter().copied()).collect();
        Scene { sh_degree: degree, sh, ..self.clone() }
    }

    /// Number of Gaussians.
    pub fn len(&self) -> usize {
        self.means.len()
    }

    /// Whether there are no Gaussians.
    pub fn is_empty(&self) -> bool {
        self.means.is_empty()
    }

    /// Which attribute groups are present.
    pub fn attributes(&self) -> AttributeGroups {
        let m = &self.materials;
        AttributeGroups {
            normals: self.normals.is_some(),
            albedo: m.albedo.is_some(),
            roughness: m.roughness.is_some(),
            metallic: m.metallic.is_some(),
            ao: m.ao.is_some(),
            visibility: m.visibility.is_some(),
        }
    }

    /// Bounds of the centres; `None` for an empty scene.
    pub fn bounds(&self) -> Option<Bounds> {
        let first = *self.means.first()?;
        let mut b = Bounds { min: first, max: first };
        for p in &self.means {
            for ((lo, hi), v) in b.min.iter_mut().zip(b.max.iter_mut()).zip(p) {
                *lo = lo.min(*v);
                *hi = hi.max(*v);
            }
        }
        Some(b)
    }

    /// Bounds of the centres between the `tail` and 1 − `tail` quantiles on
    /// each axis (`tail` in [0, 0.5)): the place a trained scene covers, without
    /// the few floaters far out that stretch [`Scene::bounds`]; `None` when empty.
    pub fn core_bounds(&self, tail: f32) -> Option<Bounds> {
        order::core_bounds(&self.means, tail)
    }

    /// The scene without the Gaussians whose centres lie in `b` grown by `margin` on every side.
    pub fn without_box(&self, b: &demo::Aabb, margin: f32) -> Scene {
        let keep: Vec<bool> = self
            .means
            .iter()
            .map(|p| {
                let p = glam::Vec3::from_array(*p);
                !(p.cmpge(b.min - margin).all() && p.cmple(b.max + margin).all())
            })
            .collect();
        self.select(&keep)
    }

    /// The Gaussians where `keep` is true, every attribute kept in step.
    pub fn select(&self, keep: &[bool]) -> Scene {
        let kept: Vec<usize> = keep.iter().enumerate().filter(|(_, k)| **k).map(|(i, _)| i).collect();
        self.permuted(&kept)
    }

    /// An order of the Gaussians along a Morton (Z-order) curve through their
    /// centres, for [`Scene::permuted`]: neighbours in the order are mostly
    /// neighbours in space, so a kernel's neighbouring invocations (a CPU's
    /// SIMD row, a GPU's subgroup) cull, project and list tiles alike. Over
    /// [`Scene::core_bounds`] at a tail of 0.1%, so a few far floaters do not
    /// squeeze everything else into few cells ([`Scene::morton_order_over`]).
    pub fn morton_order(&self) -> Vec<usize> {
        self.core_bounds(0.001).map_or_else(Vec::new, |b| self.morton_order_over(&b))
    }

    /// The Gaussians sorted by the Morton code of their centres quantized to
    /// 1024 cells an axis over `b` (centres outside it in the edge cells,
    /// non-finite ones last; ties keep their order). The compressed PLY and
    /// SOG writers order their chunks so over [`Scene::bounds`].
    pub fn morton_order_over(&self, b: &Bounds) -> Vec<usize> {
        order::morton_order(&self.means, b)
    }

    /// The median distance between consecutive Gaussians' centres when taken
    /// in `order` (every index once; `None`: as stored), over pairs of finite
    /// centres: how far a file's order is from keeping neighbours together
    /// (compare with [`Scene::morton_order`]'s); `None` under two such pairs.
    pub fn median_step(&self, order: Option<&[usize]>) -> Option<f32> {
        order::median_step(&self.means, order)
    }

    /// The Gaussians `order` names, in its order, every attribute kept in
    /// step: a permutation of `0..len()` reorders the scene, a subset keeps
    /// those; indices past the end are left out.
    pub fn permuted(&self, order: &[usize]) -> Scene {
        fn pick<T: Copy>(v: &[T], order: &[usize], per: usize) -> Vec<T> {
            let range = |i: usize| i.checked_mul(per).and_then(|s| v.get(s..s.checked_add(per)?));
            order.iter().filter_map(|&i| range(i)).flatten().copied().collect()
        }
        let k = 3 * sh_coefficients(self.sh_degree);
        let m = &self.materials;
        Scene {
            means: pick(&self.means, order, 1),
            normals: self.normals.as_ref().map(|v| pick(v, order, 1)),
            sh_degree: self.sh_degree,
            sh: pick(&self.sh, order, k),
            opacity_logits: pick(&self.opacity_logits, order, 1),
            log_scales: pick(&self.log_scales, order, 1),
            rotations: pick(&self.rotations, order, 1),
            materials: Materials {
                albedo: m.albedo.as_ref().map(|v| pick(v, order, 1)),
                roughness: m.roughness.as_ref().map(|v| pick(v, order, 1)),
                metallic: m.metallic.as_ref().map(|v| pick(v, order, 1)),
                ao: m.ao.as_ref().map(|v| pick(v, order, 1)),
                visibility: m.visibility.as_ref().map(|v| pick(v, order, 1)),
            },
            extra_properties: self.extra_properties.clone(),
        }
    }

    /// Floats stored per Gaussian on the GPU (parameters as uploaded).
    pub fn floats_per_gaussian(&self) -> usize {
        let a = self.attributes();
        3 + 3
            + 4
            + 1
            + 3 * sh_coefficients(self.sh_degree)
            + if a.normals { 3 } else { 0 }
            + if a.albedo { 3 } else { 0 }
            + [a.roughness, a.metallic, a.ao, a.visibility].iter().filter(|x| **x).count()
    }

    /// GPU bytes the scene's parameters and their activations take
    /// (covariance and opacity: 7 floats per Gaussian).
    pub fn gpu_bytes(&self) -> u64 {
        (self.len() as u64) * ((self.floats_per_gaussian() + 7) as u64) * 4
    }

    /// Checks lengths, finiteness and quaternions; `origin` names the source in errors.
    pub fn validate(&self, origin: &str) -> Result<(), SceneError> {
        let n = self.len();
        let k = sh_coefficients(self.sh_degree);
        if self.sh_degree > 3 {
            return Err(SceneError::file(origin, format!("SH degree {} is not supported (0 to 3)", self.sh_degree)));
        }
        let mut lengths: Vec<(&str, usize, usize)> = vec![
            ("opacity", self.opacity_logits.len(), n),
            ("scale", self.log_scales.len(), n),
            ("rot", self.rotations.len(), n),
            ("sh", self.sh.len(), n * k * 3),
        ];
        let m = &self.materials;
        if let Some(v) = &self.normals {
            lengths.push(("normal", v.len(), n));
        }
        if let Some(v) = &m.albedo {
            lengths.push(("albedo", v.len(), n));
        }
        for (name, v) in
            [("roughness", &m.roughness), ("metallic", &m.metallic), ("ao", &m.ao), ("visibility", &m.visibility)]
        {
            if let Some(v) = v {
                lengths.push((name, v.len(), n));
            }
        }
        for (name, got, want) in lengths {
            if got != want {
                return Err(SceneError::file(
                    origin,
                    format!("{name} has {got} values, expected {want} for {n} Gaussians"),
                ));
            }
        }
        let check = |row: usize, property: &str, v: f32| -> Result<(), SceneError> {
            if v.is_finite() {
                Ok(())
            } else {
                Err(SceneError::at(origin, row, property, format!("value is {v}")))
            }
        };
        for i in 0..n {
            for a in 0..3 {
                check(i, ["x", "y", "z"][a], self.means[i][a])?;
                check(i, ["scale_0", "scale_1", "scale_2"][a], self.log_scales[i][a])?;
            }
            for a in 0..4 {
                check(i, ["rot_0", "rot_1", "rot_2", "rot_3"][a], self.rotations[i][a])?;
            }
            if self.rotations[i].iter().all(|c| *c == 0.0) {
                return Err(SceneError::at(origin, i, "rot_0..rot_3", "rotation quaternion is zero"));
            }
            check(i, "opacity", self.opacity_logits[i])?;
            for (j, v) in self.sh[i * k * 3..(i + 1) * k * 3].iter().enumerate() {
                let (coef, channel) = (j / 3, j % 3);
                if !v.is_finite() {
                    let name = if coef == 0 {
                        format!("f_dc_{channel}")
                    } else {
                        format!("f_rest_{}", channel * (k - 1) + coef - 1)
                    };
                    return Err(SceneError::at(origin, i, &name, format!("value is {v}")));
                }
            }
            if let Some(v) = &self.normals {
                for a in 0..3 {
                    check(i, ["nx", "ny", "nz"][a], v[i][a])?;
                }
            }
            if let Some(v) = &m.albedo {
                for a in 0..3 {
                    check(i, ["albedo_0", "albedo_1", "albedo_2"][a], v[i][a])?;
                }
            }
            for (name, v) in
                [("roughness", &m.roughness), ("metallic", &m.metallic), ("ao", &m.ao), ("visibility", &m.visibility)]
            {
                if let Some(v) = v {
                    check(i, name, v[i])?;
                }
            }
        }
        Ok(())
    }

    /// A human-readable summary (what `srug info` prints).
    pub fn summary(&self) -> String {
        let mut s = format!("Gaussians: {}\nSH degree: {}\n", self.len(), self.sh_degree);
        let groups = self.attributes().names();
        s += &format!(
            "attributes: {}\n",
            if groups.is_empty() { "none (plain 3DGS colour)".to_string() } else { groups.join(", ") }
        );
        if let Some(b) = self.bounds() {
            s += &format!(
                "bounds: [{:.3}, {:.3}, {:.3}] .. [{:.3}, {:.3}, {:.3}]\n",
                b.min[0], b.min[1], b.min[2], b.max[0], b.max[1], b.max[2]
            );
        }
        s += &format!(
            "GPU memory: {} ({} floats per Gaussian + 7 activated)\n",
            human_bytes(self.gpu_bytes()),
            self.floats_per_gaussian()
        );
        if !self.extra_properties.is_empty() {
            s += &format!("ignored properties: {}\n", self.extra_properties.join(", "));
        }
        s
    }
}

/// Formats a byte count with a binary unit.
pub fn human_bytes(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = bytes as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{bytes} B")
    } else {
        format!("{v:.2} {}", UNITS[u])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Gaussian `g`'s every attribute made from `g`, so a moved Gaussian is recognisable.
    fn numbered(n: usize, sh_degree: u32) -> Scene {
        let k = 3 * sh_coefficients(sh_degree);
        let f = |g: usize, part: usize| (g * 100 + part) as f32;
        Scene {
            means: (0..n).map(|g| [f(g, 0), f(g, 1), f(g, 2)]).collect(),
            normals: Some((0..n).map(|g| [f(g, 3), f(g, 4), f(g, 5)]).collect()),
            sh_degree,
            sh: (0..n).flat_map(|g| (0..k).map(move |c| f(g, 10 + c))).collect(),
            opacity_logits: (0..n).map(|g| f(g, 6)).collect(),
            log_scales: (0..n).map(|g| [f(g, 7), f(g, 8), f(g, 9)]).collect(),
            rotations: (0..n).map(|g| [f(g, 60), f(g, 61), f(g, 62), f(g, 63)]).collect(),
            materials: Materials {
                albedo: Some((0..n).map(|g| [f(g, 70), f(g, 71), f(g, 72)]).collect()),
                roughness: Some((0..n).map(|g| f(g, 73)).collect()),
                metallic: Some((0..n).map(|g| f(g, 74)).collect()),
                ao: Some((0..n).map(|g| f(g, 75)).collect()),
                visibility: Some((0..n).map(|g| f(g, 76)).collect()),
            },
            extra_properties: vec!["f_extra".into()],
        }
    }

    #[test]
    fn permuted_moves_every_attribute_together_and_the_inverse_undoes_it() {
        for sh_degree in [0, 1, 3] {
            let scene = numbered(5, sh_degree);
            let order = [3, 0, 4, 1, 2];
            let moved = scene.permuted(&order);
            for (at, &from) in order.iter().enumerate() {
                assert_eq!(moved.select(&[at == 0, at == 1, at == 2, at == 3, at == 4]), {
                    let mut keep = [false; 5];
                    keep[from] = true;
                    scene.select(&keep)
                });
            }
            let mut inverse = [0; 5];
            for (at, &from) in order.iter().enumerate() {
                inverse[from] = at;
            }
            assert_eq!(moved.permuted(&inverse), scene, "SH degree {sh_degree}");
        }
        assert_eq!(numbered(3, 1).permuted(&[]).len(), 0);
        // A subset keeps those, in its order; indices past the end are left out.
        let scene = numbered(4, 1);
        assert_eq!(
            scene.permuted(&[2, 99, usize::MAX, 0]),
            scene.select(&[true, false, true, false]).permuted(&[1, 0])
        );
        assert_eq!(scene.select(&[false, true, true, false, true]).means, vec![scene.means[1], scene.means[2]]);
    }

    #[test]
    fn morton_order_keeps_neighbours_together_and_non_finite_centres_last() {
        // A 16 × 16 × 4 grid of centres, listed in a scrambled order, with two NaN centres.
        let mut scene = numbered(16 * 16 * 4 + 2, 0);
        for (g, p) in scene.means.iter_mut().enumerate() {
            let c = (g * 389) % (16 * 16 * 4);
            *p = [(c % 16) as f32, ((c / 16) % 16) as f32, (c / 256) as f32 * 3.0];
        }
        let last = scene.len() - 1;
        scene.means[7] = [f32::NAN, 0.0, 0.0];
        scene.means[last] = [0.0, f32::INFINITY, 0.0];
        let order = scene.morton_order();
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..scene.len()).collect::<Vec<_>>(), "a permutation");
        assert_eq!(&order[order.len() - 2..], &[7, last], "non-finite centres last, in their order");
        let steps = |idx: &[usize]| -> f32 {
            let p = |i: usize| glam::Vec3::from(scene.means[i]);
            idx.windows(2).map(|w| p(w[0]).distance(p(w[1]))).sum::<f32>() / (idx.len() - 1) as f32
        };
        let finite: Vec<usize> = (0..scene.len()).filter(|&i| i != 7 && i != last).collect();
        let (scrambled, morton) = (steps(&finite), steps(&order[..order.len() - 2]));
        assert!(morton < 0.25 * scrambled && morton < 2.0, "mean step {morton} against {scrambled}");
        // A curve through cells: the first sixteen centres are one corner of the grid.
        let first: Vec<[f32; 3]> = order[..16].iter().map(|&i| scene.means[i]).collect();
        assert!(first.iter().all(|p| p[0] < 4.0 && p[1] < 4.0 && p[2] == 0.0), "{first:?}");
        assert!(Scene::default().morton_order().is_empty());
        // The median step: the scrambled grid's is long, the Morton order's one cell; NaN steps left out.
        let (file, curve) = (scene.median_step(None), scene.median_step(Some(&order)));
        assert!(curve == Some(1.0) && file.is_some_and(|f| f > 4.0), "median steps {file:?} and {curve:?}");
        assert_eq!(numbered(2, 0).median_step(None), None, "one step");
    }
}
