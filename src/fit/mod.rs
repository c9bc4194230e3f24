//! `mediareg fit`: a medium's parameters from images. Each iteration renders the
//! image and its derivatives in the parameters in the same paths
//! (`integrator::volpath::Differentiated`), one render per target, and takes a
//! Levenberg–Marquardt step on the squared error:
//!
//!   (JᵀJ + λ diag JᵀJ) δ = −Jᵀ r,
//!
//! r the residuals (render − target, every pixel and channel of every target), J their
//! derivatives in the unknowns' step coordinates (`unknowns`). With a handful of
//! unknowns and their derivative images at hand, Gauss–Newton needs few iterations
//! where a first-order method (Adam, as in Mitsuba 3's examples) needs hundreds, and
//! JᵀJ is also what says how well the images determine each unknown.
//!
//! The renders are noisy, and a residual and its derivative from the same paths are
//! correlated: Jᵀr from one render is biased (it holds the gradient of the render's
//! variance). Each iteration therefore renders twice at independent seeds and takes
//! Jᵀr = (J₁ᵀr₂ + J₂ᵀr₁)/2, whose zero is the least-squares optimum of the expected
//! image; the loss reported is r₁·r₂ (unbiased for the squared error of the expected
//! image, without the noise floor). No step is rejected on a noisy loss: each is
//! bounded (a trust region per unknown), and the estimate is the mean of the iterates
//! over the last half of the iterations (Polyak averaging: the iterates jitter around
//! the optimum by the renders' noise), which render at `SETTLE_SPP_FACTOR` times the
//! samples, so that their jitter on a curved valley does not pull the mean aside.
//! While that mean is still moving (its iterates' trend carries it across its
//! interval), the fit goes on, up to `max_iterations`: a poorly determined direction
//! (an optically thick medium seen from one side) is crossed slowly.
//!
//! Confidence intervals: the covariance of the least-squares estimate,
//! s² (JᵀJ)⁻¹ with s² the residual variance, from two renders at independent seeds
//! whose cross product J₁ᵀJ₂ estimates JᵀJ without the bias that render noise adds to
//! J₁ᵀJ₁ (which would make an undetermined direction look determined). A direction
//! the images do not fix has an interval that says so (wide, or unbounded).

mod unknowns;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

use nalgebra::{DMatrix, DVector};

pub use unknowns::Unknown;

use crate::image::Image;
use crate::integrator::render::{render, RenderOptions, Rendered};
use crate::integrator::{derivative_images, medium_gradient, GradientError, MediumParam};
use crate::scene::Scene;

/// One image to fit, and the scene (camera, lighting) that renders it.
pub struct FitTarget {
    pub scene: Scene,
    pub image: Image,
}

/// How to fit.
#[derive(Clone, Debug)]
pub struct FitSettings {
    /// The medium's XML id (None: the scenes' only medium).
    pub medium: Option<String>,
    pub params: Vec<MediumParam>,
    pub spp: u32,
    /// Iterations planned; the second half of them are averaged.
    pub iterations: u32,
    /// While the averaged iterates are still moving, the plan grows by half (the
    /// averaged window with it) up to this many iterations; `iterations` for a fixed
    /// count.
    pub max_iterations: u32,
    pub seed: u64,
    /// Set to stop after the iteration under way (the best so far is returned).
    pub cancel: Option<Arc<AtomicBool>>,
}

/// Where an iteration left the fit (for a progress line).
pub struct Progress<'a> {
    pub iteration: u32,
    /// The iterations planned now (it grows while the fit has not settled).
    pub planned: u32,
    pub loss: f64,
    pub unknowns: &'a [Unknown],
    pub values: &'a [f32],
}

/// What a fit found.
#[derive(Clone, Debug)]
pub struct FitResult {
    pub unknowns: Vec<Unknown>,
    /// The best iterate's values.
    pub values: Vec<f32>,
    /// 95% intervals per unknown (±∞ where the images do not determine it).
    pub ci: Vec<[f32; 2]>,
    /// Whether the averaged iterates had stopped moving (else more iterations, or more
    /// samples per iteration, are needed before the intervals mean what they say).
    pub converged: bool,
    /// The loss (mean squared residual) of each iteration's render.
    pub loss: Vec<f64>,
    pub iterations: u32,
    pub seconds: f64,
}

/// Why a fit cannot run.
#[derive(Debug)]
pub enum FitError {
    Gradient(GradientError),
    /// A target's size differs from its scene's film, or no target was given.
    Target(String),
}

impl std::fmt::Display for FitError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FitError::Gradient(e) => write!(f, "{e}"),
            FitError::Target(why) => write!(f, "{why}"),
        }
    }
}

impl std::error::Error for FitError {}

/// Every target rendered once at the current values: the residuals and their
/// derivative columns in the unknowns (pixel-major, channel-minor), all targets end
/// to end.
struct Evaluation {
    residuals: Vec<f64>,
    columns: Vec<Vec<f64>>,
}

/// Σ a·b.
fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a * b).sum()
}

/// (Aᵀ B + Bᵀ A) / 2 over two evaluations' columns.
fn cross(a: &Evaluation, b: &Evaluation) -> DMatrix<f64> {
    let k = a.columns.len();
    DMatrix::from_fn(k, k, |i, j| {
        0.5 * (dot(&a.columns[i], &b.columns[j]) + dot(&a.columns[j], &b.columns[i]))
    })
}

/// Fits `settings.params` of one medium to `targets`, starting from the first
/// target's scene values (each target's scene gets the same values as the fit goes);
/// `progress` sees each iteration.
pub fn fit(
    targets: &mut [FitTarget],
    settings: &FitSettings,
    mut progress: impl FnMut(&Progress),
) -> Result<FitResult, FitError> {
    let start = Instant::now();
    let mi = check(targets, settings)?;
    let unknowns = Unknown::of(&targets[0].scene.media[mi as usize], &settings.params);
    let m0 = &targets[0].scene.media[mi as usize];
    let mut x: Vec<f64> = unknowns.iter().map(|u| u.to_x(u.value(m0))).collect();
    let cancelled = || {
        settings
            .cancel
            .as_ref()
            .is_some_and(|c| c.load(Ordering::Relaxed))
    };
    let mut losses = Vec::new();
    let mut iterates = Vec::new();
    let (mut gain, mut previous) = (1.0f64, None::<DVector<f64>>);
    let mut planned = settings.iterations;
    let mut it = 0;
    loop {
        while it < planned && !cancelled() {
            set_values(targets, mi, &unknowns, &x);
            let seed = settings.seed.wrapping_add(2 * it as u64);
            // The iterations whose iterates are averaged render at more samples: their
            // jitter on a curved valley would otherwise pull the mean off the optimum (a
            // bias that shrinks with the noise), and halving their steps instead stopped
            // them short along the valley.
            let settling = 2 * (it + 1) >= settings.iterations;
            let now = FitSettings {
                spp: match settling {
                    true => settings.spp.saturating_mul(SETTLE_SPP_FACTOR),
                    false => settings.spp,
                },
                ..settings.clone()
            };
            let e1 = evaluate(targets, &now, mi, &unknowns, seed);
            let e2 = evaluate(targets, &now, mi, &unknowns, seed + 1);
            let loss = dot(&e1.residuals, &e2.residuals) / e1.residuals.len().max(1) as f64;
            losses.push(loss);
            iterates.push(x.clone());
            let values: Vec<f32> = unknowns.iter().zip(&x).map(|(u, &x)| u.from_x(x)).collect();
            it += 1;
            progress(&Progress {
                iteration: it,
                planned,
                loss,
                unknowns: &unknowns,
                values: &values,
            });
            if cancelled() {
                break;
            }
            let delta = gauss_newton(&e1, &e2);
            // Step-length adaptation: steps that keep their direction lengthen the next
            // (a poorly determined direction, where render noise on JᵀJ shortens the
            // Gauss–Newton step, is crossed in fewer iterations); a reversal shortens it.
            if let Some(p) = &previous {
                gain = match p.dot(&delta) > 0.0 {
                    true => (gain * 1.5).min(MAX_GAIN),
                    false => (gain * 0.5).max(1.0),
                };
            }
            x = bounded_step(&unknowns, &x, &(&delta * gain));
            previous = Some(delta);
        }
        if iterates.is_empty() {
            iterates.push(x.clone()); // cancelled before the first render
        }
        let estimate = conclude(targets, settings, mi, &unknowns, &iterates);
        // Not settled yet: go on, the averaged window growing with the plan.
        if estimate.converged || planned >= settings.max_iterations || cancelled() {
            let Estimate {
                values,
                ci,
                converged,
            } = estimate;
            return Ok(FitResult {
                unknowns,
                values,
                ci,
                converged,
                iterations: losses.len() as u32,
                loss: losses,
                seconds: start.elapsed().as_secs_f64(),
            });
        }
        planned = (planned + planned.div_ceil(2)).min(settings.max_iterations);
    }
}

/// The estimate from a fit's iterates so far.
struct Estimate {
    values: Vec<f32>,
    ci: Vec<[f32; 2]>,
    converged: bool,
}

/// The mean of the last half of the iterates (Polyak averaging), its intervals, and
/// whether it has settled. Leaves the estimate in the targets' scenes.
fn conclude(
    targets: &mut [FitTarget],
    settings: &FitSettings,
    mi: u32,
    unknowns: &[Unknown],
    iterates: &[Vec<f64>],
) -> Estimate {
    let tail = &iterates[iterates.len() / 2..];
    let best_x: Vec<f64> = (0..unknowns.len())
        .map(|i| tail.iter().map(|x| x[i]).sum::<f64>() / tail.len().max(1) as f64)
        .collect();
    set_values(targets, mi, unknowns, &best_x);
    let values: Vec<f32> = unknowns
        .iter()
        .zip(&best_x)
        .map(|(u, &x)| u.from_x(x))
        .collect();
    let ci = intervals(targets, settings, mi, unknowns, &best_x);
    // Still moving: the averaged iterates' trend (a least-squares line through them)
    // carries a value across the window by more than its interval's half-width (the
    // interval then understates the error: the estimate lags the optimum).
    let converged = unknowns.iter().enumerate().all(|(i, u)| {
        let values: Vec<f64> = tail.iter().map(|x| u.from_x(x[i]) as f64).collect();
        let drift = trend(&values).abs() * values.len() as f64;
        let half_width = 0.5 * (ci[i][1] - ci[i][0]) as f64;
        drift <= half_width || drift.is_nan() || half_width.is_nan()
    });
    Estimate {
        values,
        ci,
        converged,
    }
}

/// The medium to fit, after checking that every target can be fitted.
fn check(targets: &[FitTarget], settings: &FitSettings) -> Result<u32, FitError> {
    let first = targets
        .first()
        .ok_or_else(|| FitError::Target("no target image".into()))?;
    let (_, mi) = medium_gradient(&first.scene, settings.medium.as_deref(), &settings.params)
        .map_err(FitError::Gradient)?;
    for (i, t) in targets.iter().enumerate() {
        // Each target's scene (its own defines) must have the same medium to fit.
        let (_, own) = medium_gradient(&t.scene, settings.medium.as_deref(), &settings.params)
            .map_err(FitError::Gradient)?;
        if own != mi {
            return Err(FitError::Target(format!(
                "target {}: its scene's medium to fit is #{own}, the first target's #{mi}",
                i + 1
            )));
        }
        let film = &t.scene.shot.film;
        if (t.image.width, t.image.height) != film.crop_size {
            return Err(FitError::Target(format!(
                "target {}: {}×{} pixels, its scene's film {}×{}",
                i + 1,
                t.image.width,
                t.image.height,
                film.crop_size.0,
                film.crop_size.1
            )));
        }
    }
    Ok(mi)
}

/// The slope per step of the least-squares line through `values` (0 for fewer than two).
fn trend(values: &[f64]) -> f64 {
    let n = values.len() as f64;
    if values.len() < 2 {
        return 0.0;
    }
    let mean_i = (n - 1.0) / 2.0;
    let mean_v = values.iter().sum::<f64>() / n;
    let (mut num, mut den) = (0.0, 0.0);
    for (i, v) in values.iter().enumerate() {
        num += (i as f64 - mean_i) * (v - mean_v);
        den += (i as f64 - mean_i).powi(2);
    }
    num / den
}

/// Puts the values at step coordinates `x` into medium `mi` of every target's scene.
fn set_values(targets: &mut [FitTarget], mi: u32, unknowns: &[Unknown], x: &[f64]) {
    for t in targets.iter_mut() {
        let m = &mut t.scene.media[mi as usize];
        for (u, &x) in unknowns.iter().zip(x) {
            u.set(m, u.from_x(x));
        }
    }
}

/// The intervals' renders take this many times an iteration's samples.
const CI_SPP_FACTOR: u32 = 8;

/// The iterations over whose iterates the estimate is averaged render at this many times
/// `spp`.
const SETTLE_SPP_FACTOR: u32 = 4;

/// The iterations a fit plans unless told a count.
pub const DEFAULT_ITERATIONS: u32 = 100;

/// The most iterations a fit grows to while its estimate is still moving, unless told
/// a count.
pub const MAX_ITERATIONS: u32 = 400;

/// The longest a step is stretched by the step-length adaptation.
const MAX_GAIN: f64 = 8.0;

/// The damped Gauss–Newton step with the decorrelated gradient (J₁ᵀr₂ + J₂ᵀr₁)/2 and
/// the curvature (J₁ᵀJ₁ + J₂ᵀJ₂)/2. The curvature is positive semi-definite, for a
/// stable solve; the unbiased cross product J₁ᵀJ₂ was tried and its noisy small
/// eigenvalue threw the thin cube's fit far along its valley. Render noise on J₁ᵀJ₁'s
/// diagonal shortens steps along a poorly determined direction instead (the step-length
/// adaptation in `fit` makes up for it).
fn gauss_newton(e1: &Evaluation, e2: &Evaluation) -> DVector<f64> {
    const LAMBDA: f64 = 1e-3;
    let k = e1.columns.len();
    let jtr = DVector::from_fn(k, |i, _| {
        0.5 * (dot(&e1.columns[i], &e2.residuals) + dot(&e2.columns[i], &e1.residuals))
    });
    let mut a = DMatrix::from_fn(k, k, |i, j| {
        0.5 * (dot(&e1.columns[i], &e1.columns[j]) + dot(&e2.columns[i], &e2.columns[j]))
    });
    for i in 0..k {
        a[(i, i)] += LAMBDA * a[(i, i)].max(1e-30);
    }
    a.clone()
        .cholesky()
        .map(|c| c.solve(&(-&jtr)))
        .or_else(|| a.pseudo_inverse(1e-12).ok().map(|p| p * (-&jtr)))
        .unwrap_or_else(|| DVector::zeros(k))
}

/// x + δ, δ shortened as a whole (keeping its direction) to each unknown's largest
/// step, then clamped into range.
fn bounded_step(unknowns: &[Unknown], x: &[f64], delta: &DVector<f64>) -> Vec<f64> {
    let shrink = unknowns
        .iter()
        .enumerate()
        .map(|(i, u)| (u.max_step() / delta[i].abs()).min(1.0))
        .fold(1.0f64, f64::min);
    x.iter()
        .zip(delta.iter())
        .zip(unknowns)
        .map(|((x, d), u)| u.clamp_x(x + shrink * d))
        .collect()
}

/// Renders every target at the values now in its scene, with the derivatives.
fn evaluate(
    targets: &[FitTarget],
    settings: &FitSettings,
    mi: u32,
    unknowns: &[Unknown],
    seed: u64,
) -> Evaluation {
    let mut eval = Evaluation {
        residuals: Vec::new(),
        columns: vec![Vec::new(); unknowns.len()],
    };
    for t in targets {
        let (rendered, derivs) = render_with_derivatives(t, settings, mi, seed);
        let m = &t.scene.media[mi as usize];
        let chain: Vec<f64> = unknowns.iter().map(|u| u.dv_dx(u.value(m))).collect();
        for (p, (mine, want)) in rendered
            .image
            .pixels
            .iter()
            .zip(&t.image.pixels)
            .enumerate()
        {
            for c in 0..3 {
                eval.residuals.push((mine[c] - want[c]) as f64);
                for (j, u) in unknowns.iter().enumerate() {
                    let d = derivs[&u.param].pixels[p];
                    eval.columns[j].push(u.derivative_in(d, c) * chain[j]);
                }
            }
        }
    }
    eval
}

/// One render of target `t` at `seed` with its derivative images by parameter.
fn render_with_derivatives(
    t: &FitTarget,
    settings: &FitSettings,
    mi: u32,
    seed: u64,
) -> (Rendered, std::collections::HashMap<MediumParam, Image>) {
    let (estimand, _) = medium_gradient(&t.scene, settings.medium.as_deref(), &settings.params)
        .expect("checked before the fit");
    let shot = t.scene.shot.with(settings.spp, seed);
    let opts = RenderOptions {
        estimand,
        ..Default::default()
    };
    let rendered = render(&t.scene, &shot, &opts);
    let derivs = derivative_images(&t.scene, mi, &settings.params, &rendered)
        .into_iter()
        .filter_map(|(p, img)| img.map(|img| (p, img)))
        .collect();
    (rendered, derivs)
}

/// The estimate's covariance s² C⁻¹ from the curvature C, over the directions C
/// determines, and which unknowns take part in a direction it does not: an eigenvalue
/// at most `UNDETERMINED` × the largest (not clearly positive: render noise makes an
/// exact zero a small number of either sign).
fn covariance(curvature: &DMatrix<f64>, s2: f64) -> (DMatrix<f64>, Vec<bool>) {
    let k = curvature.nrows();
    let eig = curvature.clone().symmetric_eigen();
    let top = eig.eigenvalues.iter().cloned().fold(0.0f64, f64::max);
    let mut cov = DMatrix::<f64>::zeros(k, k);
    let mut undetermined = vec![false; k];
    for (n, &l) in eig.eigenvalues.iter().enumerate() {
        let v = eig.eigenvectors.column(n);
        if l <= UNDETERMINED * top.max(1e-300) {
            for i in 0..k {
                undetermined[i] |= v[i].abs() > 1e-3;
            }
            continue;
        }
        cov += (v * v.transpose()) * (s2 / l);
    }
    (cov, undetermined)
}

/// A curvature eigenvalue at most this share of the largest is a direction the images do
/// not determine.
const UNDETERMINED: f64 = 1e-9;

/// 95% intervals at `x` from two renders at fresh seeds: s² (J₁ᵀJ₂)⁻¹ (the module
/// comment), mapped through each unknown's coordinate.
fn intervals(
    targets: &[FitTarget],
    settings: &FitSettings,
    mi: u32,
    unknowns: &[Unknown],
    x: &[f64],
) -> Vec<[f32; 2]> {
    let k = unknowns.len();
    let seed = settings.seed.wrapping_add(1 << 32);
    // At more samples than an iteration's: the cross product's noise would otherwise
    // decide whether a weakly determined direction is determined.
    let more = FitSettings {
        spp: settings.spp.saturating_mul(CI_SPP_FACTOR),
        ..settings.clone()
    };
    let e1 = evaluate(targets, &more, mi, unknowns, seed);
    let e2 = evaluate(targets, &more, mi, unknowns, seed + 1);
    let cross = cross(&e1, &e2);
    // The residual variance of one render (the noise and what the model misses).
    let n = e1.residuals.len();
    let s2 = 0.5 * (dot(&e1.residuals, &e1.residuals) + dot(&e2.residuals, &e2.residuals))
        / (n.saturating_sub(k)).max(1) as f64;
    // The estimate is the mean of the averaged iterates, each from renders at the
    // iteration's samples; its noise is bounded by one iteration's: s² at that spp.
    let s2 = s2 * CI_SPP_FACTOR as f64;
    let (cov, undetermined) = covariance(&cross, s2);
    unknowns
        .iter()
        .enumerate()
        .map(|(i, u)| {
            if undetermined[i] {
                return [f32::NEG_INFINITY, f32::INFINITY];
            }
            let half = 1.96 * cov[(i, i)].max(0.0).sqrt();
            [u.from_x(x[i] - half), u.from_x(x[i] + half)]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The slope of the least-squares line: exact on a line, 0 on a constant and on
    /// fewer than two values.
    #[test]
    fn trend_is_the_least_squares_slope() {
        let line: Vec<f64> = (0..7).map(|i| 3.0 + 0.5 * i as f64).collect();
        assert!((trend(&line) - 0.5).abs() < 1e-12);
        assert_eq!(trend(&[2.0; 5]), 0.0);
        assert_eq!(trend(&[1.0]), 0.0);
        // A reversed line flips it.
        let rev: Vec<f64> = line.iter().rev().cloned().collect();
        assert!((trend(&rev) + 0.5).abs() < 1e-12);
    }

    /// Determined directions get s² C⁻¹; a direction of (numerically) zero curvature
    /// marks exactly the unknowns that take part in it (sigma_t and scale multiply, so
    /// their curvature is [[1, 1], [1, 1]] in log coordinates), and the threshold sits
    /// between 1e-8 and 1e-10 of the largest eigenvalue.
    #[test]
    fn covariance_inverts_the_determined_directions_and_marks_the_rest() {
        let (cov, undetermined) =
            covariance(&DMatrix::from_row_slice(2, 2, &[4.0, 0.0, 0.0, 1.0]), 2.0);
        assert_eq!(undetermined, [false, false]);
        assert!((cov[(0, 0)] - 0.5).abs() < 1e-12 && (cov[(1, 1)] - 2.0).abs() < 1e-12);
        let product = DMatrix::from_row_slice(3, 3, &[1.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 2.0]);
        let (cov, undetermined) = covariance(&product, 1.0);
        assert_eq!(undetermined, [true, true, false]);
        assert!((cov[(2, 2)] - 0.5).abs() < 1e-12, "{}", cov[(2, 2)]);
        for (small, marked) in [(1e-8, false), (1e-10, true)] {
            let c = DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, small]);
            assert_eq!(covariance(&c, 1.0).1, [false, marked], "eigenvalue {small}");
        }
    }
}
