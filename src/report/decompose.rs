//! Where the method's gain goes, per scene (`table1.md`'s last table): what the pilot
//! measured at the target albedo α_t and at the source albedo α_s it chose, and what is
//! left for the denoising's bias.
//!
//! Per pixel and channel, at the run's N spp, the prediction's error is
//!
//!   MSE ≈ [Var(R_s) + Var(F D) / N_eff] / N + bias²,
//!
//! (`regularize::pilot`, Eq. P1). The variances come from the pilot (one sample's,
//! averaged over pixels and channels); bias² is estimated as the run's corrected MSE
//! minus the predicted variance (so it also holds whatever the pilot's variances miss).
//! The mean number of scattering vertices in the medium is weighted by contribution:
//! k̄ = Σ α ∂R/∂α / Σ R (a path with k vertices has weight ∝ α^k), from a short render
//! with the albedo gradient.

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::integrator::volpath::Estimand;
use crate::integrator::{render, RenderOptions};
use crate::regularize::pilot::Pilot;
use crate::scene::shot::Shot;
use crate::scene::Scene;

/// One scene's decomposition (all variances per pixel and channel, of one sample).
#[derive(Serialize, Deserialize, Clone, Debug)]
pub struct Decomposition {
    pub scene: String,
    /// The pilot's factor per channel.
    pub factor: [f32; 3],
    pub seconds_per_spp_target: f64,
    pub seconds_per_spp_source: f64,
    /// Contribution-weighted mean scattering vertices in the medium.
    pub vertices_target: f64,
    pub vertices_source: f64,
    pub var_target: f64,
    pub var_source: f64,
    /// Var(D), the difference before denoising.
    pub var_difference: f64,
    /// Var(F D) / N_eff: after the spatial filter and the blend over frames.
    pub var_difference_denoised: f64,
    /// The run's spp per frame, and the variance predicted for it.
    pub spp: u32,
    pub predicted_variance: f64,
    pub mse_corrected: f64,
    /// The corrected MSE minus the predicted variance.
    pub bias2: f64,
}

/// k̄ = Σ α ∂R/∂α / Σ R at `albedo` for `medium`, from `spp` samples.
pub fn mean_vertices(scene: &Scene, shot: &Shot, medium: u32, albedo: Vec3, spp: u32) -> f64 {
    let options = RenderOptions {
        estimand: Estimand::AlbedoDerivative(medium),
        ..Default::default()
    }
    .with_albedo(scene, medium, albedo);
    let r = render(
        scene,
        &shot.with(spp, shot.seed.wrapping_add(5_000_000)),
        &options,
    );
    let g = r.gradient.expect("a gradient was asked for");
    let a = albedo.to_array();
    let (mut weighted, mut total) = (0.0f64, 0.0f64);
    for (l, d) in r.image.pixels.iter().zip(&g.pixels) {
        for c in 0..3 {
            weighted += (a[c] * d[c]) as f64;
            total += l[c] as f64;
        }
    }
    if total > 0.0 {
        weighted / total
    } else {
        0.0
    }
}

/// The pilot's terms at factor 1 and at its choice, per pixel and channel.
pub struct PilotTerms {
    pub var_target: f64,
    pub var_source: f64,
    pub var_difference: f64,
    pub var_difference_denoised: f64,
}

/// Reads `pilot`'s candidates at factor 1 and at each channel's chosen factor, for an
/// image of `pixels` pixels and a sequence worth `n_eff` frames.
pub fn pilot_terms(pilot: &Pilot, pixels: usize, n_eff: f64) -> PilotTerms {
    let per = (3 * pixels.max(1)) as f64;
    let at = |f: f32| {
        pilot
            .candidates
            .iter()
            .find(|c| c.factor == f)
            .expect("the chosen factor is a candidate")
    };
    let one = at(1.0);
    let (mut var_source, mut var_difference, mut denoised) = (0.0, 0.0, 0.0);
    for c in 0..3 {
        let chosen = at(pilot.factor[c]);
        var_source += chosen.var_source[c];
        var_difference += chosen.var_difference[c];
        denoised += chosen.var_difference_filtered[c] / n_eff;
    }
    PilotTerms {
        var_target: one.var_source.iter().sum::<f64>() / per,
        var_source: var_source / per,
        var_difference: var_difference / per,
        var_difference_denoised: denoised / per,
    }
}
