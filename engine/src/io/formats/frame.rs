//! Coordinate frames of the splat formats, and the exact change between them.
//!
//! srug keeps a scene in the frame its PLY was written in (the trainer's
//! COLMAP world, right-down-forward for cameras). Two formats store another
//! frame: SPZ stores right-up-back (RUB) and glTF stores +Y up. Each pair of
//! frames differs by flipping two axes, a 180° rotation about the third, so
//! the change is exact: signs on positions, on the quaternion's vector part
//! and on the spherical-harmonic coefficients whose basis function is odd in
//! an odd number of the flipped axes.

use crate::scene::{sh_coefficients, Scene};

/// Flip two of the three axes (a proper rotation by 180° about the third).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct AxisFlip {
    sign: [f32; 3],
}

/// Parity in (x, y, z) of each real SH basis function after the constant one,
/// in the 3DGS order (band 1: y, z, x; band 2: xy, yz, 3z²−1, xz, x²−y²; band 3:
/// y(3x²−y²), xyz, y(5z²−1), z(5z²−3), x(5z²−1), z(x²−y²), x(x²−3y²)).
const SH_PARITY: [[u8; 3]; 15] = [
    [0, 1, 0],
    [0, 0, 1],
    [1, 0, 0],
    [1, 1, 0],
    [0, 1, 1],
    [0, 0, 0],
    [1, 0, 1],
    [0, 0, 0],
    [0, 1, 0],
    [1, 1, 1],
    [0, 1, 0],
    [0, 0, 1],
    [1, 0, 0],
    [0, 0, 1],
    [1, 0, 0],
];

impl AxisFlip {
    /// SPZ's right-up-back frame and the PLY's right-down-forward frame (y and z flip).
    pub(crate) const RUB_RDF: AxisFlip = AxisFlip { sign: [1.0, -1.0, -1.0] };
    /// glTF's +Y-up frame and the PLY's frame, as splat-transform writes GLB (x and y flip).
    pub(crate) const GLTF_PLY: AxisFlip = AxisFlip { sign: [-1.0, -1.0, 1.0] };

    /// The sign of SH coefficient `k` (1-based after the constant term) under this flip.
    pub(crate) fn sh_sign(self, k: usize) -> f32 {
        let p = SH_PARITY[k - 1];
        (0..3).filter(|&a| p[a] == 1).map(|a| self.sign[a]).product()
    }

    /// A position or direction in the other frame.
    pub(crate) fn vector(self, v: [f32; 3]) -> [f32; 3] {
        [v[0] * self.sign[0], v[1] * self.sign[1], v[2] * self.sign[2]]
    }

    /// A (w, x, y, z) quaternion in the other frame.
    pub(crate) fn quaternion(self, q: [f32; 4]) -> [f32; 4] {
        [q[0], q[1] * self.sign[0], q[2] * self.sign[1], q[3] * self.sign[2]]
    }

    /// A (w, x, y, z) quaternion turned with the scene: r·q, where r is the
    /// 180° turn about the axis the flip keeps (the rotation's local axes turn
    /// too, as splat-transform writes GLB); `inverse` gives the way back, −r·q.
    /// Only signs and a permutation: exact.
    pub(crate) fn turn_quaternion(self, q: [f32; 4], inverse: bool) -> [f32; 4] {
        let k = (0..3).find(|&a| self.sign[a] > 0.0).unwrap_or(2);
        let [w, x, y, z] = q;
        let v = [x, y, z];
        // r = (0, e_k): r·q = (−v_k, w·e_k + e_k × v).
        let (i, j) = ((k + 1) % 3, (k + 2) % 3);
        let mut out_v = [0.0f32; 3];
        out_v[k] = w;
        out_v[i] = -v[j];
        out_v[j] = v[i];
        let out = [-v[k], out_v[0], out_v[1], out_v[2]];
        if inverse {
            out.map(|c| -c)
        } else {
            out
        }
    }

    /// Moves `scene` to the other frame with [`AxisFlip::apply`]'s positions and SH, and
    /// quaternions by [`AxisFlip::turn_quaternion`].
    pub(crate) fn apply_turn(self, scene: &mut Scene, inverse: bool) {
        let rotations = std::mem::take(&mut scene.rotations);
        self.apply(scene);
        scene.rotations = rotations.into_iter().map(|q| self.turn_quaternion(q, inverse)).collect();
    }

    /// Moves every frame-dependent attribute of `scene` to the other frame (the
    /// flip is its own inverse; quaternions are conjugated, which keeps each
    /// Gaussian's shape and is how the SPZ reference converts).
    pub(crate) fn apply(self, scene: &mut Scene) {
        for p in &mut scene.means {
            *p = self.vector(*p);
        }
        if let Some(n) = &mut scene.normals {
            for v in n {
                *v = self.vector(*v);
            }
        }
        for q in &mut scene.rotations {
            *q = self.quaternion(*q);
        }
        let k = sh_coefficients(scene.sh_degree);
        let signs: Vec<f32> = (1..k).map(|c| self.sh_sign(c)).collect();
        for g in scene.sh.chunks_exact_mut(3 * k) {
            for (c, s) in signs.iter().enumerate() {
                for v in &mut g[3 * (c + 1)..3 * (c + 2)] {
                    *v *= s;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The real SH basis up to band 3 (3DGS order and constants), in f64.
    fn basis(d: [f64; 3]) -> [f64; 16] {
        let [x, y, z] = d;
        let (xx, yy, zz) = (x * x, y * y, z * z);
        [
            0.282_094_791_773_878_1,
            -0.488_602_511_902_919_9 * y,
            0.488_602_511_902_919_9 * z,
            -0.488_602_511_902_919_9 * x,
            1.092_548_430_592_079 * x * y,
            -1.092_548_430_592_079 * y * z,
            0.315_391_565_252_520_05 * (2.0 * zz - xx - yy),
            -1.092_548_430_592_079 * x * z,
            0.546_274_215_296_039_5 * (xx - yy),
            -0.590_043_589_926_643_5 * y * (3.0 * xx - yy),
            2.890_611_442_640_554 * x * y * z,
            -0.457_045_799_464_465_8 * y * (4.0 * zz - xx - yy),
            0.373_176_332_590_115_4 * z * (2.0 * zz - 3.0 * xx - 3.0 * yy),
            -0.457_045_799_464_465_8 * x * (4.0 * zz - xx - yy),
            1.445_305_721_320_277 * z * (xx - yy),
            -0.590_043_589_926_643_5 * x * (xx - 3.0 * yy),
        ]
    }

    /// A flipped SH field evaluated in the flipped direction equals the
    /// original in the original direction, for every basis function and flip.
    #[test]
    fn sh_signs_follow_the_basis_functions() {
        for flip in [AxisFlip::RUB_RDF, AxisFlip::GLTF_PLY] {
            for d in [[0.3, -0.5, 0.81], [-0.9, 0.1, 0.42], [0.2, 0.7, -0.68]] {
                let f = flip.sign.map(f64::from);
                let b = basis(d);
                let bf = basis([d[0] * f[0], d[1] * f[1], d[2] * f[2]]);
                for k in 1..16 {
                    let s = f64::from(flip.sh_sign(k));
                    assert!((b[k] - s * bf[k]).abs() < 1e-12, "flip {flip:?} coefficient {k}: {} vs {}", b[k], bf[k]);
                }
            }
        }
    }

    /// The turned quaternion is the flip applied after the rotation, and the inverse turn undoes it exactly.
    #[test]
    fn turned_quaternions_rotate_with_the_scene() {
        let rot = |q: [f32; 4], v: [f32; 3]| {
            glam::Quat::from_xyzw(q[1], q[2], q[3], q[0]).normalize().mul_vec3(glam::Vec3::from(v)).to_array()
        };
        let q = [0.8, -0.3, 0.4, 0.2];
        for flip in [AxisFlip::RUB_RDF, AxisFlip::GLTF_PLY] {
            let t = flip.turn_quaternion(q, false);
            assert_eq!(flip.turn_quaternion(t, true), q);
            for v in [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.3, -0.2, 0.9]] {
                let (a, b) = (flip.vector(rot(q, v)), rot(t, v));
                for i in 0..3 {
                    assert!((a[i] - b[i]).abs() < 1e-6, "{flip:?}: {a:?} vs {b:?}");
                }
            }
        }
    }

    /// The quaternion change rotates a Gaussian's axes exactly as the flip moves vectors.
    #[test]
    fn quaternion_change_matches_the_vector_change() {
        let rot = |q: [f32; 4], v: [f32; 3]| {
            glam::Quat::from_xyzw(q[1], q[2], q[3], q[0]).normalize().mul_vec3(glam::Vec3::from(v)).to_array()
        };
        let q = [0.8, -0.3, 0.4, 0.2];
        for flip in [AxisFlip::RUB_RDF, AxisFlip::GLTF_PLY] {
            for v in [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.3, -0.2, 0.9]] {
                let a = flip.vector(rot(q, v));
                let b = rot(flip.quaternion(q), flip.vector(v));
                for i in 0..3 {
                    assert!((a[i] - b[i]).abs() < 1e-6, "{flip:?}: {a:?} vs {b:?}");
                }
            }
        }
    }
}
