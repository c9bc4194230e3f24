//! `run_scene`'s regularized rows: the sequences (the paper's predictor, the spatial
//! filter, the default `mediareg regularize`, its radiance control, the fixed-factor
//! differences), each at the budget less its pipeline's overhead, and where the
//! default row's gain goes (`decompose`).

use std::time::Instant;

use anyhow::{anyhow, Result};
use glam::Vec3;

use super::{
    budget_seconds, budget_spp, default_options, orbit_about_centre, seconds_per_spp,
    sequence_options, spp_for, MethodImage, SceneRun, TableRun,
};
use crate::integrator::volpath::Estimand;
use crate::integrator::RenderOptions;
use crate::regularize::pilot::{self, Pilot};
use crate::regularize::sequence::CameraPath;
use crate::regularize::spatial::BilateralParams;
use crate::regularize::{self, Regularized};
use crate::report::decompose::{self, Decomposition};
use crate::report::row::{Accounting, Method};

/// One regularized row to render.
struct SequenceRun {
    method: Method,
    options: regularize::Options,
    /// Added to the run's seed for the row's shot (each method its own streams).
    seed_offset: u64,
    /// Seconds per spp of its frames (`None` at an spp budget).
    per_spp: Option<f64>,
}

/// Renders the regularized rows, in order; returns the default sequence's whole time
/// (the still baselines' budget) when it ran.
pub(super) fn run_sequences(
    ctx: &SceneRun,
    run: &mut TableRun,
    volpath_per_spp: Option<f64>,
) -> Result<Option<f64>> {
    let mut still_seconds = None;
    for sequence in sequence_runs(ctx, run, volpath_per_spp) {
        let sequence_seconds = run_sequence(ctx, run, &sequence)?;
        if sequence.method == Method::Regularized {
            still_seconds = Some(sequence_seconds);
        }
    }
    Ok(still_seconds)
}

/// The sequences: the paper's predictor, the default, the control (and the
/// fixed-factor differences), each with its seconds per spp; those the run skips left
/// out. Notes in `run` when the camera cannot orbit.
fn sequence_runs(
    ctx: &SceneRun,
    run: &mut TableRun,
    volpath_per_spp: Option<f64>,
) -> Vec<SequenceRun> {
    let (opts, scene, medium, name) = (ctx.opts, &ctx.scene, ctx.medium, ctx.name);
    let path = orbit_about_centre(opts, scene).unwrap_or_else(|| {
        run.notes.push(format!(
            "{name}: the image centre sees no surface, so the regularized sequence keeps the camera still (frames differ only in noise)"
        ));
        CameraPath::Static
    });
    let temporal = sequence_options(opts, medium, ctx.factor, path);
    let spatial = regularize::Options {
        frames: 1,
        path: CameraPath::Static,
        spatial: Some(BilateralParams::default()),
        ..temporal.clone()
    };
    let auto = default_options(opts, &temporal);
    let control = regularize::Options {
        method: regularize::Method::Radiance,
        auto_factor: None,
        ..auto.clone()
    };
    // Its frames render at the source albedo (shorter paths): calibrate there.
    let target_albedo = scene.media[medium as usize].albedo;
    let at_source = |factor: f32| {
        RenderOptions {
            estimand: Estimand::AlbedoDerivative(medium),
            ..Default::default()
        }
        .with_albedo(scene, medium, target_albedo * factor)
    };
    let per_spp_gradient = ctx.calibrate(&at_source(ctx.factor));
    // The default renders the difference (a second estimate per path) and, through
    // OIDN, the seen emission: calibrated as it renders.
    let per_spp_default = match auto.auto_factor {
        Some(_) => per_spp_gradient,
        None => ctx.calibrate(
            &RenderOptions {
                estimand: Estimand::AlbedoDifference {
                    medium,
                    target: target_albedo,
                },
                seen_emission: auto.oidn == regularize::OidnUse::Frames,
                ..Default::default()
            }
            .with_albedo(scene, medium, target_albedo * auto.factor),
        ),
    };
    let fixed: Vec<SequenceRun> = opts
        .difference_factors
        .iter()
        .enumerate()
        .map(|(i, &f)| SequenceRun {
            method: Method::RegularizedDifference,
            options: regularize::Options {
                factor: f,
                auto_factor: None,
                ..auto.clone()
            },
            seed_offset: 400 + i as u64,
            per_spp: per_spp_gradient,
        })
        .collect();
    let (paper, filtered) = (Method::RegularizedPaper, Method::VolpathFiltered);
    [
        (paper, temporal, 100u64, per_spp_gradient),
        (Method::RegularizedSpatial, spatial, 200, per_spp_gradient),
        (Method::Regularized, auto, 300, per_spp_default),
        (filtered, control, 500, volpath_per_spp),
    ]
    .into_iter()
    .map(|(method, options, seed_offset, per_spp)| SequenceRun {
        method,
        options,
        seed_offset,
        per_spp,
    })
    .chain(fixed)
    .filter(|s| !ctx.skip(s.method))
    .collect()
}

/// The row's spp: at a time budget, the budget less the pipeline's overhead beside the
/// frames' rendering, over its seconds per spp.
fn sequence_spp(ctx: &SceneRun, run: &mut TableRun, sequence: &SequenceRun) -> Result<u32> {
    let (name, method) = (ctx.name, sequence.method);
    let Some(per_spp) = sequence.per_spp else {
        return Ok(budget_spp(ctx.opts.budget, name, true));
    };
    // The denoising and prediction cost comes out of the frame's budget: measured on a
    // 1-spp run of the same pipeline (at the scene's first seed; the others reuse it).
    let known = run
        .overheads
        .iter()
        .find(|(n, m, _)| n == name && *m == method)
        .map(|o| o.2);
    let overhead = match known {
        Some(o) => o,
        None => {
            let probe_shot = ctx.scene.shot.with(1, ctx.seed.wrapping_add(2_000_000));
            let probe = regularize::regularize(&ctx.scene, &probe_shot, &sequence.options)
                .map_err(|e| anyhow!("{e}"))?;
            let t = &probe.timings;
            let o = t.denoise_and_predict
                + t.frame_denoise
                + (t.pilot + t.check) / probe.frames_rendered as f64;
            run.overheads.push((name.to_string(), method, o));
            o
        }
    };
    Ok(spp_for(budget_seconds(ctx.opts.budget) - overhead, per_spp))
}

/// Renders one sequence and pushes its row (and its still row when asked), with notes
/// on the pilot's choice and on fallbacks, and at the scene's first seed the default
/// row's decomposition; returns the whole sequence's seconds.
fn run_sequence(ctx: &SceneRun, run: &mut TableRun, sequence: &SequenceRun) -> Result<f64> {
    let (name, seed, method) = (ctx.name, ctx.seed, sequence.method);
    let spp = sequence_spp(ctx, run, sequence)?;
    let shot = ctx
        .scene
        .shot
        .with(spp, seed.wrapping_add(sequence.seed_offset));
    let started = Instant::now();
    let r =
        regularize::regularize(&ctx.scene, &shot, &sequence.options).map_err(|e| anyhow!("{e}"))?;
    let sequence_seconds = started.elapsed().as_secs_f64();
    if let Some(p) = &r.pilot {
        run.notes.push(format!(
            "{name} seed {seed} {}: the pilot chose the factors {:?} (R, G, B) in {:.1} s",
            method.as_str(),
            p.factor,
            p.seconds
        ));
    }
    if r.fallbacks > 0 {
        run.notes.push(format!(
            "{name} seed {seed} {}: {} channel values could not be predicted and keep the source radiance",
            method.as_str(),
            r.fallbacks
        ));
    }
    if let Some(c) = &r.pipeline_check {
        run.notes.push(format!(
            "{name} seed {seed} {}: the check picked {} ({}) in {:.2} s",
            method.as_str(),
            c.chosen.as_str(),
            c.errors_by_name(),
            c.seconds
        ));
    }
    // One frame of the sequence, and the pilot's and the check's share of it (each
    // serves the whole sequence).
    let t = &r.timings;
    let seconds = t.target_frame
        + t.frame_denoise
        + t.denoise_and_predict
        + (t.pilot + t.check) / r.frames_rendered as f64;
    let is_sequence = method != Method::RegularizedSpatial;
    let out = MethodImage {
        method,
        accounting: Accounting::Frame,
        factor: (method != Method::VolpathFiltered).then(|| factor_of(&r)),
        image: &r.predicted,
        spp,
        seconds,
        sequence: is_sequence.then_some((r.frames_rendered, sequence_seconds)),
        // The default's still row is `regularize --frames 1` at this time
        // (`run_still_regularized`): one image is what a still asks for.
        still_seconds: (ctx.opts.still && is_sequence && method != Method::Regularized)
            .then_some(sequence_seconds),
    };
    let mse_corrected = ctx.push(run, out)?;
    if let (Method::Regularized, Some(pilot), true) = (method, &r.pilot, ctx.first_seed) {
        let decomposition = decompose_scene(ctx, &sequence.options, pilot, spp, mse_corrected);
        run.decomposition.push(decomposition);
    }
    Ok(sequence_seconds)
}

/// The factor per channel the sequence rendered at: source over target albedo (1 where
/// the target is black).
fn factor_of(r: &Regularized) -> [f32; 3] {
    let (source, target) = (r.albedos.source.to_array(), r.albedos.target.to_array());
    [0, 1, 2].map(|c| match target[c] > 0.0 {
        true => source[c] / target[c],
        false => 1.0,
    })
}

/// Where the automatic row's gain goes (`decompose`): the pilot's terms, and the time
/// per spp and mean path vertices measured at the target and the chosen albedo.
fn decompose_scene(
    ctx: &SceneRun,
    ropts: &regularize::Options,
    pilot: &Pilot,
    spp: u32,
    mse_corrected: f64,
) -> Decomposition {
    let (scene, medium) = (&ctx.scene, ctx.medium);
    let target = scene.media[medium as usize].albedo;
    let source = target * Vec3::from(pilot.factor);
    let shot = &scene.shot;
    let (w, h) = shot.film.crop_size;
    let n_eff = pilot::effective_frames(ropts.frames, ropts.w_a);
    let terms = decompose::pilot_terms(pilot, w * h, n_eff);
    let seed = shot.seed.wrapping_add(6_000_000);
    let difference = RenderOptions {
        estimand: Estimand::AlbedoDifference { medium, target },
        ..Default::default()
    }
    .with_albedo(scene, medium, source);
    let predicted_variance = (terms.var_source + terms.var_difference_denoised) / spp as f64;
    Decomposition {
        scene: ctx.name.to_string(),
        factor: pilot.factor,
        seconds_per_spp_target: seconds_per_spp(scene, &RenderOptions::default(), 1.0, seed),
        seconds_per_spp_source: seconds_per_spp(scene, &difference, 1.0, seed),
        vertices_target: decompose::mean_vertices(scene, shot, medium, target, 4),
        vertices_source: decompose::mean_vertices(scene, shot, medium, source, 4),
        var_target: terms.var_target,
        var_source: terms.var_source,
        var_difference: terms.var_difference,
        var_difference_denoised: terms.var_difference_denoised,
        spp,
        predicted_variance,
        mse_corrected,
        bias2: mse_corrected - predicted_variance,
    }
}
