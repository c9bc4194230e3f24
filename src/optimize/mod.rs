//! `mediareg optimize`: a grid medium's voxels from images of several views, Mitsuba 3's
//! volume tutorial (`inverse_rendering/volume_optimization.ipynb`) as one loop. For each
//! view in turn: render the image I at the current volume, take the L2 loss
//! L = mean((I − T)²) against its target T, its gradient in every voxel by reverse mode
//! (`integrator::backward`, adjoint image ∂L/∂I = 2 (I − T) / n), and an Adam step on
//! the voxels, each then clamped into its range. Stages run a number of iterations
//! at a grid resolution and spp each; entering a stage at another resolution resamples
//! the grid (nearest, as the tutorial's `dr.upsample` of a tensor, or trilinear) and
//! forgets Adam's moments, as Mitsuba does when a parameter changes shape.
//!
//! The image that sets the adjoint and the gradient's paths take independent seeds, so
//! that the gradient is unbiased for that of the expected image's loss; Mitsuba's
//! `prbvolpath` replays the primal's own paths (the same seed), whose gradient also
//! holds that of the render's variance.

pub mod adam;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

pub use adam::Adam;

use crate::image::Image;
use crate::integrator::backward::{self, BackwardError, BackwardOptions};
use crate::integrator::render::{render, RenderOptions};
use crate::medium::grid::{Filter, Source, Volume};
use crate::scene::shot::Shot;
use crate::scene::Scene;

/// One view: the shot that renders it and its target image.
pub struct View {
    pub shot: Shot,
    pub target: Image,
}

/// A stretch of the schedule: its iterations (each a step per view), the grid
/// resolution (None: as it is) and the spp of its renders.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stage {
    pub iterations: u32,
    pub res: Option<[usize; 3]>,
    pub spp: u32,
    /// Adam's learning rate in this stage (None: the settings').
    pub lr: Option<f32>,
}

/// How to optimize.
#[derive(Clone, Debug)]
pub struct OptimizeSettings {
    pub medium: u32,
    pub sigma_t: bool,
    pub albedo: bool,
    pub lr: f32,
    pub stages: Vec<Stage>,
    /// How a grid is resampled between stages of other resolutions.
    pub upsampling: Filter,
    /// The ranges the values are clamped into after every step.
    pub sigma_t_range: (f32, f32),
    pub albedo_range: (f32, f32),
    /// A uniform starting value of the sigma_t grid (at the first stage's resolution);
    /// None starts from the scene's grid.
    pub init_sigma_t: Option<f32>,
    pub seed: u64,
    pub cancel: Option<Arc<AtomicBool>>,
}

/// One iteration done: the loss summed over the views (each the mean squared error
/// of its render, before the step), the seconds since the start.
#[derive(Clone, Copy, Debug)]
pub struct IterationReport {
    pub iteration: u32,
    pub loss: f64,
    pub seconds: f64,
    pub res: [usize; 3],
    pub spp: u32,
}

/// The optimized grids (their data) and their resolution.
#[derive(Clone, Debug)]
pub struct Grids {
    pub res: [usize; 3],
    pub sigma_t: Option<Vec<f32>>,
    pub albedo: Option<Vec<f32>>,
}

/// What the loop did.
pub struct Optimized {
    pub iterations: Vec<IterationReport>,
    /// The grids after the last step, and those at the start of the iteration with the
    /// lowest loss.
    pub last: Grids,
    pub best: Grids,
    pub interrupted: bool,
}

#[derive(Debug, PartialEq)]
pub enum OptimizeError {
    Backward(BackwardError),
    NoViews,
    TargetSize { view: usize },
    AlbedoResolution,
}

impl std::fmt::Display for OptimizeError {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        match self {
            OptimizeError::Backward(e) => write!(f, "{e}"),
            OptimizeError::NoViews => write!(f, "no target to fit"),
            OptimizeError::TargetSize { view } => {
                write!(f, "target {view} is not the size of its sensor's film")
            }
            OptimizeError::AlbedoResolution => write!(
                f,
                "the albedo grid's resolution differs from sigma_t's; a schedule that \
                 changes resolution resamples both and needs them alike"
            ),
        }
    }
}

impl std::error::Error for OptimizeError {}

/// The grid of `volume` (its resolution and data); None for a constant.
fn grid_of(volume: &Volume) -> Option<([usize; 3], &[f32])> {
    match &volume.source {
        Source::Grid { grid, .. } => Some((grid.res, &grid.data)),
        Source::Const(_) => None,
    }
}

/// Puts `grids` into the scene's medium `mi`.
fn set_grids(scene: &mut Scene, mi: u32, grids: &Grids) {
    let m = &mut scene.media[mi as usize];
    let Some(het) = m.heterogeneous.as_deref() else {
        return;
    };
    let with = |v: &Volume, data: &Option<Vec<f32>>| match data {
        Some(d) => v
            .with_grid(grids.res, d.clone())
            .unwrap_or_else(|| v.clone()),
        None => v.clone(),
    };
    let new = het.with_volumes(
        with(&het.sigma_t, &grids.sigma_t),
        with(&het.albedo, &grids.albedo),
    );
    m.sigma_t = glam::Vec3::splat(new.majorant);
    m.heterogeneous = Some(Box::new(new));
}

/// The scene's grids, resampled to `res` (or as they are).
fn grids_at(scene: &Scene, s: &OptimizeSettings, res: Option<[usize; 3]>) -> Grids {
    let het = scene.media[s.medium as usize]
        .heterogeneous
        .as_deref()
        .expect("checked by backward::adjoint_params");
    let (res0, _) = grid_of(&het.sigma_t)
        .or(grid_of(&het.albedo))
        .expect("a grid");
    let res = res.unwrap_or(res0);
    let take = |on: bool, v: &Volume| -> Option<Vec<f32>> {
        let (r, data) = grid_of(v).filter(|_| on)?;
        Some(match r == res {
            true => data.to_vec(),
            false => v.resampled(res, s.upsampling)?,
        })
    };
    Grids {
        res,
        sigma_t: take(s.sigma_t, &het.sigma_t),
        albedo: take(s.albedo, &het.albedo),
    }
}

/// Mean squared error of `image` against `target` and its adjoint image 2 (I − T) / n.
fn l2_loss(image: &Image, target: &Image) -> (f64, Image) {
    let n = (image.pixels.len() * 3) as f32;
    let mut loss = 0f64;
    let pixels = image
        .pixels
        .iter()
        .zip(&target.pixels)
        .map(|(i, t)| {
            let mut a = [0.0f32; 3];
            for c in 0..3 {
                let r = i[c] - t[c];
                loss += (r as f64) * (r as f64);
                a[c] = 2.0 * r / n;
            }
            a
        })
        .collect();
    let adjoint = Image {
        width: image.width,
        height: image.height,
        pixels,
    };
    (loss / n as f64, adjoint)
}

/// Runs the schedule on `scene`'s medium against `views`; `on_iteration` hears of each
/// iteration with the scene as it then is. The scene is left at the last iterate.
pub fn optimize(
    scene: &mut Scene,
    views: &[View],
    s: &OptimizeSettings,
    mut on_iteration: impl FnMut(&IterationReport, &Scene),
) -> Result<Optimized, OptimizeError> {
    if views.is_empty() {
        return Err(OptimizeError::NoViews);
    }
    for (i, v) in views.iter().enumerate() {
        if (v.target.width, v.target.height) != v.shot.film.crop_size {
            return Err(OptimizeError::TargetSize { view: i });
        }
    }
    let bw = BackwardOptions {
        medium: s.medium,
        sigma_t: s.sigma_t,
        albedo: s.albedo,
        show_progress: false,
        cancel: s.cancel.clone(),
        defect: None,
    };
    backward::adjoint_params(scene, &bw).map_err(OptimizeError::Backward)?;
    {
        let het = scene.media[s.medium as usize].heterogeneous.as_deref();
        let het = het.expect("checked");
        if let (Some((a, _)), Some((b, _))) = (grid_of(&het.sigma_t), grid_of(&het.albedo)) {
            let resampling = s.stages.iter().any(|st| st.res.is_some_and(|r| r != a));
            if s.sigma_t && s.albedo && a != b && resampling {
                return Err(OptimizeError::AlbedoResolution);
            }
        }
    }
    let cancelled = || s.cancel.as_ref().is_some_and(|c| c.load(Ordering::Relaxed));
    let start = Instant::now();
    let mut grids = grids_at(scene, s, s.stages.first().and_then(|st| st.res));
    if let (Some(v), Some(data)) = (s.init_sigma_t, grids.sigma_t.as_mut()) {
        data.fill(v);
    }
    set_grids(scene, s.medium, &grids);
    let mut adam_sigma = Adam::new(s.lr, grids.sigma_t.as_ref().map_or(0, Vec::len));
    let mut adam_albedo = Adam::new(s.lr, grids.albedo.as_ref().map_or(0, Vec::len));
    let mut reports = Vec::new();
    let mut best = (f64::INFINITY, grids.clone());
    let mut iteration = 0u32;
    let mut interrupted = false;
    'stages: for stage in &s.stages {
        let lr = stage.lr.unwrap_or(s.lr);
        (adam_sigma.lr, adam_albedo.lr) = (lr, lr);
        if let Some(res) = stage.res.filter(|&r| r != grids.res) {
            grids = grids_at(scene, s, Some(res));
            set_grids(scene, s.medium, &grids);
            adam_sigma.reset(grids.sigma_t.as_ref().map_or(0, Vec::len));
            adam_albedo.reset(grids.albedo.as_ref().map_or(0, Vec::len));
        }
        for _ in 0..stage.iterations {
            // The grids this iteration's loss is (mostly) measured at.
            let before = grids.clone();
            let mut loss = 0f64;
            for (vi, view) in views.iter().enumerate() {
                if cancelled() {
                    interrupted = true;
                    break 'stages;
                }
                let k = (iteration as u64 * views.len() as u64 + vi as u64) * 2;
                let seed = s.seed.wrapping_mul(1 << 32).wrapping_add(k);
                let opts = RenderOptions {
                    cancel: s.cancel.clone(),
                    ..Default::default()
                };
                let image = render(scene, &view.shot.with(stage.spp, seed), &opts).image;
                let (l, adjoint) = l2_loss(&image, &view.target);
                loss += l;
                let shot = view.shot.with(stage.spp, seed + 1);
                let g = backward::backward(scene, &shot, &adjoint, &bw)
                    .map_err(OptimizeError::Backward)?;
                if g.interrupted {
                    interrupted = true;
                    break 'stages;
                }
                if let (Some(x), Some(g)) = (grids.sigma_t.as_mut(), &g.sigma_t) {
                    adam_sigma.step(x, g, s.sigma_t_range);
                }
                if let (Some(x), Some(g)) = (grids.albedo.as_mut(), &g.albedo) {
                    adam_albedo.step(x, g, s.albedo_range);
                }
                set_grids(scene, s.medium, &grids);
            }
            let report = IterationReport {
                iteration,
                loss,
                seconds: start.elapsed().as_secs_f64(),
                res: grids.res,
                spp: stage.spp,
            };
            if loss < best.0 {
                best = (loss, before);
            }
            on_iteration(&report, scene);
            reports.push(report);
            iteration += 1;
        }
    }
    Ok(Optimized {
        iterations: reports,
        last: grids,
        best: best.1,
        interrupted,
    })
}
