//! The source factor without a reference, for the difference predictor (`--factor
//! auto`): a cheap pilot measures, at each candidate factor f, what the method's error
//! is made of, and picks the f of least error per second.
//!
//! At α_s = f α_t the prediction is R_t ≈ R_s + D̃, D̃ the denoised difference. Its
//! variance per pixel and channel at N spp is
//!
//!   Var(R_s)/N + Var(D)/(N · η),    η = N_eff · η_spatial,
//!
//! (the two are nearly uncorrelated once D is blended over frames), where N_eff =
//! (Σ w_k)² / Σ w_k² is the number of frames Eq. 10's weights are worth and η_spatial
//! the factor the spatial filter divides noise by: measured by filtering pure noise, the
//! half-difference of two pilot renders, with the same guides. The pilot renders `chunks`
//! independent images of `spp` samples at each factor; their spread gives Var(R_s) and
//! Var(D) summed over the image, and their time the seconds per spp t(f). The factor
//! chosen minimises [Σ Var(R_s) + Σ Var(D)/η] · t(f), the error at equal time, for each
//! channel on its own: a channel's albedo scales only that channel's contributions and
//! sampling does not depend on it, so a channel's terms depend on its own factor alone
//! (a candle's red albedo 0.98 wants a factor nearer 1 than its blue 0.88). Factor 1
//! (plain volpath, D = 0) is a candidate too, so the choice never predicts a loss.
//!
//! Not in the estimate: the bias the denoising adds to D (it grows with D, so at low
//! factors the estimate is optimistic; the candidates stop at 0.7 for that reason).

use super::spatial::{self, BilateralParams, Features};
use crate::image::stats::{Estimate, PixelLayout};
use crate::integrator::volpath::Gradient;
use crate::integrator::{render, RenderOptions};
use crate::scene::shot::Shot;
use crate::scene::Scene;

/// The factors the pilot tries, 1 (no extrapolation) included.
pub const CANDIDATES: [f32; 7] = [1.0, 0.95, 0.9, 0.85, 0.8, 0.75, 0.7];

/// One candidate's measurements.
#[derive(Clone, Debug)]
pub struct Candidate {
    pub factor: f32,
    /// Per channel, Σ over pixels of Var(R_s) of one sample per pixel.
    pub var_source: [f64; 3],
    /// Per channel, Σ of Var(D) of one sample per pixel.
    pub var_difference: [f64; 3],
    /// The spatial filter's noise reduction measured at this factor (1 without it).
    pub spatial_gain: f64,
    pub seconds_per_spp: f64,
    /// Per channel, [Var(R_s) + Var(D)/η] · t: the error at equal time, up to a
    /// common factor.
    pub cost: [f64; 3],
}

#[derive(Clone, Debug)]
pub struct Pilot {
    /// The factor chosen for each channel.
    pub factor: [f32; 3],
    pub candidates: Vec<Candidate>,
    pub seconds: f64,
}

/// N_eff of Eq. 10's weights w_k ∝ (1 − w_a)^k over `frames` frames.
pub fn effective_frames(frames: usize, w_a: f64) -> f64 {
    let w: Vec<f64> = (0..frames).map(|k| (1.0 - w_a).powi(k as i32)).collect();
    let sum: f64 = w.iter().sum();
    let sq: f64 = w.iter().map(|x| x * x).sum();
    sum * sum / sq
}

/// Runs the pilot for `medium` (target albedo the scene's) through `shot`, with
/// `chunks` ≥ 2 renders of `spp` samples per factor, for a sequence of `frames`
/// frames blended with `w_a` and, if given, the spatial filter `spatial`.
#[allow(clippy::too_many_arguments)]
pub fn choose_factor(
    scene: &Scene,
    shot: &Shot,
    medium: u32,
    frames: usize,
    w_a: f64,
    spatial: Option<&BilateralParams>,
    features: &Features,
    chunks: usize,
    spp: u32,
) -> Pilot {
    assert!(
        chunks >= 2,
        "the pilot needs two renders to measure a spread"
    );
    let start = std::time::Instant::now();
    let target = scene.media[medium as usize].albedo;
    let n_eff = effective_frames(frames, w_a);
    let width = shot.film.crop_size.0;
    let mut candidates = Vec::new();
    for (i, &factor) in CANDIDATES.iter().enumerate() {
        let options = RenderOptions {
            gradient: Gradient::Difference { medium, target },
            ..Default::default()
        }
        .with_albedo(scene, medium, target * factor);
        let mut seconds = 0.0;
        let (sources, differences): (Vec<_>, Vec<_>) = (0..chunks)
            .map(|k| {
                // Seeds no frame of a sequence uses.
                let seed = shot.seed.wrapping_add(3_000_000 + (i * chunks + k) as u64);
                let r = render(scene, &shot.with(spp, seed), &options);
                seconds += r.stats.seconds;
                (
                    r.image.pixels,
                    r.gradient.expect("a difference was asked for").pixels,
                )
            })
            .unzip();
        // Σ over pixels of one sample's variance: the chunks' variance of the mean,
        // times chunks × spp (`Estimate` computes the per-pixel part).
        let spread = |images: &[Vec<[f32; 3]>]| -> [f64; 3] {
            let e = Estimate::from_chunks(images, PixelLayout::independent(width));
            [0, 1, 2].map(|c| {
                e.var_mean.iter().map(|v| v[c]).sum::<f64>() * (chunks as u32 * spp) as f64
            })
        };
        let var_source = spread(&sources);
        let var_difference = spread(&differences);
        let spatial_gain = match spatial {
            Some(params) if var_difference.iter().sum::<f64>() > 0.0 => {
                // Pure noise with the difference's spread: (D_0 − D_1) / √2.
                let noise: Vec<[f32; 3]> = differences[0]
                    .iter()
                    .zip(&differences[1])
                    .map(|(a, b)| {
                        [0, 1, 2].map(|c| (a[c] - b[c]) * std::f32::consts::FRAC_1_SQRT_2)
                    })
                    .collect();
                let filtered = spatial::denoise(&noise, &sources[0], features, width, params);
                let power = |img: &[[f32; 3]]| -> f64 {
                    img.iter().flatten().map(|&x| (x as f64) * (x as f64)).sum()
                };
                (power(&noise) / power(&filtered).max(f64::MIN_POSITIVE)).max(1.0)
            }
            _ => 1.0,
        };
        let seconds_per_spp = seconds / (chunks as f64 * spp as f64);
        let cost = [0, 1, 2].map(|c| {
            (var_source[c] + var_difference[c] / (n_eff * spatial_gain)) * seconds_per_spp
        });
        candidates.push(Candidate {
            factor,
            var_source,
            var_difference,
            spatial_gain,
            seconds_per_spp,
            cost,
        });
    }
    let best = [0, 1, 2].map(|c| {
        candidates
            .iter()
            .min_by(|a, b| a.cost[c].total_cmp(&b.cost[c]))
            .expect("candidates")
            .factor
    });
    Pilot {
        factor: best,
        candidates,
        seconds: start.elapsed().as_secs_f64(),
    }
}
