//! The source factor without a reference, for the difference predictor (`--factor
//! auto`): a cheap pilot measures, at each candidate factor f, what the method's error
//! is made of, and picks the f of least predicted error at equal time.
//!
//! At α_s = f α_t the prediction is R_t ≈ R_s + D̃, D̃ the denoised difference. Its
//! squared error, summed over pixels, for one channel at N spp is about
//!
//!   E(f) = [Σ Var(R_s) + Σ Var(F D) / N_eff] / N_f + Σ b²,                      (P1)
//!
//! with Var(·) the variance of one sample, F the spatial filter as a matrix (the
//! identity without it), N_eff = (Σ w_k)² / Σ w_k² the number of frames Eq. 10's weights
//! are worth, and b = (F − I) E[D] the bias F adds (the temporal blend of a still or
//! slowly turning view adds little). The two variances are nearly uncorrelated once D is
//! blended over frames. N_f = N t(1)/t(f) is the spp the same time buys at factor f,
//! t(f) the seconds per spp.
//!
//! The pilot renders `chunks` independent images of `spp` samples at each factor with
//! the same seeds for every factor. Sampling depends on σ_t only and the difference's
//! Russian roulette on the target's weight only (`volpath::Estimand::AlbedoDifference`), so
//! every candidate sees exactly the same paths: their differences are measured with far
//! less noise than each alone (common random numbers). From the images D_k and their
//! mean D̄ (P1)'s terms are:
//! * Σ Var(R_s), Σ Var(D): per pixel j the chunks' spread v_j, summed;
//! * Σ Var(F D) = Σ_j v_j Σ_i F_ij² for pixel noise independent between pixels (each
//!   column's norm from the filter's weights: no noisy filtered noise image);
//! * Σ b² = ‖(F − I) D̄‖² − Σ_j Var(D̄_j) Σ_i (F − I)_ij² (clamped at 0): F is
//!   linear in D for fixed guides, and the second term removes, in expectation, what
//!   D̄'s own noise adds to the first;
//! * t(f): a straight line through the candidates' times (one candidate's time at a
//!   few spp is mostly noise; the real dependence on the albedo is smooth).
//!
//! F is guided by the mean of all the pilot's source images (the run guides by its own,
//! less noisy, R_s). Each channel is chosen on its own: a channel's albedo scales only that
//! channel's contributions, so its terms depend on its own factor alone (a candle's red
//! albedo 0.98 wants a factor nearer 1 than its blue 0.88). Factor 1 (plain volpath,
//! D = 0) is a candidate, so the choice never plans a loss.
//!
//! At the pilot's few samples the bias estimate is mostly below its own noise. A bias
//! the pilot cannot see is not taken as 0 but as large as its noise allows: Σ b² is the
//! estimate plus `BIAS_Z` standard errors, for Gaussian pixel noise
//!
//!   SE² ≈ Σ_j 2 s_j⁴ (1 + 1/(chunks − 1)),  s_j² = Var(D̄_j) Σ_i (F − I)_ij²,      (P2)
//!
//! (the squared norm's variance, and the spread of the chunks' variance estimate). On
//! the cloud (docs/regularize.md) the spatial filter's squared bias was 5.5e-5 to
//! 2.2e-4 per value, at the pilot's 8 spp far below its noise; the point estimate,
//! clamped at 0, chose factors 0.4/0.5 that lost ×3 to plain volpath, the bound keeps
//! factor 1. It is a safeguard more than a bound: the guide shares D's paths, so F
//! smooths least where D̄'s noise is largest and the estimate runs below 0 (by 4–8
//! standard errors on the cloud and the cube); it bites where D's noise is heavy. The
//! temporal blend's bias is not estimated (the pilot renders one view). The candidates
//! stop at 0.2: below, the denoising would do nearly all the work.

use super::spatial::{self, BilateralParams, Features};
use crate::image::stats::{Estimate, PixelLayout};
use crate::integrator::volpath::Estimand;
use crate::integrator::{render, RenderOptions};
use crate::scene::shot::Shot;
use crate::scene::Scene;

/// How many standard errors of the bias estimate the pilot adds to it (P2): a bias it
/// cannot tell from its noise is taken as large as the noise allows (one-sided ~98%).
pub const BIAS_Z: f64 = 2.0;

/// The factors the pilot tries, 1 (no extrapolation) included.
pub const CANDIDATES: [f32; 10] = [1.0, 0.95, 0.9, 0.8, 0.7, 0.6, 0.5, 0.4, 0.3, 0.2];

/// One candidate's measurements, per channel where an array (sums over pixels).
#[derive(Clone, Debug)]
pub struct Candidate {
    pub factor: f32,
    /// Σ Var(R_s) of one sample per pixel.
    pub var_source: [f64; 3],
    /// Σ Var(D) of one sample per pixel.
    pub var_difference: [f64; 3],
    /// Σ Var(F D) of one sample per pixel: what the spatial filter F leaves of it
    /// (Var(D) without the filter).
    pub var_difference_filtered: [f64; 3],
    /// Σ b², the spatial filter's squared bias on E[D] (0 without it).
    pub bias2: [f64; 3],
    pub seconds_per_spp: f64,
    /// (P1): the predicted squared error of the run's prediction at equal time.
    pub error: [f64; 3],
}

#[derive(Clone, Debug)]
pub struct Pilot {
    /// The factor chosen for each channel.
    pub factor: [f32; 3],
    pub candidates: Vec<Candidate>,
    pub seconds: f64,
}

/// The pilot's size: `chunks` ≥ 2 renders of `spp` samples per candidate factor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PilotSize {
    pub chunks: usize,
    pub spp: u32,
}

impl Default for PilotSize {
    fn default() -> Self {
        PilotSize { chunks: 8, spp: 1 }
    }
}

/// The most of a run's samples (frames × spp, counted at the target albedo) its pilot
/// may cost: a pilot is worth its time only when it is small beside the render.
pub const MAX_SHARE: f64 = 0.1;

/// The pilot of `size` cut to `MAX_SHARE` of a run of `frames` × `spp`: fewer renders per
/// candidate (at least 2, to estimate a variance), else none (`None`).
pub fn affordable(size: PilotSize, frames: usize, spp: u32) -> Option<PilotSize> {
    let allowed = MAX_SHARE * frames as f64 * spp as f64;
    let per_chunk = (CANDIDATES.len() as u32 * size.spp) as f64;
    let chunks = size.chunks.min((allowed / per_chunk).floor() as usize);
    (chunks >= 2).then_some(PilotSize { chunks, ..size })
}

/// N_eff of Eq. 10's weights w_k ∝ (1 − w_a)^k over `frames` frames.
pub fn effective_frames(frames: usize, w_a: f64) -> f64 {
    let w: Vec<f64> = (0..frames).map(|k| (1.0 - w_a).powi(k as i32)).collect();
    let sum: f64 = w.iter().sum();
    let sq: f64 = w.iter().map(|x| x * x).sum();
    sum * sum / sq
}

/// Per channel Σ over pixels of (a − b)².
fn distance2(a: &[[f32; 3]], b: &[[f32; 3]]) -> [f64; 3] {
    a.iter().zip(b).fold([0.0; 3], |acc, (x, y)| {
        [0, 1, 2].map(|c| acc[c] + ((x[c] - y[c]) as f64).powi(2))
    })
}

/// The least-squares line through `points` (x, y), as a function clamped to stay
/// positive (a time); constant where the x do not vary.
fn fit_line(points: &[(f64, f64)]) -> impl Fn(f64) -> f64 {
    let n = points.len() as f64;
    let (mx, my) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let sxx: f64 = points.iter().map(|(x, _)| (x - mx).powi(2)).sum();
    let sxy: f64 = points.iter().map(|(x, y)| (x - mx) * (y - my)).sum();
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    let floor = my.abs() * 1e-3 + f64::MIN_POSITIVE;
    move |x| (my + slope * (x - mx)).max(floor)
}

/// What the spatial filter F leaves of the difference's noise (Σ_j Σ_i F_ij² v_j, per
/// channel, v_j one sample's variance at pixel j, from `samples` samples in `chunks`
/// renders) and an upper bound on its squared bias on the difference's mean (the module
/// comment's estimator plus `BIAS_Z` of its standard errors).
fn spatial_terms(
    difference: &Measured,
    samples: f64,
    chunks: usize,
    filter: &FilterMatrix,
) -> ([f64; 3], [f64; 3]) {
    let mut left = [0.0; 3];
    // Σ_j Var(D̄_j) Σ_i (F − I)_ij²: what D̄'s own noise adds to ‖(F − I) D̄‖².
    let mut noise_power = [0.0; 3];
    // The estimator's variance (P2): Σ_j 2 s_j⁴ (1 + 1/(chunks − 1)).
    let mut noise_var = [0.0; 3];
    let dof_term = 1.0 + 1.0 / (chunks as f64 - 1.0);
    for (j, v) in difference.var_mean.iter().enumerate() {
        for c in 0..3 {
            let v = v[c] as f64;
            left[c] += filter.norm2[j] * v * samples;
            let s2 = (filter.norm2[j] - 2.0 * filter.diagonal[j] + 1.0) * v;
            noise_power[c] += s2;
            noise_var[c] += 2.0 * s2 * s2 * dof_term;
        }
    }
    let filtered = spatial::denoise(
        &difference.mean,
        &filter.guide,
        filter.features,
        filter.width,
        filter.params,
    );
    let seen = distance2(&filtered, &difference.mean);
    let bias2 =
        [0, 1, 2].map(|c| (seen[c] - noise_power[c] + BIAS_Z * noise_var[c].sqrt()).max(0.0));
    (left, bias2)
}

/// Per pixel, the mean of a candidate's difference images and the variance of that
/// mean (kept in f32: ten candidates of a large image add up).
struct Measured {
    mean: Vec<[f32; 3]>,
    var_mean: Vec<[f32; 3]>,
}

/// The spatial filter as the pilot sees it: guided by the mean of all its source
/// renders (every factor's: less noisy than one factor's few), with its column norms.
struct FilterMatrix<'a> {
    guide: Vec<[f32; 3]>,
    features: &'a Features,
    width: usize,
    params: &'a BilateralParams,
    norm2: Vec<f64>,
    diagonal: Vec<f64>,
}

/// What the pilot is asked: the factor for which medium, for which run (its frames,
/// their blend and spatial filter), and at what size of its own.
#[derive(Clone, Copy, Debug)]
pub struct PilotSettings<'a> {
    /// The medium whose source factor is chosen (its target albedo the scene's).
    pub medium: u32,
    /// The run's sequence: `frames` frames blended with `w_a` (Eq. 10).
    pub frames: usize,
    pub w_a: f64,
    /// The run's spatial filter, if any.
    pub spatial: Option<&'a BilateralParams>,
    /// `chunks` ≥ 2 renders of `spp` samples per candidate factor.
    pub size: PilotSize,
}

/// One candidate factor's renders, reduced: the sums of one sample's variances and the
/// difference's mean and spread per pixel.
struct Measurement {
    factor: f32,
    var_source: [f64; 3],
    var_difference: [f64; 3],
    difference: Measured,
    seconds: f64,
}

/// Runs the pilot `settings` describes through `shot` (its spp is the run's N at
/// factor 1), `features` the first visible points that guide the spatial filter.
pub fn choose_factor(
    scene: &Scene,
    shot: &Shot,
    features: &Features,
    settings: &PilotSettings,
) -> Pilot {
    let PilotSize { chunks, spp } = settings.size;
    assert!(
        chunks >= 2,
        "the pilot needs two renders to measure a spread"
    );
    let start = std::time::Instant::now();
    let n_eff = effective_frames(settings.frames, settings.w_a);
    let width = shot.film.crop_size.0;
    let run_spp = shot.spp.max(1) as f64;
    let samples = (chunks as u32 * spp) as f64;
    let mut guide = vec![[0.0f32; 3]; shot.film.crop_size.0 * shot.film.crop_size.1];
    let measured: Vec<Measurement> = CANDIDATES
        .iter()
        .map(|&factor| measure(scene, shot, settings, factor, &mut guide))
        .collect();
    let filter = settings.spatial.map(|params| {
        let (norm2, diagonal) = spatial::column_norms(&guide, features, width, params);
        FilterMatrix {
            guide,
            features,
            width,
            params,
            norm2,
            diagonal,
        }
    });
    let mut candidates: Vec<Candidate> = Vec::new();
    for m in measured {
        let (var_difference_filtered, bias2) = match &filter {
            Some(filter) if m.var_difference.iter().sum::<f64>() > 0.0 => {
                spatial_terms(&m.difference, samples, chunks, filter)
            }
            _ => (m.var_difference, [0.0; 3]),
        };
        candidates.push(Candidate {
            factor: m.factor,
            var_source: m.var_source,
            var_difference: m.var_difference,
            var_difference_filtered,
            bias2,
            seconds_per_spp: m.seconds / samples,
            error: [0.0; 3],
        });
    }
    predict_errors(&mut candidates, run_spp, n_eff);
    Pilot {
        factor: best_factors(&candidates),
        candidates,
        seconds: start.elapsed().as_secs_f64(),
    }
}

/// Renders the pilot's `chunks` images at `factor` and measures them; each source image
/// is added to `guide` with weight 1 / (chunks × candidates), so that after every
/// candidate it holds the mean of all the pilot's source renders.
fn measure(
    scene: &Scene,
    shot: &Shot,
    settings: &PilotSettings,
    factor: f32,
    guide: &mut [[f32; 3]],
) -> Measurement {
    let PilotSize { chunks, spp } = settings.size;
    let medium = settings.medium;
    let target = scene.media[medium as usize].albedo;
    let samples = (chunks as u32 * spp) as f64;
    let layout = PixelLayout::independent(shot.film.crop_size.0);
    let options = RenderOptions {
        estimand: Estimand::AlbedoDifference { medium, target },
        ..Default::default()
    }
    .with_albedo(scene, medium, target * factor);
    let mut seconds = 0.0;
    let (sources, differences): (Vec<_>, Vec<_>) = (0..chunks)
        .map(|k| {
            // The same seeds for every factor (common random numbers), seeds no
            // frame of a sequence uses.
            let seed = shot.seed.wrapping_add(3_000_000 + k as u64);
            let r = render(scene, &shot.with(spp, seed), &options);
            seconds += r.stats.seconds;
            (
                r.image.pixels,
                r.gradient.expect("a difference was asked for").pixels,
            )
        })
        .unzip();
    let share = 1.0 / (chunks * CANDIDATES.len()) as f32;
    for image in &sources {
        for (g, v) in guide.iter_mut().zip(image) {
            *g = [0, 1, 2].map(|c| g[c] + v[c] * share);
        }
    }
    // Σ over pixels of one sample's variance: the chunks' variance of the mean,
    // times chunks × spp.
    let total = |e: &Estimate| -> [f64; 3] {
        [0, 1, 2].map(|c| e.var_mean.iter().map(|v| v[c]).sum::<f64>() * samples)
    };
    let var_source = total(&Estimate::from_chunks(&sources, layout));
    let difference = Estimate::from_chunks(&differences, layout);
    let var_difference = total(&difference);
    let to_f32 =
        |v: &[[f64; 3]]| -> Vec<[f32; 3]> { v.iter().map(|x| x.map(|y| y as f32)).collect() };
    Measurement {
        factor,
        var_source,
        var_difference,
        difference: Measured {
            mean: to_f32(&difference.mean),
            var_mean: to_f32(&difference.var_mean),
        },
        seconds,
    }
}

/// Fills each candidate's `error` with (P1) for a run of `run_spp` spp at factor 1 and
/// frames worth `n_eff`, the seconds per spp taken from the module comment's line.
fn predict_errors(candidates: &mut [Candidate], run_spp: f64, n_eff: f64) {
    let times: Vec<(f64, f64)> = candidates
        .iter()
        .map(|c| (c.factor as f64, c.seconds_per_spp))
        .collect();
    let time_at = fit_line(&times);
    for c in candidates {
        // N_f: the spp that factor 1's time for N buys at this factor.
        let n_f = run_spp * time_at(1.0) / time_at(c.factor as f64);
        c.error = [0, 1, 2]
            .map(|k| (c.var_source[k] + c.var_difference_filtered[k] / n_eff) / n_f + c.bias2[k]);
    }
}

/// Per channel, the factor of the least predicted error.
fn best_factors(candidates: &[Candidate]) -> [f32; 3] {
    [0, 1, 2].map(|c| {
        candidates
            .iter()
            .min_by(|a, b| a.error[c].total_cmp(&b.error[c]))
            .expect("candidates")
            .factor
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// N_eff against the geometric series' closed forms, q = 1 − w_a:
    /// Σ w = (1 − qⁿ)/(1 − q), Σ w² = (1 − q²ⁿ)/(1 − q²).
    #[test]
    fn effective_frames_is_the_weights_closed_form() {
        for (frames, w_a) in [(11, 0.1), (3, 0.5), (25, 0.3), (2, 0.9)] {
            let q: f64 = 1.0 - w_a;
            let n = frames as i32;
            let sum = (1.0 - q.powi(n)) / (1.0 - q);
            let sq = (1.0 - q.powi(2 * n)) / (1.0 - q * q);
            let want = sum * sum / sq;
            let got = effective_frames(frames, w_a);
            assert!(
                (got - want).abs() < 1e-12 * want,
                "{frames}, {w_a}: {got} vs {want}"
            );
        }
        // Equal weights are worth every frame; one frame is one.
        assert!((effective_frames(11, 0.0) - 11.0).abs() < 1e-12);
        assert_eq!(effective_frames(1, 0.1), 1.0);
        // Many frames at w_a 0.1 are worth (1 + q)/(1 − q) = 19.
        assert!((effective_frames(2000, 0.1) - 19.0).abs() < 1e-9);
    }

    /// The least-squares line, by hand: x̄ = 1, ȳ = 2, Sxx = 2, Sxy = 1, so the slope is
    /// 1/2 through (1, 2).
    #[test]
    fn fit_line_is_least_squares_and_stays_positive() {
        let line = fit_line(&[(0.0, 1.0), (1.0, 3.0), (2.0, 2.0)]);
        for (x, want) in [(0.0, 1.5), (1.0, 2.0), (3.0, 3.0)] {
            assert!((line(x) - want).abs() < 1e-12, "{x}: {}", line(x));
        }
        // Exact points lie on it.
        let line = fit_line(&[(0.2, 5.0), (0.6, 4.2), (1.0, 3.4)]);
        assert!((line(0.4) - 4.6).abs() < 1e-12);
        // One x: the mean.
        let line = fit_line(&[(0.5, 1.0), (0.5, 3.0)]);
        assert_eq!((line(0.0), line(9.0)), (2.0, 2.0));
        // A time never reaches 0: past its root the line is floored at ȳ · 1e-3.
        let line = fit_line(&[(0.0, 1.0), (1.0, 0.5)]);
        assert_eq!(line(10.0), 0.75e-3);
    }

    /// A candidate whose channels all measure the same.
    fn candidate(factor: f32, var_source: f64, var_filtered: f64, bias2: f64, t: f64) -> Candidate {
        Candidate {
            factor,
            var_source: [var_source; 3],
            var_difference: [var_filtered; 3],
            var_difference_filtered: [var_filtered; 3],
            bias2: [bias2; 3],
            seconds_per_spp: t,
            error: [0.0; 3],
        }
    }

    /// (P1) by hand, and each of its terms deciding the choice: factor 1 wins the
    /// baseline by a little, and lowering any one of factor 0.5's terms alone (the
    /// source's variance, the filtered difference's or its weight 1/N_eff, the bias, the
    /// time per spp) hands the choice to 0.5.
    #[test]
    fn each_term_of_the_error_decides_the_choice() {
        let n = 100.0;
        let plain = || candidate(1.0, 8.0, 0.0, 0.0, 1.0);
        let run = |low: Candidate, plain: Candidate, n_eff: f64| {
            let mut c = vec![plain, low];
            predict_errors(&mut c, n, n_eff);
            (best_factors(&c), c[0].error[0], c[1].error[0])
        };
        let close = |a: f64, b: f64| (a - b).abs() < 1e-12 * b.abs();
        // Equal times: N_f = N, error = (V_s + V_F / N_eff) / N + b².
        let (best, e1, e2) = run(candidate(0.5, 2.0, 20.0, 0.011, 1.0), plain(), 4.0);
        assert!(close(e1, 0.08) && close(e2, 0.081), "{e1}, {e2}");
        assert_eq!(best, [1.0; 3]);
        // (what, factor 0.5's V_s, V_F, b², factor 1's seconds per spp, N_eff, 0.5's error).
        let cases = [
            ("source variance", 1.0, 20.0, 0.011, 1.0, 4.0, 0.071),
            ("filtered difference", 2.0, 10.0, 0.011, 1.0, 4.0, 0.056),
            ("more frames", 2.0, 20.0, 0.011, 1.0, 10.0, 0.051),
            ("bias", 2.0, 20.0, 0.001, 1.0, 4.0, 0.071),
            // Factor 1 twice as slow per spp (the line through the two times): 2N spp.
            ("time", 2.0, 20.0, 0.011, 2.0, 4.0, 0.046),
        ];
        for (what, v_s, v_f, b2, t_plain, n_eff, want) in cases {
            let plain = candidate(1.0, 8.0, 0.0, 0.0, t_plain);
            let (best, e1, e2) = run(candidate(0.5, v_s, v_f, b2, 1.0), plain, n_eff);
            assert!(close(e1, 0.08) && close(e2, want), "{what}: {e1}, {e2}");
            assert_eq!(best, [0.5; 3], "{what}");
        }
    }

    /// Each channel picks its own factor from its own terms.
    #[test]
    fn channels_choose_apart() {
        let mut low = candidate(0.3, 1.0, 1.0, 0.0, 1.0);
        low.bias2 = [0.0, 1.0, 0.0];
        let mut mid = candidate(0.7, 2.0, 1.0, 0.0, 1.0);
        mid.var_source = [2.0, 2.0, 0.5];
        let mut c = vec![candidate(1.0, 5.0, 0.0, 0.0, 1.0), low, mid];
        predict_errors(&mut c, 10.0, 1.0);
        assert_eq!(best_factors(&c), [0.3, 0.7, 0.7]);
    }

    /// `spatial_terms` against the filter written out as a matrix (its columns the
    /// filtered unit impulses) and (P2) summed term by term.
    #[test]
    fn spatial_terms_match_the_filter_as_a_matrix() {
        let (w, h) = (6, 5);
        let n = w * h;
        let features = Features {
            depth: (0..n).map(|i| 1.0 + (i % 4) as f32 * 0.03).collect(),
            normal: (0..n)
                .map(|i| if i % w < 2 { Vec3::Y } else { Vec3::Z })
                .collect(),
            position: vec![Vec3::ZERO; n],
            direction: vec![Vec3::Z; n],
        };
        let guide: Vec<[f32; 3]> = (0..n).map(|i| [0.3 + 0.04 * (i % 5) as f32; 3]).collect();
        let params = BilateralParams::default();
        let (norm2, diagonal) = spatial::column_norms(&guide, &features, w, &params);
        let filter = FilterMatrix {
            guide: guide.clone(),
            features: &features,
            width: w,
            params: &params,
            norm2,
            diagonal,
        };
        // F[i][j], column j the filtered impulse at j.
        let mut f = vec![vec![0.0f64; n]; n];
        for j in 0..n {
            let mut impulse = vec![[0.0f32; 3]; n];
            impulse[j] = [1.0; 3];
            let column = spatial::denoise(&impulse, &guide, &features, w, &params);
            for i in 0..n {
                f[i][j] = column[i][0] as f64;
            }
        }
        let (samples, chunks) = (16.0, 8);
        // A checkerboard difference the guide does not show (the filter blurs it: a
        // bias), over noise that differs per channel and pixel.
        let difference = Measured {
            mean: (0..n)
                .map(|i| {
                    let s = if (i % w + i / w) % 2 == 0 { 1.0 } else { -1.0 };
                    [0.2 * s, 0.02 * s, 0.0]
                })
                .collect(),
            var_mean: (0..n)
                .map(|i| [1e-3 * (1 + i % 3) as f32, 2e-3, 5e-4 * (1 + i % 7) as f32])
                .collect(),
        };
        let (left, bias2) = spatial_terms(&difference, samples, chunks, &filter);
        for c in 0..3 {
            let (mut want_left, mut power, mut var, mut seen) = (0.0, 0.0, 0.0, 0.0);
            for (j, row) in f.iter().enumerate() {
                let v = difference.var_mean[j][c] as f64;
                let col2: f64 = (0..n).map(|i| f[i][j] * f[i][j]).sum();
                let minus_i2: f64 = (0..n)
                    .map(|i| (f[i][j] - if i == j { 1.0 } else { 0.0 }).powi(2))
                    .sum();
                want_left += col2 * v * samples;
                power += minus_i2 * v;
                var += 2.0 * (minus_i2 * v).powi(2) * (1.0 + 1.0 / (chunks as f64 - 1.0));
                let fd: f64 = (0..n).map(|k| row[k] * difference.mean[k][c] as f64).sum();
                seen += (fd - difference.mean[j][c] as f64).powi(2);
            }
            let want_bias = (seen - power + BIAS_Z * var.sqrt()).max(0.0);
            assert!(
                (left[c] - want_left).abs() < 1e-4 * want_left,
                "{c}: {left:?} vs {want_left}"
            );
            assert!(
                (bias2[c] - want_bias).abs() < 1e-4 * want_bias.max(1e-6),
                "{c}: {bias2:?} vs {want_bias}"
            );
        }
        // The checkerboard's bias shows in the first channel; the zero third channel's
        // estimate is below 0 before the bound and clamps at 0 with it.
        assert!(bias2[0] > 1.0, "{bias2:?}");
        assert_eq!(bias2[2], 0.0);
    }
}
