//! Choosing c_β without a reference (beyond the paper, which picks it by hand).
//!
//! A cheap, noisy but unbiased render R_f at an albedo α_f > α_s (by default the target
//! albedo itself, at few samples per pixel, with its own seed) is a stand-in for the
//! truth: since its noise is independent of the source render and has mean zero,
//!
//!   E Σ_i (P_i(c_β) − R_f,i)² = Σ_i (P_i(c_β) − E R_f,i)² + Σ_i Var R_f,i,
//!
//! the second term does not depend on c_β, so the c_β that minimises the squared
//! distance between the prediction P(c_β) from α_s to α_f and R_f estimates the c_β
//! that minimises the true error at α_f. One scalar is fitted to every pixel and
//! channel, so the noise of R_f averages out.

use super::predict::{Albedos, Predictor};

/// Σ (prediction − cheap)² over pixels and channels.
fn objective(
    c_beta: f32,
    fit: &Albedos,
    radiance: &[[f32; 3]],
    gradient: &[[f32; 3]],
    cheap: &[[f32; 3]],
) -> f64 {
    let (pred, _) = Predictor::Paper { c_beta }.predict(fit, radiance, gradient);
    pred.iter()
        .zip(cheap)
        .flat_map(|(p, r)| (0..3).map(move |c| (p[c] as f64 - r[c] as f64).powi(2)))
        .sum()
}

/// The c_β in (0, min_c σ_t α_s] minimising the objective: a grid over log c_β, then a
/// golden-section search in the best grid cell. `fit` holds the source albedo and the
/// cheap render's albedo as its target.
pub fn fit_c_beta(
    fit: &Albedos,
    radiance: &[[f32; 3]],
    gradient: &[[f32; 3]],
    cheap: &[[f32; 3]],
) -> f32 {
    let limit = (0..3)
        .map(|c| fit.sigma_t[c] * fit.source[c])
        .fold(f32::INFINITY, f32::min);
    let f = |log_c: f64| objective(log_c.exp() as f32, fit, radiance, gradient, cheap);
    let (lo, hi) = ((limit as f64 * 1e-3).ln(), (limit as f64).ln());
    const GRID: usize = 48;
    let at = |j: usize| lo + (hi - lo) * j as f64 / GRID as f64;
    let values: Vec<f64> = (0..=GRID).map(|j| f(at(j))).collect();
    let best = (0..=GRID)
        .min_by(|&a, &b| values[a].total_cmp(&values[b]))
        .unwrap_or(GRID);
    let (mut a, mut b) = (at(best.saturating_sub(1)), at((best + 1).min(GRID)));
    let phi = 0.5 * (5f64.sqrt() - 1.0);
    let (mut x1, mut x2) = (b - phi * (b - a), a + phi * (b - a));
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..30 {
        if f1 <= f2 {
            b = x2;
            (x2, f2) = (x1, f1);
            x1 = b - phi * (b - a);
            f1 = f(x1);
        } else {
            a = x1;
            (x1, f1) = (x2, f2);
            x2 = a + phi * (b - a);
            f2 = f(x2);
        }
    }
    let c = (0.5 * (a + b)).exp() as f32;
    // Never outside the valid range through rounding.
    c.min(limit)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// The cheap image is the paper's prediction with c_β = 0.7 plus zero-mean noise:
    /// the fit recovers 0.7.
    #[test]
    fn recovers_the_c_beta_that_made_the_image() {
        let a = Albedos {
            source: Vec3::splat(0.9025),
            target: Vec3::splat(0.95),
            sigma_t: Vec3::splat(10.0),
        };
        let mut rng = crate::sampling::Pcg32::for_pixel(5, 0);
        let n = 4000;
        let radiance: Vec<[f32; 3]> = (0..n).map(|_| [0.02 + 0.3 * rng.next_1d(); 3]).collect();
        let gradient: Vec<[f32; 3]> = radiance.iter().map(|r| [r[0] * 3.0; 3]).collect();
        let (truth, _) = Predictor::Paper { c_beta: 0.7 }.predict(&a, &radiance, &gradient);
        let cheap: Vec<[f32; 3]> = truth
            .iter()
            .map(|t| [t[0] * (1.0 + 0.5 * (rng.next_1d() - 0.5)); 3])
            .collect();
        let c = fit_c_beta(&a, &radiance, &gradient, &cheap);
        assert!((c - 0.7).abs() < 0.05, "fitted {c}");
        let exact = fit_c_beta(&a, &radiance, &gradient, &truth);
        assert!(
            (exact - 0.7).abs() < 1e-3,
            "fitted {exact} to the noise-free image"
        );
    }
}
