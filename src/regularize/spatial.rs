//! Spatial gradient denoising for still images: a joint (cross) bilateral filter on the
//! gradient image, guided by features of the first visible point of each pixel, which
//! are noise-free: its depth and normal (one ray through the pixel centre), and the
//! rendered radiance. Only the gradient is filtered, never the radiance (the paper,
//! Sec. 4.2: the bias of a denoised gradient is much less visible).
//!
//!   G'(i) = Σ_j w_ij G(j) / Σ_j w_ij,  over j within `radius` of i,
//!   w_ij = exp(−|x_i − x_j|²/2σ_x² − |R_i − R_j|²/2σ_r² − |n_i − n_j|²/2σ_n² − (z_i − z_j)²/2σ_z²)
//!
//! with σ_r relative to the radiance's level and σ_z relative to the depth.

use glam::{Vec2, Vec3, Vec3A};

use crate::scene::shot::Shot;
use crate::scene::Scene;

/// Per pixel of the crop window: distance to the first surface along the ray through
/// the pixel centre (∞ when it escapes) and that surface's shading normal (0 if none).
#[derive(Clone, Debug)]
pub struct Features {
    pub depth: Vec<f32>,
    pub normal: Vec<Vec3>,
    /// The first visible point (meaningless where `depth` is ∞).
    pub position: Vec<Vec3>,
    /// The direction of the ray through the pixel centre.
    pub direction: Vec<Vec3>,
}

/// One ray per pixel centre (null boundaries count: they are what the camera sees of a
/// medium).
pub fn first_hit_features(scene: &Scene, shot: &Shot) -> Features {
    let film = &shot.film;
    let (cw, ch) = film.crop_size;
    let (ox, oy) = film.crop_offset;
    let mut f = Features {
        depth: Vec::with_capacity(cw * ch),
        normal: Vec::with_capacity(cw * ch),
        position: Vec::with_capacity(cw * ch),
        direction: Vec::with_capacity(cw * ch),
    };
    for y in 0..ch {
        for x in 0..cw {
            let pos = Vec2::new((x + ox) as f32 + 0.5, (y + oy) as f32 + 0.5);
            let ray = shot.camera.sample_ray(pos);
            f.direction.push(Vec3::from(ray.d));
            match scene.intersect(ray.o, ray.d, ray.tmax) {
                Some(h) => {
                    f.depth.push(h.t);
                    f.normal.push(Vec3::from(h.sh_frame.n));
                    f.position.push(Vec3::from(h.p));
                }
                None => {
                    f.depth.push(f32::INFINITY);
                    f.normal.push(Vec3::ZERO);
                    f.position.push(Vec3::ZERO);
                }
            }
        }
    }
    f
}

#[derive(Clone, Copy, Debug)]
pub struct BilateralParams {
    pub radius: usize,
    pub sigma_x: f32,
    /// Relative to the larger radiance of the two pixels.
    pub sigma_r: f32,
    pub sigma_n: f32,
    /// Relative to the smaller depth of the two pixels.
    pub sigma_z: f32,
}

impl Default for BilateralParams {
    fn default() -> Self {
        BilateralParams {
            radius: 5,
            sigma_x: 3.0,
            sigma_r: 0.25,
            sigma_n: 0.3,
            sigma_z: 0.05,
        }
    }
}

/// The joint bilateral filter of the module comment over a `width`-wide image.
pub fn denoise(
    gradient: &[[f32; 3]],
    radiance: &[[f32; 3]],
    features: &Features,
    width: usize,
    p: &BilateralParams,
) -> Vec<[f32; 3]> {
    let filter = Filter::new(radiance, features, width, p);
    (0..gradient.len())
        .map(|i| {
            let mut sum = [0.0f64; 3];
            let mut wsum = 0.0f64;
            filter.for_each_weight(i, |j, w| {
                for c in 0..3 {
                    sum[c] += w * gradient[j][c] as f64;
                }
                wsum += w;
            });
            // The centre pixel always has weight 1, so wsum ≥ 1.
            sum.map(|s| (s / wsum) as f32)
        })
        .collect()
}

/// For the filter as a matrix F (G' = F G, F_ij = w_ij / Σ_j w_ij): per pixel j, the
/// column's squared norm Σ_i F_ij² and the diagonal F_jj. For independent pixel noise
/// of variances v_j, Σ_j v_j Σ_i F_ij² is the noise left after filtering, and
/// Σ_j v_j (Σ_i F_ij² − 2 F_jj + 1) the power of (F − I) applied to the noise.
pub fn column_norms(
    radiance: &[[f32; 3]],
    features: &Features,
    width: usize,
    p: &BilateralParams,
) -> (Vec<f64>, Vec<f64>) {
    let filter = Filter::new(radiance, features, width, p);
    let len = radiance.len();
    let mut norm2 = vec![0.0f64; len];
    // Pixel i's weights, kept to normalise them without computing them twice.
    let mut weights: Vec<(usize, f64)> = Vec::new();
    let diagonal = (0..len)
        .map(|i| {
            weights.clear();
            filter.for_each_weight(i, |j, w| weights.push((j, w)));
            let wsum: f64 = weights.iter().map(|(_, w)| w).sum();
            let mut own = 0.0;
            for &(j, w) in &weights {
                let f = w / wsum;
                norm2[j] += f * f;
                if j == i {
                    own = f;
                }
            }
            own
        })
        .collect();
    (norm2, diagonal)
}

/// The filter's weights w_ij (the module comment) over one image's guides.
struct Filter<'a> {
    radiance: &'a [[f32; 3]],
    features: &'a Features,
    width: usize,
    height: usize,
    p: &'a BilateralParams,
}

impl<'a> Filter<'a> {
    fn new(
        radiance: &'a [[f32; 3]],
        features: &'a Features,
        width: usize,
        p: &'a BilateralParams,
    ) -> Self {
        Filter {
            radiance,
            features,
            width,
            height: radiance.len() / width,
            p,
        }
    }

    /// Calls `f(j, w_ij)` for each pixel j within the radius of i whose weight is > 0.
    fn for_each_weight(&self, i: usize, mut f: impl FnMut(usize, f64)) {
        let (p, width, features) = (self.p, self.width, self.features);
        let lum = |c: &[f32; 3]| (c[0] + c[1] + c[2]) / 3.0;
        let r = p.radius as i64;
        let (xi, yi) = ((i % width) as i64, (i / width) as i64);
        let (li, zi, ni) = (
            lum(&self.radiance[i]),
            features.depth[i],
            Vec3A::from(features.normal[i]),
        );
        for yj in (yi - r).max(0)..=(yi + r).min(self.height as i64 - 1) {
            for xj in (xi - r).max(0)..=(xi + r).min(width as i64 - 1) {
                let j = yj as usize * width + xj as usize;
                let dx2 = ((xi - xj).pow(2) + (yi - yj).pow(2)) as f32;
                let lj = lum(&self.radiance[j]);
                let dr = (li - lj) / (p.sigma_r * li.abs().max(lj.abs()).max(1e-6));
                let dn = (ni - Vec3A::from(features.normal[j])).length() / p.sigma_n;
                let zj = features.depth[j];
                let dz = if zi.is_finite() && zj.is_finite() {
                    (zi - zj) / (p.sigma_z * zi.min(zj).max(1e-6))
                } else if zi.is_finite() != zj.is_finite() {
                    f32::INFINITY // background against a surface: never mixed
                } else {
                    0.0
                };
                let e = dx2 / (2.0 * p.sigma_x * p.sigma_x) + 0.5 * (dr * dr + dn * dn + dz * dz);
                let w = (-e as f64).exp();
                if w > 0.0 {
                    f(j, w);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two regions split by a depth edge, each with a constant true gradient plus noise:
    /// the filter lowers the error inside each region and does not mix them.
    #[test]
    fn smooths_noise_and_keeps_feature_edges() {
        let (w, h) = (32, 16);
        let mut rng = crate::sampling::Pcg32::for_pixel(9, 0);
        let truth = |x: usize| if x < w / 2 { 1.0f32 } else { -2.0 };
        let mut noisy = Vec::new();
        let mut features = Features {
            depth: Vec::new(),
            normal: Vec::new(),
            position: Vec::new(),
            direction: Vec::new(),
        };
        for _y in 0..h {
            for x in 0..w {
                let n = (rng.next_1d() - 0.5) * 1.0;
                noisy.push([truth(x) + n; 3]);
                features.depth.push(if x < w / 2 { 1.0 } else { 3.0 });
                features.normal.push(Vec3::Z);
            }
        }
        let radiance = vec![[0.5f32; 3]; w * h];
        let out = denoise(&noisy, &radiance, &features, w, &BilateralParams::default());
        let err = |img: &[[f32; 3]]| {
            img.iter()
                .enumerate()
                .map(|(i, v)| (v[0] - truth(i % w)).powi(2) as f64)
                .sum::<f64>()
                / img.len() as f64
        };
        let (before, after) = (err(&noisy), err(&out));
        assert!(after < before / 10.0, "MSE {before} → {after}");
        // At the edge, no mixing: the pixels next to it stay near their own side.
        for y in 0..h {
            let (l, r) = (out[y * w + w / 2 - 1][0], out[y * w + w / 2][0]);
            assert!(
                (l - 1.0).abs() < 0.3 && (r + 2.0).abs() < 0.3,
                "row {y}: {l}, {r}"
            );
        }
    }

    /// The column norms and diagonal are those of the matrix whose columns are the
    /// filtered unit impulses.
    #[test]
    fn column_norms_match_filtered_impulses() {
        let (w, h) = (7, 5);
        let f = Features {
            depth: (0..w * h).map(|i| 1.0 + (i % 3) as f32 * 0.02).collect(),
            normal: (0..w * h)
                .map(|i| if i % w < 3 { Vec3::Y } else { Vec3::Z })
                .collect(),
            position: vec![Vec3::ZERO; w * h],
            direction: vec![Vec3::Z; w * h],
        };
        let radiance: Vec<[f32; 3]> = (0..w * h)
            .map(|i| [0.2 + 0.05 * (i % 4) as f32; 3])
            .collect();
        let params = BilateralParams::default();
        let (norm2, diagonal) = column_norms(&radiance, &f, w, &params);
        for j in 0..w * h {
            let mut impulse = vec![[0.0f32; 3]; w * h];
            impulse[j] = [1.0; 3];
            let column = denoise(&impulse, &radiance, &f, w, &params);
            let expected: f64 = column.iter().map(|v| (v[0] as f64).powi(2)).sum();
            assert!(
                (norm2[j] - expected).abs() < 1e-5 * expected,
                "column {j}: {} vs {expected}",
                norm2[j]
            );
            assert!(
                (diagonal[j] - column[j][0] as f64).abs() < 1e-6,
                "diagonal {j}"
            );
            assert!(diagonal[j] > 0.0 && diagonal[j] < 1.0);
        }
    }

    /// A constant gradient is a fixed point.
    #[test]
    fn constant_gradient_is_unchanged() {
        let (w, h) = (9, 7);
        let g = vec![[0.3f32, -0.2, 0.1]; w * h];
        let f = Features {
            depth: (0..w * h).map(|i| 1.0 + i as f32 * 0.1).collect(),
            normal: vec![Vec3::Y; w * h],
            position: vec![Vec3::ZERO; w * h],
            direction: vec![Vec3::Z; w * h],
        };
        let out = denoise(
            &g,
            &vec![[1.0; 3]; w * h],
            &f,
            w,
            &BilateralParams::default(),
        );
        assert!(out
            .iter()
            .all(|v| (v[0] - 0.3).abs() < 1e-6 && (v[1] + 0.2).abs() < 1e-6));
    }
}
