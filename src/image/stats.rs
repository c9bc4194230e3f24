//! Statistical comparison of two Monte Carlo estimates of the same image.
//!
//! Each side gives, per pixel and channel, a mean and the variance of that mean (from
//! independent chunks: `var_mean = s² / k` with `k − 1` degrees of freedom). Under the
//! hypothesis that both estimate the same image:
//!
//! * per value, `z = (m_a − m_b) / √(v_a + v_b)` is approximately Student-t distributed;
//!   we use ν = min(dof_a, dof_b), below Welch's ν, so the tails we assume are heavier
//!   than the true ones (conservative);
//! * a value is an outlier when |z| exceeds the two-sided t quantile at `alpha`; the
//!   number of outliers is Binomial(N, alpha) and the test allows the count whose upper
//!   tail probability is below `false_alarm`;
//! * the same on the means of 8×8 blocks of pixels (at α = 1e-2: there are few), which
//!   catches regional differences too small for one pixel that cancel in the image mean;
//! * the image mean per channel, `Σ (m_a − m_b) / N`, has variance `Σ (v_a + v_b) / N²`
//!   (pixels are independent: own random streams, box filter); its z must stay below the
//!   normal quantile at `false_alarm` (split over the three channels).
//!
//! The block and global checks need independent pixels; with a wider reconstruction
//! filter only the per-pixel check runs.

use serde::Serialize;
use statrs::distribution::{Binomial, ContinuousCDF, DiscreteCDF, Normal, StudentsT};

/// Per-value mean and variance of the mean, with its degrees of freedom.
#[derive(Clone, Debug)]
pub struct Estimate {
    pub mean: Vec<[f64; 3]>,
    pub var_mean: Vec<[f64; 3]>,
    pub dof: f64,
}

impl Estimate {
    /// From `k ≥ 2` independent renders of equal sample count.
    pub fn from_chunks(chunks: &[Vec<[f32; 3]>]) -> Estimate {
        let k = chunks.len();
        assert!(k >= 2, "need at least two independent chunks");
        let n = chunks[0].len();
        let mut mean = vec![[0.0; 3]; n];
        let mut var_mean = vec![[0.0; 3]; n];
        for i in 0..n {
            for c in 0..3 {
                let m = chunks.iter().map(|img| img[i][c] as f64).sum::<f64>() / k as f64;
                let s2 = chunks
                    .iter()
                    .map(|img| (img[i][c] as f64 - m).powi(2))
                    .sum::<f64>()
                    / (k - 1) as f64;
                mean[i][c] = m;
                var_mean[i][c] = s2 / k as f64;
            }
        }
        Estimate {
            mean,
            var_mean,
            dof: (k - 1) as f64,
        }
    }
}

/// Outliers among one set of z values (pixels, or blocks of pixels).
#[derive(Clone, Debug, Serialize)]
pub struct OutlierTest {
    /// Values compared (per channel).
    pub values: usize,
    pub alpha: f64,
    /// |z| beyond this is an outlier: the two-sided t quantile at `alpha`.
    pub threshold: f64,
    pub outliers: usize,
    /// The most outliers Binomial(values, alpha) allows at the test's share of the
    /// false-alarm probability.
    pub allowed: usize,
    pub max_abs_z: f64,
}

impl OutlierTest {
    fn passed(&self) -> bool {
        self.outliers <= self.allowed
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct Comparison {
    /// z of the image mean, per channel.
    pub global_z: [f64; 3],
    pub global_threshold: f64,
    /// Per pixel and channel.
    pub pixels: OutlierTest,
    /// Per `block`×`block` tile of pixels and channel (regional differences too small
    /// to stand out in one pixel, which may cancel in the global mean).
    pub blocks: OutlierTest,
    pub block: usize,
    pub passed: bool,
}

impl std::fmt::Display for Comparison {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (p, b) = (&self.pixels, &self.blocks);
        write!(
            f,
            "{}: global z = [{:.2}, {:.2}, {:.2}] (limit {:.2}); pixel outliers {} of {} with |z| > {:.2} (allowed {}, max |z| {:.2}); {}x{} block outliers {} of {} with |z| > {:.2} (allowed {}, max |z| {:.2})",
            if self.passed { "PASS" } else { "FAIL" },
            self.global_z[0],
            self.global_z[1],
            self.global_z[2],
            self.global_threshold,
            p.outliers,
            p.values,
            p.threshold,
            p.allowed,
            p.max_abs_z,
            self.block,
            self.block,
            b.outliers,
            b.values,
            b.threshold,
            b.allowed,
            b.max_abs_z
        )
    }
}

/// Per-value outlier level of the block test: blocks are few (a 64×64 image has 64 of
/// 8×8), so a larger α keeps the test sensitive while the Binomial allowance keeps the
/// false-alarm probability where it is asked to be.
pub const BLOCK_ALPHA: f64 = 1e-2;
/// Side of the blocks of the regional test, in pixels.
pub const BLOCK: usize = 8;

/// z of a difference `d` with variance `v`; a value with zero variance on both sides is
/// deterministic (e.g. a constant environment seen directly): equal up to float32
/// rounding of the same arithmetic done in another order (1e-5 relative, ~100 ulp).
/// A standard deviation below 1e-6 of the value is float32 rounding between chunks
/// (chunk means of a constant that differ in the last bit), not noise: also
/// deterministic. Monte Carlo noise of a chunk mean is orders of magnitude above it.
fn z_of(d: f64, v: f64, a: f64, b: f64) -> f64 {
    let rounding = 1e-6 * a.abs().max(b.abs());
    if v > rounding * rounding {
        d / v.sqrt()
    } else if d.abs() <= 1e-5 * a.abs().max(b.abs()).max(1e-6) {
        0.0
    } else {
        f64::INFINITY
    }
}

/// Counts |z| > t-quantile(α) among `zs` and the allowance of Binomial(n, α) at `budget`.
fn outlier_test(zs: &[f64], alpha: f64, nu: f64, budget: f64) -> OutlierTest {
    let t = StudentsT::new(0.0, 1.0, nu).expect("valid t distribution");
    let threshold = t.inverse_cdf(1.0 - alpha / 2.0);
    let binom = Binomial::new(alpha, zs.len() as u64).expect("valid binomial");
    // Smallest k with P(X > k) < budget.
    let mut allowed = 0u64;
    while binom.sf(allowed) >= budget {
        allowed += 1;
    }
    OutlierTest {
        values: zs.len(),
        alpha,
        threshold,
        outliers: zs.iter().filter(|z| z.abs() > threshold).count(),
        allowed: allowed as usize,
        max_abs_z: zs.iter().fold(0.0f64, |m, z| m.max(z.abs())),
    }
}

/// Compares two estimates of an image; `alpha` is the per-pixel outlier level,
/// `false_alarm` the probability that two estimates of the same image fail any of the
/// three checks (a third each: pixels, blocks, global mean).
///
/// `independent_width`: the image width when pixels are independent (box filter: each
/// sample lands in one pixel). With a wider reconstruction filter neighbouring pixels
/// share samples, the variance of a sum of pixels is not the sum of their variances, and
/// only the per-pixel test is valid: pass `None` and the other two are skipped.
pub fn compare(
    a: &Estimate,
    b: &Estimate,
    independent_width: Option<usize>,
    alpha: f64,
    false_alarm: f64,
) -> Comparison {
    assert_eq!(a.mean.len(), b.mean.len(), "images differ in size");
    let width = independent_width.unwrap_or(a.mean.len());
    assert!(
        width > 0 && a.mean.len().is_multiple_of(width),
        "width does not divide the image"
    );
    let height = a.mean.len() / width;
    let independent = independent_width.is_some();
    let nu = a.dof.min(b.dof);
    let budget = false_alarm / 3.0;
    let normal = Normal::new(0.0, 1.0).expect("valid normal");
    // Global: two-sided, split over the 3 channels.
    let global_threshold = normal.inverse_cdf(1.0 - budget / 3.0 / 2.0);

    let mut pixel_z = Vec::with_capacity(a.mean.len() * 3);
    let mut diff_sum = [0.0f64; 3];
    let mut var_sum = [0.0f64; 3];
    for i in 0..a.mean.len() {
        for c in 0..3 {
            let d = a.mean[i][c] - b.mean[i][c];
            let v = a.var_mean[i][c] + b.var_mean[i][c];
            diff_sum[c] += d;
            var_sum[c] += v;
            pixel_z.push(z_of(d, v, a.mean[i][c], b.mean[i][c]));
        }
    }
    // Blocks: the mean difference over the block's pixels; pixels are independent (own
    // random streams, box filter), so its variance is Σ v / n².
    let mut block_z = Vec::new();
    for by in (0..if independent { height } else { 0 }).step_by(BLOCK) {
        for bx in (0..width).step_by(BLOCK) {
            for c in 0..3 {
                let (mut d, mut v, mut ma, mut mb, mut n) = (0.0, 0.0, 0.0, 0.0, 0.0);
                for y in by..(by + BLOCK).min(height) {
                    for x in bx..(bx + BLOCK).min(width) {
                        let i = y * width + x;
                        d += a.mean[i][c] - b.mean[i][c];
                        v += a.var_mean[i][c] + b.var_mean[i][c];
                        ma += a.mean[i][c];
                        mb += b.mean[i][c];
                        n += 1.0;
                    }
                }
                block_z.push(z_of(d / n, v / (n * n), ma / n, mb / n));
            }
        }
    }
    let global_z = [0, 1, 2].map(|c| {
        if var_sum[c] > 0.0 && independent {
            diff_sum[c] / var_sum[c].sqrt()
        } else {
            0.0
        }
    });
    let pixels = outlier_test(&pixel_z, alpha, nu, budget);
    let blocks = outlier_test(&block_z, BLOCK_ALPHA.max(alpha), nu, budget);
    let passed =
        global_z.iter().all(|z| z.abs() <= global_threshold) && pixels.passed() && blocks.passed();
    Comparison {
        global_z,
        global_threshold,
        pixels,
        blocks,
        block: BLOCK,
        passed,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noisy(seed: u64, n: usize, k: usize, offset: f32) -> Vec<Vec<[f32; 3]>> {
        let mut rng = crate::integrator::sampler::Pcg32::for_pixel(seed, 0);
        (0..k)
            .map(|_| {
                (0..n)
                    .map(|i| {
                        let base = 0.5 + 0.3 * ((i % 17) as f32 / 17.0);
                        // Sum of 12 uniforms − 6: approximately N(0, 1).
                        let g = |r: &mut crate::integrator::sampler::Pcg32| {
                            (0..12).map(|_| r.next_1d()).sum::<f32>() - 6.0
                        };
                        [
                            base + offset + 0.05 * g(&mut rng),
                            base + 0.05 * g(&mut rng),
                            base + 0.05 * g(&mut rng),
                        ]
                    })
                    .collect()
            })
            .collect()
    }

    #[test]
    fn same_distribution_passes_and_shift_fails() {
        let a = Estimate::from_chunks(&noisy(1, 4096, 8, 0.0));
        let b = Estimate::from_chunks(&noisy(2, 4096, 8, 0.0));
        let c = compare(&a, &b, Some(64), 1e-3, 1e-6);
        assert!(c.passed, "{c}");
        let shifted = Estimate::from_chunks(&noisy(3, 4096, 8, 0.01));
        let c = compare(&shifted, &b, Some(64), 1e-3, 1e-6);
        assert!(!c.passed, "a 2% shift must be detected: {c}");
    }
}
