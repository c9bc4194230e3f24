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
//! * the image mean per channel, `Σ (m_a − m_b) / N`, has variance `Σ (v_a + v_b) / N²`
//!   (pixels are independent: own random streams, box filter); its z must stay below the
//!   normal quantile at `false_alarm` (split over the three channels).

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

#[derive(Clone, Debug, Serialize)]
pub struct Comparison {
    /// Pixel-channel values compared.
    pub values: usize,
    /// z of the image mean, per channel.
    pub global_z: [f64; 3],
    pub global_threshold: f64,
    pub outliers: usize,
    pub outlier_z: f64,
    pub allowed_outliers: usize,
    /// The largest |z| seen.
    pub max_abs_z: f64,
    pub passed: bool,
}

impl std::fmt::Display for Comparison {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: global z = [{:.2}, {:.2}, {:.2}] (limit {:.2}); outliers {} of {} with |z| > {:.2} (allowed {}); max |z| {:.2}",
            if self.passed { "PASS" } else { "FAIL" },
            self.global_z[0],
            self.global_z[1],
            self.global_z[2],
            self.global_threshold,
            self.outliers,
            self.values,
            self.outlier_z,
            self.allowed_outliers,
            self.max_abs_z
        )
    }
}

/// Compares two estimates; `alpha` is the per-value outlier level, `false_alarm` the
/// probability that two estimates of the same image fail either check.
pub fn compare(a: &Estimate, b: &Estimate, alpha: f64, false_alarm: f64) -> Comparison {
    assert_eq!(a.mean.len(), b.mean.len(), "images differ in size");
    let nu = a.dof.min(b.dof);
    let t = StudentsT::new(0.0, 1.0, nu).expect("valid t distribution");
    let outlier_z = t.inverse_cdf(1.0 - alpha / 2.0);
    let normal = Normal::new(0.0, 1.0).expect("valid normal");
    // Half the false-alarm budget to each check; the global one split over 3 channels.
    let global_threshold = normal.inverse_cdf(1.0 - false_alarm / 2.0 / 3.0 / 2.0);

    let mut diff_sum = [0.0f64; 3];
    let mut var_sum = [0.0f64; 3];
    let mut outliers = 0;
    let mut values = 0;
    let mut max_abs_z: f64 = 0.0;
    for i in 0..a.mean.len() {
        for c in 0..3 {
            let d = a.mean[i][c] - b.mean[i][c];
            let v = a.var_mean[i][c] + b.var_mean[i][c];
            diff_sum[c] += d;
            var_sum[c] += v;
            values += 1;
            // A value with zero variance on both sides is deterministic (e.g. a constant
            // environment seen directly): equal up to float32 rounding of the same
            // arithmetic done in another order (1e-5 relative, about 100 ulp).
            let z = if v > 0.0 {
                d / v.sqrt()
            } else if d.abs() <= 1e-5 * a.mean[i][c].abs().max(b.mean[i][c].abs()).max(1e-6) {
                0.0
            } else {
                f64::INFINITY
            };
            max_abs_z = max_abs_z.max(z.abs());
            if z.abs() > outlier_z {
                outliers += 1;
            }
        }
    }
    let global_z = [0, 1, 2].map(|c| {
        if var_sum[c] > 0.0 {
            diff_sum[c] / var_sum[c].sqrt()
        } else {
            0.0
        }
    });
    let binom = Binomial::new(alpha, values as u64).expect("valid binomial");
    // Smallest k with P(X > k) < false_alarm / 2.
    let mut allowed = 0u64;
    while binom.sf(allowed) >= false_alarm / 2.0 {
        allowed += 1;
    }
    let passed = global_z.iter().all(|z| z.abs() <= global_threshold) && outliers as u64 <= allowed;
    Comparison {
        values,
        global_z,
        global_threshold,
        outliers,
        outlier_z,
        allowed_outliers: allowed as usize,
        max_abs_z,
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
        let c = compare(&a, &b, 1e-3, 1e-6);
        assert!(c.passed, "{c}");
        let shifted = Estimate::from_chunks(&noisy(3, 4096, 8, 0.01));
        let c = compare(&shifted, &b, 1e-3, 1e-6);
        assert!(!c.passed, "a 2% shift must be detected: {c}");
    }
}
