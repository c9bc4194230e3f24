//! Reverse mode (Mitsuba 3's `dr.backward` through `prbvolpath`): for an adjoint image
//! A (∂L/∂I per pixel and channel), the gradient of L = Σ A · I in every stored value of
//! one grid medium's sigma_t (before `scale`) and albedo volumes, estimated by path
//! replay (`volpath::sample_adjoint`) with the tracking of `medium::differential`.
//!
//! A sample's radiance enters pixel p of the developed image with weight w_p / W_p (its
//! filter weight over the pixel's weight sum), so its adjoint is Σ_p A_p w_p / W_p; the
//! weight sums depend on the sample positions alone and are found first. Each thread
//! scatters into buffers of its own (no lock in the loop), summed at the end: the
//! buffers cost threads × (values of the differentiated grids) × 4 bytes.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use glam::{Vec2, Vec3};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

use super::volpath::{
    self, AdjointDefect, AdjointParams, AdjointPath, Estimand, GridGradients, PathSettings,
};
use crate::image::Image;
use crate::medium::differential::DifferentialTracking;
use crate::medium::grid::Source;
use crate::sampling::{PaddedScrambles, Pcg32, PixelSamples};
use crate::scene::film::{ImageBlock, Rfilter};
use crate::scene::shot::Shot;
use crate::scene::{IntegratorKind, Scene};

/// Where the sample indices of the ghosts' streams start (far from the paths').
const GHOST_STREAMS: u64 = 1 << 62;

/// What a reverse-mode render differentiates and how it reports.
#[derive(Clone, Debug, Default)]
pub struct BackwardOptions {
    pub medium: u32,
    pub sigma_t: bool,
    pub albedo: bool,
    pub show_progress: bool,
    /// Set to stop early: the gradient of the samples done so far is returned, scaled
    /// as if they were all (`Gradients::interrupted`).
    pub cancel: Option<Arc<AtomicBool>>,
    /// A deliberately wrong estimator, for the power tests.
    #[doc(hidden)]
    pub defect: Option<AdjointDefect>,
}

/// ∂L/∂value for each stored value of the grids asked for (their data's layout).
#[derive(Clone, Debug)]
pub struct Gradients {
    pub sigma_t: Option<Vec<f32>>,
    pub albedo: Option<Vec<f32>>,
    pub seconds: f64,
    pub interrupted: bool,
}

/// Why a scene cannot be differentiated in reverse mode.
#[derive(Debug, PartialEq)]
pub enum BackwardError {
    NotVolpath,
    NotHeterogeneous,
    /// The volume asked for is no grid (`sigma_t` or `albedo`).
    NotAGrid(&'static str),
    ChromaticExtinction,
    NothingAsked,
    LuminanceFilm,
    AdjointSize {
        adjoint: (usize, usize),
        film: (usize, usize),
    },
}

impl std::fmt::Display for BackwardError {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        match self {
            BackwardError::NotVolpath => write!(
                f,
                "reverse-mode gradients need the volpath integrator (add --integrator volpath)"
            ),
            BackwardError::NotHeterogeneous => write!(
                f,
                "the medium is not a heterogeneous one with grid volumes: differentiate a \
                 homogeneous medium's parameters with `render --gradient` instead"
            ),
            BackwardError::NotAGrid(v) => write!(
                f,
                "the medium's {v} is no gridvolume, so it has no voxels to differentiate \
                 (leave {v} out of --params, or give the medium a {v} gridvolume)"
            ),
            BackwardError::ChromaticExtinction => write!(
                f,
                "the medium's sigma_t grid has 3 channels; reverse mode differentiates \
                 1-channel density grids only (Mitsuba's usual density)"
            ),
            BackwardError::NothingAsked => write!(f, "no parameter to differentiate"),
            BackwardError::LuminanceFilm => write!(
                f,
                "the film's pixel_format is luminance; give the scene an rgb film for \
                 reverse mode"
            ),
            BackwardError::AdjointSize { adjoint, film } => write!(
                f,
                "the adjoint image is {}x{} but the film renders {}x{}",
                adjoint.0, adjoint.1, film.0, film.1
            ),
        }
    }
}

impl std::error::Error for BackwardError {}

/// The reverse-mode settings for `opts` on `scene`, checked.
pub fn adjoint_params(
    scene: &Scene,
    opts: &BackwardOptions,
) -> Result<AdjointParams, BackwardError> {
    if !matches!(scene.integrator.kind, IntegratorKind::Volpath) {
        return Err(BackwardError::NotVolpath);
    }
    if !opts.sigma_t && !opts.albedo {
        return Err(BackwardError::NothingAsked);
    }
    let het = scene.media[opts.medium as usize]
        .heterogeneous
        .as_deref()
        .ok_or(BackwardError::NotHeterogeneous)?;
    if !het.sigma_t.is_grey() {
        return Err(BackwardError::ChromaticExtinction);
    }
    if opts.sigma_t && !matches!(het.sigma_t.source, Source::Grid { .. }) {
        return Err(BackwardError::NotAGrid("sigma_t"));
    }
    if opts.albedo && !matches!(het.albedo.source, Source::Grid { .. }) {
        return Err(BackwardError::NotAGrid("albedo"));
    }
    Ok(AdjointParams {
        medium: opts.medium,
        sigma_t: opts.sigma_t,
        albedo: opts.albedo,
        tracking: DifferentialTracking::for_medium(het),
        defect: opts.defect,
    })
}

/// The gradient of Σ A · I, I the image of `scene` through `shot`, in the voxels
/// `opts` names.
pub fn backward(
    scene: &Scene,
    shot: &Shot,
    adjoint: &Image,
    opts: &BackwardOptions,
) -> Result<Gradients, BackwardError> {
    let params = adjoint_params(scene, opts)?;
    let film = &shot.film;
    if film.pixel_format.is_luminance() {
        return Err(BackwardError::LuminanceFilm);
    }
    let (cw, ch) = film.crop_size;
    if (adjoint.width, adjoint.height) != (cw, ch) {
        return Err(BackwardError::AdjointSize {
            adjoint: (adjoint.width, adjoint.height),
            film: (cw, ch),
        });
    }
    let het = scene.media[opts.medium as usize]
        .heterogeneous
        .as_deref()
        .ok_or(BackwardError::NotHeterogeneous)?;
    let sizes = (
        if opts.sigma_t {
            het.sigma_t.values()
        } else {
            0
        },
        if opts.albedo { het.albedo.values() } else { 0 },
    );
    let albedo: Vec<Vec3> = scene.media.iter().map(|m| m.albedo).collect();
    let settings = PathSettings {
        albedo: &albedo,
        estimand: Estimand::Adjoint(params),
    };
    let per_weight = adjoint_over_weights(shot, adjoint);
    let start = std::time::Instant::now();
    let threads = rayon::current_num_threads().max(1);
    let pool: Vec<Mutex<AdjointPath>> = (0..threads)
        .map(|_| {
            Mutex::new(AdjointPath::new(GridGradients {
                sigma_t: vec![0.0; sizes.0],
                albedo: vec![0.0; sizes.1],
            }))
        })
        .collect();
    let rows: Vec<usize> = (0..ch).collect();
    let bar = progress(opts.show_progress, (cw * ch) as u64 * shot.spp as u64);
    let cancelled = || {
        opts.cancel
            .as_ref()
            .is_some_and(|c| c.load(Ordering::Relaxed))
    };
    let (ox, oy) = film.crop_offset;
    let done_rows: usize = rows
        .par_iter()
        .map(|&y| {
            if cancelled() {
                return 0;
            }
            let slot = rayon::current_thread_index().unwrap_or(0) % threads;
            let mut adj = pool[slot].lock().unwrap_or_else(|e| e.into_inner());
            for x in 0..cw {
                let (fx, fy) = (x + ox, y + oy);
                let pixel = (fy * film.width + fx) as u64;
                let positions = PixelSamples::new(shot.seed, pixel);
                let mut words = Pcg32::for_sample(shot.seed, pixel, u64::MAX - 1);
                let scrambles = PaddedScrambles::new(|| words.next_u32());
                for si in 0..shot.spp {
                    let u = positions.get(si);
                    let pos = Vec2::new(fx as f32 + u.x, fy as f32 + u.y);
                    let weight = sample_adjoint(
                        &per_weight,
                        film.rfilter,
                        (cw, ch),
                        pos - Vec2::new(ox as f32, oy as f32),
                    );
                    if weight == Vec3::ZERO {
                        continue;
                    }
                    let ray = shot.camera.sample_ray(pos);
                    let ray = (ray.o, ray.d, ray.tmax);
                    let rng0 = Pcg32::for_path(shot.seed, pixel, si, &scrambles);
                    // The ghosts' stream: the sample's, apart from its path's.
                    adj.first_pass(
                        weight,
                        Pcg32::for_sample(shot.seed, pixel, GHOST_STREAMS + si as u64),
                    );
                    let first =
                        volpath::sample_adjoint(scene, &settings, ray, &mut rng0.clone(), &mut adj);
                    if !first.radiance.is_finite() {
                        continue;
                    }
                    adj.second_pass(first.radiance);
                    volpath::sample_adjoint(scene, &settings, ray, &mut rng0.clone(), &mut adj);
                }
            }
            bar.inc(cw as u64 * shot.spp as u64);
            1
        })
        .sum();
    bar.finish_and_clear();
    let mut sigma_t = opts.sigma_t.then(|| vec![0.0f32; sizes.0]);
    let mut albedo_grad = opts.albedo.then(|| vec![0.0f32; sizes.1]);
    // Rows not done (cancelled) leave the sum short by their share: scaled back up.
    let scale = if done_rows > 0 {
        ch as f32 / done_rows as f32
    } else {
        0.0
    };
    for slot in pool {
        let adj = slot.into_inner().unwrap_or_else(|e| e.into_inner());
        for (sum, part) in [
            (&mut sigma_t, &adj.grads.sigma_t),
            (&mut albedo_grad, &adj.grads.albedo),
        ] {
            if let Some(sum) = sum {
                for (s, v) in sum.iter_mut().zip(part) {
                    // A non-finite value (never expected) is dropped, never written.
                    if v.is_finite() {
                        *s += v * scale;
                    }
                }
            }
        }
    }
    Ok(Gradients {
        sigma_t,
        albedo: albedo_grad,
        seconds: start.elapsed().as_secs_f64(),
        interrupted: done_rows < ch,
    })
}

fn progress(show: bool, total: u64) -> ProgressBar {
    if !show {
        return ProgressBar::hidden();
    }
    let b = ProgressBar::new(total);
    b.set_style(
        ProgressStyle::with_template(
            "{bar:40} {percent:>3}%  {human_pos}/{human_len} samples (adjoint)  {per_sec}  ETA {eta}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    b
}

/// A / W per pixel of the crop: the adjoint over the weight sum of the samples the
/// shot puts there (0 where none lands).
fn adjoint_over_weights(shot: &Shot, adjoint: &Image) -> Vec<Vec3> {
    let film = &shot.film;
    let (cw, ch) = film.crop_size;
    let (ox, oy) = film.crop_offset;
    let border = film.rfilter.border();
    let mut weights = ImageBlock::new((0, 0), (cw, ch), border);
    for y in 0..ch {
        for x in 0..cw {
            let (fx, fy) = (x + ox, y + oy);
            let positions = PixelSamples::new(shot.seed, (fy * film.width + fx) as u64);
            for si in 0..shot.spp {
                let u = positions.get(si);
                weights.put((x as f32 + u.x, y as f32 + u.y), Vec3::ZERO, &film.rfilter);
            }
        }
    }
    weights
        .weight_sums()
        .iter()
        .zip(&adjoint.pixels)
        .map(|(&w, a)| match w > 0.0 {
            true => Vec3::from(*a) / w,
            false => Vec3::ZERO,
        })
        .collect()
}

/// The adjoint of one sample at crop position `pos`: Σ_p (A / W)_p w_p(pos), the filter
/// weights as `ImageBlock::put` gives them.
fn sample_adjoint(per_weight: &[Vec3], filter: Rfilter, (w, h): (usize, usize), pos: Vec2) -> Vec3 {
    if let Rfilter::Box = filter {
        let (x, y) = (pos.x.floor(), pos.y.floor());
        if x >= 0.0 && y >= 0.0 && (x as usize) < w && (y as usize) < h {
            return per_weight[y as usize * w + x as usize];
        }
        return Vec3::ZERO;
    }
    let r = filter.radius();
    let (cx, cy) = (pos.x - 0.5, pos.y - 0.5);
    let x0 = (cx - r).ceil().max(0.0) as i64;
    let x1 = ((cx + r).floor() as i64).min(w as i64 - 1);
    let y0 = (cy - r).ceil().max(0.0) as i64;
    let y1 = ((cy + r).floor() as i64).min(h as i64 - 1);
    let mut sum = Vec3::ZERO;
    for y in y0..=y1 {
        let wy = filter.eval(y as f32 - cy);
        for x in x0..=x1 {
            sum += per_weight[y as usize * w + x as usize] * (filter.eval(x as f32 - cx) * wy);
        }
    }
    sum
}
