//! The whole method, as `mediareg regularize` runs it:
//!
//! 1. choose α_s = factor · α_t (α_t from the scene file; the factor given, or chosen per
//!    channel by `pilot`), rendered as an albedo override (the scene is only read);
//! 2. render the camera sequence at α_s, radiance and d(radiance)/d(albedo) (or, for the
//!    difference predictor, R(α_t) − R(α_s)), frame k with seed + k so that frames have
//!    independent noise;
//! 3. reproject the earlier frames' gradients into the target frame and blend them
//!    (Eq. 10), then optionally filter spatially; the radiance is never denoised;
//! 4. predict the target-albedo image (Eq. 11–12, a baseline, or R_s + the difference),
//!    with c_β given or fitted to a cheap render (`fit`).

use std::time::Instant;

use glam::{Mat4, Vec3, Vec3A};
use indicatif::{ProgressBar, ProgressStyle};

use super::fallback::{self, OidnCheck};
use super::fit::fit_c_beta;
use super::options::validate;
pub use super::options::{CBeta, Method, OidnUse, Options, RegularizeError, Reproject};
use super::pick::{self, CheckInput, PipelineCheck, RawFrame};
pub use super::pilot::PilotSize;
use super::pilot::{self, Pilot, PilotSettings};
use super::predict::{Albedos, Predictor};
use super::reproject;
use super::sequence::CameraPath;
use super::spatial;
use super::temporal::{self, Reprojection};
use crate::denoise::{self, AuxUse};
use crate::image::Image;
use crate::integrator::volpath::Estimand;
use crate::integrator::{aovs, render, RenderOptions, Rendered};
use crate::scene::shot::Shot;
use crate::scene::Scene;

mod picked;

/// Seconds spent in each step.
#[derive(Clone, Debug, Default)]
pub struct Timings {
    /// The target frame's render (what one frame of a sequence costs).
    pub target_frame: f64,
    /// All frames of the sequence.
    pub frames: f64,
    /// The cheap render c_β is fitted to, and the fit.
    pub fit: f64,
    /// Reprojection, blending, spatial filter and prediction.
    pub denoise_and_predict: f64,
    /// The pilot that chose the factor (0 without one).
    pub pilot: f64,
    /// The target frame's own denoising (`OidnUse::Frames`) and the sharpening of its
    /// seen emission, beside `target_frame`.
    pub frame_denoise: f64,
    /// The check that picked the pipeline (`pick`; 0 without one), the denoising of the
    /// pipelines not chosen included: like the pilot, once per sequence.
    pub check: f64,
}

pub struct Regularized {
    /// The prediction at the target albedo.
    pub predicted: Image,
    /// The target frame rendered at the source albedo.
    pub source: Image,
    pub raw_gradient: Image,
    /// The gradient (difference, radiance) blended over frames, before any spatial filter.
    pub blended: Image,
    /// What the filters made of `blended`.
    pub gradient: Image,
    /// The target frame's directly seen emission (`RenderOptions::seen_emission`),
    /// sharpened at emitter edges, where OIDN filters.
    pub seen_emission: Option<Image>,
    pub albedos: Albedos,
    /// The c_β used (the paper's predictor only).
    pub c_beta: Option<f32>,
    /// Channel values that could not be predicted and kept R_s (predict.rs).
    pub fallbacks: usize,
    /// Frames blended per pixel, averaged over the image.
    pub mean_frames: f64,
    pub frames_rendered: usize,
    pub timings: Timings,
    /// Samples or gradient values that were NaN or Inf and were dropped.
    pub invalid_samples: u64,
    /// The pilot's measurements, where it chose the factor.
    pub pilot: Option<Pilot>,
    /// The factor was to be chosen, but the pilot would have cost more than
    /// `pilot::MAX_SHARE` of the render: the run is plain volpath (factor 1).
    pub pilot_unaffordable: bool,
    /// One plain frame with OIDN: whether OIDN lowered the error (`fallback`).
    pub oidn_check: Option<OidnCheck>,
    /// Which pipeline the frame came from, and why (`pick`), where one was picked.
    pub pipeline_check: Option<PipelineCheck>,
}

/// Runs the method on `scene` through `shot`, whose camera is the target frame. The
/// sequence's frames are changed copies of the shot, and the source albedo an override
/// of the render; the scene is only read.
pub fn regularize(
    scene: &Scene,
    shot: &Shot,
    opts: &Options,
) -> Result<Regularized, RegularizeError> {
    validate(scene, opts)?;
    if one_plain_frame(opts) {
        return plain_frame(scene, shot, opts);
    }
    // The first visible point of each pixel: the guides of the spatial filter and of
    // the exact reprojection (noise-free, one ray per pixel).
    let features = spatial::first_hit_features(scene, shot);
    // Step 1: the source albedo (the pilot's factor, if asked), and the predictor.
    let choice = choose_albedos(scene, shot, opts, &features)?;
    let run = Run::new(scene, shot, opts, &features, choice.albedos);
    let mut timings = Timings {
        pilot: choice.pilot.as_ref().map_or(0.0, |p| p.seconds),
        ..Default::default()
    };
    if opts.pick && opts.oidn == OidnUse::Frames && run.frames.len() > 1 {
        if let Estimand::AlbedoDifference { .. } = run.gradient {
            return run.picked(choice, timings);
        }
    }

    // Step 2: the sequence, earliest frame first.
    let Sequence {
        mut gradients,
        source,
        seen_emission,
        mut invalid_samples,
    } = run.render_sequence(&mut timings)?;

    // Step 3: reproject, blend, filter — all in the target frame.
    let start = Instant::now();
    let filtered = run.blend_and_filter(&gradients, &source, seen_emission.as_ref())?;
    timings.denoise_and_predict = start.elapsed().as_secs_f64();

    // Step 4: c_β, then the prediction.
    let predictor = run.fitted_predictor(
        choice.predictor,
        &source,
        &filtered.denoised,
        &mut timings,
        &mut invalid_samples,
    );
    let start = Instant::now();
    let (predicted, fallbacks) = run.predict(
        &predictor,
        &source,
        &filtered.denoised,
        seen_emission.as_ref(),
    )?;
    timings.denoise_and_predict += start.elapsed().as_secs_f64();
    run.bar.finish_and_clear();

    let image = |pixels| as_image(source.width, source.height, pixels);
    let c_beta = match predictor {
        Predictor::Paper { c_beta } => Some(c_beta),
        _ => None,
    };
    Ok(Regularized {
        predicted: image(predicted),
        raw_gradient: gradients.swap_remove(0),
        blended: image(filtered.blended),
        gradient: image(filtered.denoised),
        seen_emission,
        source,
        albedos: choice.albedos,
        c_beta,
        fallbacks,
        mean_frames: filtered.mean_frames,
        frames_rendered: run.frames.len(),
        timings,
        invalid_samples,
        pilot: choice.pilot,
        pilot_unaffordable: choice.pilot_unaffordable,
        oidn_check: None,
        pipeline_check: None,
    })
}

/// Whether the run is one plain frame through OIDN: OIDN where it lowers the error
/// (`fallback`); nothing of the sequence's machinery is needed.
fn one_plain_frame(opts: &Options) -> bool {
    opts.frames == 1
        && opts.oidn == OidnUse::Frames
        && match opts.method {
            Method::Radiance => true,
            Method::Difference => opts.auto_factor.is_none() && opts.factor == 1.0,
            _ => false,
        }
}

/// The run of one plain frame (`one_plain_frame`): the frame, through OIDN where
/// `fallback`'s check finds that OIDN lowers the error; the gradients are zero.
fn plain_frame(scene: &Scene, shot: &Shot, opts: &Options) -> Result<Regularized, RegularizeError> {
    let medium = &scene.media[opts.medium as usize];
    let f = match opts.oidn_check {
        true => fallback::plain_or_oidn(scene, shot),
        false => fallback::through_oidn(scene, shot),
    }
    .map_err(RegularizeError::Denoise)?;
    let zeros = Image {
        pixels: vec![[0.0; 3]; f.plain.pixels.len()],
        ..f.plain.clone()
    };
    Ok(Regularized {
        predicted: f.image,
        source: f.plain,
        raw_gradient: zeros.clone(),
        blended: zeros.clone(),
        gradient: zeros,
        seen_emission: Some(f.seen_emission),
        albedos: Albedos {
            source: medium.albedo,
            target: medium.albedo,
            sigma_t: medium.sigma_t,
        },
        c_beta: None,
        fallbacks: 0,
        mean_frames: 1.0,
        frames_rendered: 1,
        timings: Timings {
            target_frame: f.render_seconds,
            frames: f.render_seconds,
            frame_denoise: f.denoise_seconds,
            ..Default::default()
        },
        invalid_samples: f.invalid_samples,
        pilot: None,
        pilot_unaffordable: false,
        oidn_check: f.check,
        pipeline_check: None,
    })
}

/// Step 1's outcome.
struct Choice {
    /// The albedos the run renders at (source) and predicts (target).
    albedos: Albedos,
    /// The predictor; None while c_β is still to be fitted (step 4).
    predictor: Option<Predictor>,
    /// The pilot that chose the factor, where one ran.
    pilot: Option<Pilot>,
    /// See `Regularized::pilot_unaffordable`.
    pilot_unaffordable: bool,
}

/// Step 1: α_s = factor · α_t, the factor given or chosen by the pilot, and the
/// predictor, both checked (the albedos against the predictor, the c_β fit's settings).
fn choose_albedos(
    scene: &Scene,
    shot: &Shot,
    opts: &Options,
    features: &spatial::Features,
) -> Result<Choice, RegularizeError> {
    let medium = &scene.media[opts.medium as usize];
    // A pilot that would cost more than its share of the render is not run: plain
    // volpath (factor 1) then, which never loses to itself.
    let affordable = opts
        .auto_factor
        .and_then(|size| pilot::affordable(size, opts.frames, shot.spp));
    let pilot_unaffordable = opts.auto_factor.is_some() && affordable.is_none();
    let pilot = affordable.map(|size| {
        let settings = PilotSettings {
            medium: opts.medium,
            frames: opts.frames,
            w_a: opts.w_a,
            spatial: opts.spatial.as_ref(),
            size,
        };
        pilot::choose_factor(scene, shot, features, &settings)
    });
    let factor = match opts.method {
        Method::Radiance => Vec3::ONE,
        _ if pilot_unaffordable => Vec3::ONE,
        _ => pilot
            .as_ref()
            .map_or(Vec3::splat(opts.factor), |p| Vec3::from(p.factor)),
    };
    let albedos = Albedos {
        source: medium.albedo * factor,
        target: medium.albedo,
        sigma_t: medium.sigma_t,
    };
    let predictor = match opts.method {
        Method::Paper(CBeta::Fixed(c_beta)) => Some(Predictor::Paper { c_beta }),
        Method::Paper(CBeta::Fit { .. }) => None,
        Method::Linear => Some(Predictor::Linear),
        Method::LogLinear => Some(Predictor::LogLinear),
        Method::Difference | Method::Radiance => Some(Predictor::Difference),
    };
    match predictor {
        Some(p) => p.validate(&albedos)?,
        // Any valid c_β will do to check the albedos; the fit picks one in range.
        None => Predictor::Linear.validate(&albedos)?,
    }
    if let Method::Paper(CBeta::Fit { spp, at }) = opts.method {
        if spp == 0 || !(at > 0.0 && at <= 1.0) {
            return Err(RegularizeError::Fit { spp, at });
        }
        if (albedos.target - albedos.source).max_element() <= 0.0 {
            return Err(RegularizeError::NothingToFit);
        }
    }
    Ok(Choice {
        albedos,
        predictor,
        pilot,
        pilot_unaffordable,
    })
}

/// What steps 2–4 share: the inputs, the albedos step 1 chose, the frames' cameras,
/// what the frames render beside the radiance, and the progress bar.
struct Run<'a> {
    scene: &'a Scene,
    shot: &'a Shot,
    opts: &'a Options,
    features: &'a spatial::Features,
    albedos: Albedos,
    /// Each frame's camera-to-world, the target frame (k = 0) first.
    frames: Vec<Mat4>,
    gradient: Estimand,
    bar: ProgressBar,
}

/// Step 2's outcome: the frames' gradients (difference, radiance) and the target
/// frame's own images.
struct Sequence {
    /// Per frame, the target frame (k = 0) first.
    gradients: Vec<Image>,
    /// The target frame rendered at the source albedo (through OIDN where it filters
    /// frames and the predictor adds it).
    source: Image,
    /// The target frame's sharpened seen emission, where OIDN filters.
    seen_emission: Option<Image>,
    invalid_samples: u64,
}

/// Step 3's outcome, in the target frame.
struct Filtered {
    /// The gradients blended over frames.
    blended: Vec<[f32; 3]>,
    /// What the filters made of `blended`.
    denoised: Vec<[f32; 3]>,
    /// Frames blended per pixel, averaged over the image.
    mean_frames: f64,
}

/// Frames blended per pixel, averaged over `pixels` pixels: the target frame, and each
/// earlier frame where the pixel reprojects into it.
fn mean_frames(maps: &[Reprojection], pixels: usize) -> f64 {
    let found: usize = maps
        .iter()
        .map(|m| m.iter().filter(|p| p.is_some()).count())
        .sum();
    1.0 + found as f64 / pixels as f64
}

/// A `width` × `height` image of `pixels`.
fn as_image(width: usize, height: usize, pixels: Vec<[f32; 3]>) -> Image {
    Image {
        width,
        height,
        pixels,
    }
}

impl<'a> Run<'a> {
    /// The run of `opts` at `albedos` (step 1's) on the frames of `opts.path`.
    fn new(
        scene: &'a Scene,
        shot: &'a Shot,
        opts: &'a Options,
        features: &'a spatial::Features,
        albedos: Albedos,
    ) -> Self {
        let frames = opts.path.frames(shot.camera.to_world, opts.frames);
        let fit_steps = matches!(opts.method, Method::Paper(CBeta::Fit { .. })) as u64;
        let bar = if opts.show_progress {
            let b = ProgressBar::new(frames.len() as u64 + fit_steps);
            b.set_style(
                ProgressStyle::with_template("{bar:40} {pos}/{len} frames  ETA {eta}  {msg}")
                    .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            b
        } else {
            ProgressBar::hidden()
        };
        // What the frames render beside the radiance: the derivative, or the difference.
        let gradient = match opts.method {
            Method::Difference => Estimand::AlbedoDifference {
                medium: opts.medium,
                target: albedos.target,
            },
            Method::Radiance => Estimand::RadianceOnly,
            _ => Estimand::AlbedoDerivative(opts.medium),
        };
        // At factor 1 the difference is 0: the frames are plain renders (`render`'s image,
        // bit for bit), which is how the method falls back to plain volpath.
        let plain = opts.method == Method::Radiance
            || (opts.method == Method::Difference && albedos.source == albedos.target);
        Run {
            scene,
            shot,
            opts,
            features,
            albedos,
            frames,
            gradient: if plain {
                Estimand::RadianceOnly
            } else {
                gradient
            },
            bar,
        }
    }

    /// One render of the shot from `to_world` with `seed` at `albedo`, of `spp` samples
    /// (the shot's if None), with the run's gradient and, if asked, the seen emission.
    fn render_frame(
        &self,
        to_world: Mat4,
        seed: u64,
        albedo: Vec3,
        spp: Option<u32>,
        seen_emission: bool,
    ) -> Rendered {
        let mut frame = self.shot.with(spp.unwrap_or(self.shot.spp), seed);
        frame.camera.to_world = to_world;
        let options = RenderOptions {
            estimand: self.gradient,
            seen_emission,
            ..Default::default()
        }
        .with_albedo(self.scene, self.opts.medium, albedo);
        render(self.scene, &frame, &options)
    }

    /// Step 2: renders the frames at the source albedo, earliest first, frame k with
    /// seed + k, each denoised where OIDN filters frames; adds their seconds to `timings`.
    fn render_sequence(&self, timings: &mut Timings) -> Result<Sequence, RegularizeError> {
        let (opts, n) = (self.opts, self.frames.len());
        let oidn = opts.oidn != OidnUse::None;
        let mut gradients: Vec<Image> = Vec::with_capacity(n);
        let mut source = None;
        let mut seen_emission = None;
        let mut invalid_samples = 0;
        for k in (0..n).rev() {
            self.bar.set_message(format!("frame k = {k}"));
            let r = self.render_frame(
                self.frames[k],
                self.shot.seed.wrapping_add(k as u64),
                self.albedos.source,
                None,
                oidn && (k == 0 || opts.oidn == OidnUse::Frames),
            );
            timings.frames += r.stats.seconds;
            invalid_samples += r.stats.invalid_samples;
            let frame_gradient = match (opts.method, &r.gradient) {
                (Method::Radiance, _) => r.image.clone(),
                (_, Some(g)) => g.clone(),
                (_, None) => Image {
                    pixels: vec![[0.0; 3]; r.image.pixels.len()],
                    ..r.image.clone()
                },
            };
            // Charged to the frame (in a sequence each frame is denoised once).
            let start = Instant::now();
            let mut seen = r.seen_emission;
            if let Some(seen) = &mut seen {
                let mut frame_shot = self.shot.clone();
                frame_shot.camera.to_world = self.frames[k];
                aovs::sharpen_seen_emission(self.scene, &frame_shot, seen);
            }
            let (frame_gradient, frame_source) =
                self.denoise_frame(k, frame_gradient, r.image, seen.as_ref())?;
            let spent = start.elapsed().as_secs_f64();
            timings.frames += spent;
            if k == 0 {
                timings.target_frame = r.stats.seconds;
                timings.frame_denoise = spent;
                source = Some(frame_source);
                seen_emission = seen;
            }
            gradients.push(frame_gradient);
            self.bar.inc(1);
        }
        gradients.reverse();
        Ok(Sequence {
            gradients,
            source: source.expect("frame 0 is rendered"),
            seen_emission,
            invalid_samples,
        })
    }

    /// Frame k's gradient and source image through OIDN where it filters frames
    /// (`OidnUse::Frames`), else as rendered.
    fn denoise_frame(
        &self,
        k: usize,
        gradient: Image,
        source: Image,
        seen: Option<&Image>,
    ) -> Result<(Image, Image), RegularizeError> {
        if self.opts.oidn != OidnUse::Frames {
            return Ok((gradient, source));
        }
        let failed = RegularizeError::Denoise;
        match self.opts.method {
            Method::Radiance => {
                let gradient =
                    denoise::oidn(&gradient, seen, None, AuxUse::None).map_err(failed)?;
                Ok((gradient, source))
            }
            _ => {
                let gradient =
                    denoise::oidn_signed(&gradient, None, AuxUse::None).map_err(failed)?;
                // The difference predictor adds R_s as it is: the target frame's
                // through the same denoiser (D1).
                if k == 0 && self.opts.method == Method::Difference {
                    let source =
                        denoise::oidn(&source, seen, None, AuxUse::None).map_err(failed)?;
                    return Ok((gradient, source));
                }
                Ok((gradient, source))
            }
        }
    }

    /// Each earlier frame's (k ≥ 1) reprojection into the target frame, as
    /// `opts.reproject` asks.
    fn reprojections(&self, w: usize, h: usize) -> Vec<Reprojection> {
        let camera0 = &self.shot.camera;
        (1..self.frames.len())
            .map(|k| {
                let mut cam = camera0.clone();
                cam.to_world = self.frames[k];
                match self.opts.reproject {
                    Reproject::None => temporal::screen_shift(w, h, 0.0, 0.0),
                    Reproject::Exact => {
                        reproject::exact(self.scene, self.shot, self.features, &cam)
                    }
                    Reproject::Shift => {
                        let point = motion_point(&self.opts.path, self.features, w, h);
                        match reproject::screen_motion(camera0, &cam, point) {
                            Some((dx, dy)) => temporal::screen_shift(w, h, dx, dy),
                            None => vec![None; w * h],
                        }
                    }
                }
            })
            .collect()
    }

    /// Step 3: the gradients reprojected into the target frame and blended (Eq. 10),
    /// then filtered: the spatial filter, or OIDN where it filters the blend. The
    /// radiance is never denoised.
    fn blend_and_filter(
        &self,
        gradients: &[Image],
        source: &Image,
        seen_emission: Option<&Image>,
    ) -> Result<Filtered, RegularizeError> {
        let opts = self.opts;
        let (w, h) = (source.width, source.height);
        let maps = self.reprojections(w, h);
        let mean_frames = mean_frames(&maps, w * h);
        let frame_refs: Vec<&[[f32; 3]]> = gradients.iter().map(|g| g.pixels.as_slice()).collect();
        let blended = temporal::blend(&frame_refs, &maps, w, h, opts.w_a);
        let mut denoised = blended.clone();
        if let Some(params) = &opts.spatial {
            denoised = spatial::denoise(&denoised, &source.pixels, self.features, w, params);
        }
        match (opts.oidn, opts.method) {
            (OidnUse::None | OidnUse::Frames, _) => {}
            // The control's blended radiance is an image like any render's.
            (OidnUse::Difference | OidnUse::Prediction, Method::Radiance) => {
                denoised =
                    denoise::oidn(&as_image(w, h, denoised), seen_emission, None, AuxUse::None)
                        .map_err(RegularizeError::Denoise)?
                        .pixels;
            }
            (OidnUse::Difference, _) => {
                denoised = denoise::oidn_signed(&as_image(w, h, denoised), None, AuxUse::None)
                    .map_err(RegularizeError::Denoise)?
                    .pixels;
            }
            (OidnUse::Prediction, _) => {}
        }
        Ok(Filtered {
            blended,
            denoised,
            mean_frames,
        })
    }

    /// Step 4's c_β: the predictor step 1 chose, else (`CBeta::Fit`) the paper's with
    /// c_β fitted to a cheap render between source and target albedo, whose seconds go
    /// to `timings.fit` and invalid samples to `invalid_samples`.
    fn fitted_predictor(
        &self,
        predictor: Option<Predictor>,
        source: &Image,
        denoised: &[[f32; 3]],
        timings: &mut Timings,
        invalid_samples: &mut u64,
    ) -> Predictor {
        let (spp, at) = match (predictor, self.opts.method) {
            (Some(p), _) => return p,
            (None, Method::Paper(CBeta::Fit { spp, at })) => (spp, at),
            (None, _) => unreachable!("only a fitted c_beta leaves the predictor open"),
        };
        let albedos = self.albedos;
        self.bar.set_message("fitting c_beta");
        let fit_albedo = albedos.source + (albedos.target - albedos.source) * at;
        // A seed no frame of the sequence uses.
        let cheap = self.render_frame(
            self.shot.camera.to_world,
            self.shot
                .seed
                .wrapping_add(self.frames.len() as u64 + 1_000_003),
            fit_albedo,
            Some(spp),
            false,
        );
        *invalid_samples += cheap.stats.invalid_samples;
        let start = Instant::now();
        let fit = Albedos {
            target: fit_albedo,
            ..albedos
        };
        let c_beta = fit_c_beta(&fit, &source.pixels, denoised, &cheap.image.pixels);
        timings.fit = cheap.stats.seconds + start.elapsed().as_secs_f64();
        self.bar.inc(1);
        Predictor::Paper { c_beta }
    }

    /// Step 4's prediction at the target albedo from the source image and the filtered
    /// gradient (the control's blended radiance as it is), through OIDN where it filters
    /// the prediction; and how many channel values fell back to R_s.
    fn predict(
        &self,
        predictor: &Predictor,
        source: &Image,
        denoised: &[[f32; 3]],
        seen_emission: Option<&Image>,
    ) -> Result<(Vec<[f32; 3]>, usize), RegularizeError> {
        let method = self.opts.method;
        let (mut predicted, fallbacks) = match method {
            Method::Radiance => (denoised.to_vec(), 0),
            _ => predictor.predict(&self.albedos, &source.pixels, denoised),
        };
        if self.opts.oidn == OidnUse::Prediction && method != Method::Radiance {
            let image = as_image(source.width, source.height, predicted);
            predicted = denoise::oidn(&image, seen_emission, None, AuxUse::None)
                .map_err(RegularizeError::Denoise)?
                .pixels;
        }
        Ok((predicted, fallbacks))
    }
}

/// The point whose screen motion is Eq. 9's motion vector: the orbit's target, else
/// the first visible point at the image centre (a point 1 unit along its ray if none).
fn motion_point(path: &CameraPath, f: &spatial::Features, w: usize, h: usize) -> Vec3A {
    if let CameraPath::Orbit { target, .. } = path {
        return Vec3A::from(*target);
    }
    let i = (h / 2) * w + w / 2;
    if f.depth[i].is_finite() {
        Vec3A::from(f.position[i])
    } else {
        Vec3A::from(f.position[i] + f.direction[i])
    }
}
