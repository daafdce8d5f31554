//! Shadow accuracy against a true visibility: IoU of the shadowed pixels,
//! false shadow on truly lit pixels (acne), light leaking onto truly shadowed
//! pixels, and how far the shadow edges are from the true ones.
//!
//! A pixel is shadowed where V < 0.5. Only pixels the truth knows
//! (`Some`) count; the truth comes from outside srug (ray casting an
//! analytic scene, [`crate::scene::blocks`]). Edges are the shadowed pixels
//! with a known lit 4-neighbour; the edge error is the mean,
//! over both edge sets, of each edge pixel's Euclidean distance to the
//! nearest edge pixel of the other set (a symmetric mean boundary distance).

/// Counts and rates of one or more views.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ShadowAccuracy {
    /// Pixels the truth knows.
    pub pixels: u64,
    /// Truly shadowed pixels.
    pub true_shadow: u64,
    /// Truly shadowed pixels predicted shadowed.
    pub hits: u64,
    /// Truly lit pixels predicted shadowed.
    pub false_shadow: u64,
    /// Truly shadowed pixels predicted lit.
    pub leaks: u64,
    /// Sum of edge distances, pixels.
    pub edge_distance_sum: f64,
    /// Edge pixels measured.
    pub edge_pixels: u64,
}

impl ShadowAccuracy {
    /// Shadowed-pixel IoU: hits / (predicted ∪ true).
    pub fn iou(&self) -> f64 {
        let union = self.true_shadow + self.false_shadow;
        if union == 0 {
            1.0
        } else {
            self.hits as f64 / union as f64
        }
    }

    /// Fraction of truly lit pixels predicted shadowed.
    pub fn false_shadow_rate(&self) -> f64 {
        let lit = self.pixels - self.true_shadow;
        if lit == 0 {
            0.0
        } else {
            self.false_shadow as f64 / lit as f64
        }
    }

    /// Fraction of truly shadowed pixels predicted lit.
    pub fn light_leak_rate(&self) -> f64 {
        if self.true_shadow == 0 {
            0.0
        } else {
            self.leaks as f64 / self.true_shadow as f64
        }
    }

    /// Mean distance of an edge pixel to the other set's nearest edge, pixels.
    pub fn edge_error(&self) -> f64 {
        if self.edge_pixels == 0 {
            0.0
        } else {
            self.edge_distance_sum / self.edge_pixels as f64
        }
    }

    /// Adds another view's counts.
    pub fn add(&mut self, other: &ShadowAccuracy) {
        self.pixels += other.pixels;
        self.true_shadow += other.true_shadow;
        self.hits += other.hits;
        self.false_shadow += other.false_shadow;
        self.leaks += other.leaks;
        self.edge_distance_sum += other.edge_distance_sum;
        self.edge_pixels += other.edge_pixels;
    }
}

/// Compares a visibility image (`width`×`height`, row-major) with the truth
/// (`Some(true)`: lit). Panics never: mismatched lengths compare the common part.
pub fn shadow_accuracy(visibility: &[f32], truth: &[Option<bool>], width: usize, height: usize) -> ShadowAccuracy {
    let n = (width * height).min(visibility.len()).min(truth.len());
    let mut acc = ShadowAccuracy::default();
    // Class per pixel: Some(true) shadowed.
    let predicted: Vec<Option<bool>> =
        (0..n).map(|p| truth[p].map(|_| visibility[p].is_nan() || visibility[p] < 0.5)).collect();
    let shadowed: Vec<Option<bool>> = (0..n).map(|p| truth[p].map(|lit| !lit)).collect();
    for p in 0..n {
        let (Some(t), Some(s)) = (shadowed[p], predicted[p]) else { continue };
        acc.pixels += 1;
        acc.true_shadow += u64::from(t);
        acc.hits += u64::from(t && s);
        acc.false_shadow += u64::from(!t && s);
        acc.leaks += u64::from(t && !s);
    }
    let (ep, et) = (edges(&predicted, width, n), edges(&shadowed, width, n));
    for (from, to) in [(&ep, &et), (&et, &ep)] {
        if !to.iter().any(|&e| e) {
            continue;
        }
        let d2 = squared_distance_transform(to, width, n / width.max(1));
        for p in (0..from.len()).filter(|&p| from[p]) {
            acc.edge_distance_sum += d2[p].sqrt();
            acc.edge_pixels += 1;
        }
    }
    acc
}

/// Shadowed pixels with a known lit 4-neighbour.
fn edges(class: &[Option<bool>], width: usize, n: usize) -> Vec<bool> {
    let height = n / width.max(1);
    let mut out = vec![false; width * height];
    for y in 0..height {
        for x in 0..width {
            let p = y * width + x;
            if class[p] != Some(true) {
                continue;
            }
            let differs = |q: usize| class[q] == Some(false);
            out[p] = (x > 0 && differs(p - 1))
                || (x + 1 < width && differs(p + 1))
                || (y > 0 && differs(p - width))
                || (y + 1 < height && differs(p + width));
        }
    }
    out
}

/// Squared Euclidean distance of every pixel to the nearest `true` one
/// (Felzenszwalb and Huttenlocher's separable transform).
fn squared_distance_transform(mask: &[bool], width: usize, height: usize) -> Vec<f64> {
    const FAR: f64 = 1e20;
    let mut grid: Vec<f64> = mask.iter().map(|&m| if m { 0.0 } else { FAR }).collect();
    let mut line = Vec::new();
    for x in 0..width {
        line.clear();
        line.extend((0..height).map(|y| grid[y * width + x]));
        for (y, v) in transform_1d(&line).into_iter().enumerate() {
            grid[y * width + x] = v;
        }
    }
    for y in 0..height {
        let row = &mut grid[y * width..(y + 1) * width];
        let out = transform_1d(row);
        row.copy_from_slice(&out);
    }
    grid
}

/// The lower envelope of the parabolas (q − i)² + f(i).
fn transform_1d(f: &[f64]) -> Vec<f64> {
    let n = f.len();
    let mut out = vec![0.0; n];
    if n == 0 {
        return out;
    }
    let mut v = vec![0usize; n];
    let mut z = vec![0.0f64; n + 1];
    let mut k = 0usize;
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    let cross =
        |q: usize, p: usize| ((f[q] + (q * q) as f64) - (f[p] + (p * p) as f64)) / (2.0 * (q as f64 - p as f64));
    for q in 1..n {
        let mut s = cross(q, v[k]);
        while s <= z[k] {
            k -= 1;
            s = cross(q, v[k]);
        }
        k += 1;
        v[k] = q;
        z[k] = s;
        z[k + 1] = f64::INFINITY;
    }
    k = 0;
    for (q, o) in out.iter_mut().enumerate() {
        while z[k + 1] < q as f64 {
            k += 1;
        }
        let d = q as f64 - v[k] as f64;
        *o = d * d + f[v[k]];
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A half-plane shadow x < edge over a 40×20 image.
    fn half(edge: usize) -> Vec<f32> {
        (0..800).map(|p| if p % 40 < edge { 0.0 } else { 1.0 }).collect()
    }

    #[test]
    fn a_shifted_edge_measures_its_shift() {
        let truth: Vec<Option<bool>> = half(20).iter().map(|&v| Some(v > 0.5)).collect();
        let same = shadow_accuracy(&half(20), &truth, 40, 20);
        assert_eq!(
            (same.iou(), same.false_shadow_rate(), same.light_leak_rate(), same.edge_error()),
            (1.0, 0.0, 0.0, 0.0)
        );
        let wide = shadow_accuracy(&half(23), &truth, 40, 20);
        // 3 columns of 20 lit pixels read as shadow: IoU 20/23.
        assert!((wide.iou() - 20.0 / 23.0).abs() < 1e-12, "{}", wide.iou());
        assert!((wide.false_shadow_rate() - 3.0 / 20.0).abs() < 1e-12);
        assert_eq!(wide.light_leak_rate(), 0.0);
        assert!((wide.edge_error() - 3.0).abs() < 1e-12, "{}", wide.edge_error());
        let narrow = shadow_accuracy(&half(18), &truth, 40, 20);
        assert!((narrow.light_leak_rate() - 2.0 / 20.0).abs() < 1e-12);
        assert!((narrow.edge_error() - 2.0).abs() < 1e-12, "{}", narrow.edge_error());
        // Unknown pixels do not count.
        let mut masked = truth.clone();
        masked.iter_mut().skip(20).step_by(40).for_each(|t| *t = None);
        let m = shadow_accuracy(&half(20), &masked, 40, 20);
        assert_eq!(m.pixels, 780);
    }

    #[test]
    fn distance_transform_is_euclidean() {
        let mut mask = vec![false; 25];
        mask[12] = true;
        let d = squared_distance_transform(&mask, 5, 5);
        assert_eq!(d[0], 8.0);
        assert_eq!(d[2], 4.0);
        assert_eq!(d[13], 1.0);
    }
}
