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

use glam::{Vec3, Vec3A};
use indicatif::{ProgressBar, ProgressStyle};

use super::fallback::{self, OidnCheck};
use super::fit::fit_c_beta;
use super::pilot::{self, Pilot};
use super::predict::{Albedos, Predictor};
use super::reproject;
use super::sequence::CameraPath;
use super::spatial::{self, BilateralParams};
use super::temporal::{self, Reprojection};
use crate::denoise::{self, AuxUse, OidnError};
use crate::error::SceneError;
use crate::image::Image;
use crate::integrator::volpath::Gradient;
use crate::integrator::{aovs, render, RenderOptions};
use crate::scene::shot::Shot;
use crate::scene::{IntegratorKind, Scene};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reproject {
    /// Through each pixel's first visible point, with disocclusion.
    Exact,
    /// One screen-space motion per frame (the paper's Eq. 9).
    Shift,
    /// Frames are blended pixel for pixel (right only for a static camera).
    None,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CBeta {
    Fixed(f32),
    /// Fitted to a render at α_f = α_s + `at` · (α_t − α_s) with `spp` samples per pixel.
    Fit {
        spp: u32,
        at: f32,
    },
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Method {
    Paper(CBeta),
    Linear,
    LogLinear,
    /// The frames render the difference R(α_t) − R(α_s) in their paths instead of the
    /// derivative, which is denoised the same way and added to R_s.
    Difference,
    /// The control: the frames render plain radiance at α_t, which goes through the very
    /// reprojection, blend and filters the method's difference goes through (`factor`
    /// is ignored, nothing is extrapolated).
    Radiance,
}

/// Where Open Image Denoise filters (`render --denoise oidn`'s (D1): the directly seen
/// emission kept out, no auxiliary images).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum OidnUse {
    #[default]
    None,
    /// The blended difference or gradient (R_s stays as rendered).
    Difference,
    /// The prediction R_s + D̃ (the blended difference, unfiltered otherwise): one filter
    /// on an image whose noise the split and the blend lowered.
    Prediction,
    /// Each frame's gradient (difference, radiance) before the blend, the blend then
    /// averaging the denoiser's residual, which differs from frame to frame; with the
    /// difference predictor also the target frame's R_s. Measured best of these on the
    /// Bunny and the Candle (docs/regularize.md): blending raw frames leaves noise
    /// correlated between neighbouring pixels, which OIDN does not remove.
    Frames,
}

#[derive(Clone, Debug)]
pub struct Options {
    pub medium: u32,
    /// α_s = factor · α_t.
    pub factor: f32,
    /// N: the target frame and N − 1 earlier ones.
    pub frames: usize,
    pub w_a: f64,
    pub path: CameraPath,
    pub reproject: Reproject,
    pub spatial: Option<BilateralParams>,
    /// Where Open Image Denoise filters, instead of the joint bilateral filter (`spatial`
    /// is then None).
    pub oidn: OidnUse,
    pub method: Method,
    /// Choose `factor` with a pilot (`pilot`; the difference predictor only): `chunks`
    /// renders of `spp` samples at each candidate factor.
    pub auto_factor: Option<PilotSize>,
    pub show_progress: bool,
}

pub use super::pilot::PilotSize;

impl Default for Options {
    fn default() -> Self {
        Options {
            medium: 0,
            factor: 0.95,
            frames: 11,
            w_a: 0.1,
            path: CameraPath::Static,
            reproject: Reproject::Exact,
            spatial: None,
            oidn: OidnUse::None,
            method: Method::Paper(CBeta::Fixed(0.5)),
            auto_factor: None,
            show_progress: false,
        }
    }
}

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
}

/// Why the method cannot run with these options. The words are the library's; the
/// command line says which of its flags each one concerns.
#[derive(Clone, Debug)]
pub enum RegularizeError {
    /// The scene's integrator is not volpath.
    NotVolpath,
    NoMedium(usize),
    /// The automatic factor is for the difference predictor only.
    AutoFactorNeedsDifference,
    PilotTooSmall {
        chunks: usize,
        spp: u32,
    },
    /// The source factor is outside (0, 1].
    Factor(f32),
    Frames {
        frames: usize,
        w_a: f64,
    },
    /// The c_β fit needs at least 1 spp and `at` in (0, 1].
    Fit {
        spp: u32,
        at: f32,
    },
    /// The c_β fit with equal source and target albedos.
    NothingToFit,
    /// The albedos or c_β the predictor cannot use (`Predictor::validate`).
    Predictor(SceneError),
    /// Open Image Denoise is missing or failed (`Options::oidn`).
    Denoise(OidnError),
}

impl std::fmt::Display for RegularizeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RegularizeError::NotVolpath => write!(
                f,
                "regularize needs the volpath integrator (the scene's integrator ignores media)"
            ),
            RegularizeError::NoMedium(m) => write!(f, "no medium #{m}"),
            RegularizeError::AutoFactorNeedsDifference => write!(
                f,
                "the automatic factor is chosen for the difference predictor; give the factor for the others"
            ),
            RegularizeError::PilotTooSmall { chunks, spp } => write!(
                f,
                "the factor's pilot needs at least 2 renders of at least 1 spp (got {chunks} of {spp})"
            ),
            RegularizeError::Factor(x) => write!(
                f,
                "the source factor {x} must lie in (0, 1]: the source albedo is factor × the scene's"
            ),
            RegularizeError::Frames { frames, w_a } => write!(
                f,
                "{frames} frames must be at least 1 and w_a {w_a} in (0, 1]"
            ),
            RegularizeError::Fit { spp, at } => write!(
                f,
                "the c_beta fit needs at least 1 spp (got {spp}) and an albedo between source and target (at = {at} must lie in (0, 1])"
            ),
            RegularizeError::NothingToFit => write!(
                f,
                "the c_beta fit: source and target albedo are equal (factor 1), nothing to fit"
            ),
            RegularizeError::Predictor(e) => write!(f, "{e}"),
            RegularizeError::Denoise(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for RegularizeError {}

impl From<SceneError> for RegularizeError {
    fn from(e: SceneError) -> Self {
        RegularizeError::Predictor(e)
    }
}

/// Runs the method on `scene` through `shot`, whose camera is the target frame. The
/// sequence's frames are changed copies of the shot, and the source albedo an override
/// of the render; the scene is only read.
pub fn regularize(
    scene: &Scene,
    shot: &Shot,
    opts: &Options,
) -> Result<Regularized, RegularizeError> {
    if scene.integrator.kind != IntegratorKind::Volpath {
        return Err(RegularizeError::NotVolpath);
    }
    let m = opts.medium as usize;
    if m >= scene.media.len() {
        return Err(RegularizeError::NoMedium(m));
    }
    if opts.auto_factor.is_some() && opts.method != Method::Difference {
        return Err(RegularizeError::AutoFactorNeedsDifference);
    }
    if let Some(p) = opts.auto_factor {
        if p.chunks < 2 || p.spp == 0 {
            return Err(RegularizeError::PilotTooSmall {
                chunks: p.chunks,
                spp: p.spp,
            });
        }
    }
    if !(opts.factor > 0.0 && opts.factor <= 1.0) {
        return Err(RegularizeError::Factor(opts.factor));
    }
    if opts.frames == 0 || !(opts.w_a > 0.0 && opts.w_a <= 1.0) {
        return Err(RegularizeError::Frames {
            frames: opts.frames,
            w_a: opts.w_a,
        });
    }
    let target_albedo = scene.media[m].albedo;
    let sigma_t = scene.media[m].sigma_t;
    // One plain frame through OIDN: OIDN where it lowers the error (`fallback`); nothing
    // of the sequence's machinery is needed.
    let one_plain_frame = opts.frames == 1
        && opts.oidn == OidnUse::Frames
        && match opts.method {
            Method::Radiance => true,
            Method::Difference => opts.auto_factor.is_none() && opts.factor == 1.0,
            _ => false,
        };
    if one_plain_frame {
        let f = fallback::plain_or_oidn(scene, shot).map_err(RegularizeError::Denoise)?;
        let zeros = Image {
            pixels: vec![[0.0; 3]; f.plain.pixels.len()],
            ..f.plain.clone()
        };
        return Ok(Regularized {
            predicted: f.image,
            source: f.plain,
            raw_gradient: zeros.clone(),
            blended: zeros.clone(),
            gradient: zeros,
            seen_emission: Some(f.seen_emission),
            albedos: Albedos {
                source: target_albedo,
                target: target_albedo,
                sigma_t,
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
        });
    }
    // The first visible point of each pixel: the guides of the spatial filter and of
    // the exact reprojection (noise-free, one ray per pixel).
    let features = spatial::first_hit_features(scene, shot);
    // A pilot that would cost more than its share of the render is not run: plain
    // volpath (factor 1) then, which never loses to itself.
    let affordable = opts
        .auto_factor
        .and_then(|size| pilot::affordable(size, opts.frames, shot.spp));
    let pilot_unaffordable = opts.auto_factor.is_some() && affordable.is_none();
    let pilot = affordable.map(|size| {
        pilot::choose_factor(
            scene,
            shot,
            opts.medium,
            opts.frames,
            opts.w_a,
            opts.spatial.as_ref(),
            &features,
            size.chunks,
            size.spp,
        )
    });
    let factor = match opts.method {
        Method::Radiance => Vec3::ONE,
        _ if pilot_unaffordable => Vec3::ONE,
        _ => pilot
            .as_ref()
            .map_or(Vec3::splat(opts.factor), |p| Vec3::from(p.factor)),
    };
    let albedos = Albedos {
        source: target_albedo * factor,
        target: target_albedo,
        sigma_t,
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

    let camera0 = shot.camera.clone();
    let seed0 = shot.seed;
    let frames = opts.path.frames(camera0.to_world, opts.frames);
    let n = frames.len();
    let fit_steps = matches!(opts.method, Method::Paper(CBeta::Fit { .. })) as u64;
    let bar = if opts.show_progress {
        let b = ProgressBar::new(n as u64 + fit_steps);
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
        Method::Difference => Gradient::Difference {
            medium: opts.medium,
            target: albedos.target,
        },
        Method::Radiance => Gradient::None,
        _ => Gradient::Albedo(opts.medium),
    };
    // At factor 1 the difference is 0: the frames are plain renders (`render`'s image,
    // bit for bit), which is how the method falls back to plain volpath.
    let plain = opts.method == Method::Radiance
        || (opts.method == Method::Difference && albedos.source == albedos.target);
    let gradient = if plain { Gradient::None } else { gradient };
    let oidn = opts.oidn != OidnUse::None;
    let render_frame = |to_world, seed, albedo: Vec3, spp: Option<u32>, seen_emission| {
        let mut frame = shot.with(spp.unwrap_or(shot.spp), seed);
        frame.camera.to_world = to_world;
        let options = RenderOptions {
            gradient,
            seen_emission,
            ..Default::default()
        }
        .with_albedo(scene, opts.medium, albedo);
        render(scene, &frame, &options)
    };

    // Step 2: the sequence, earliest frame first.
    let mut timings = Timings {
        pilot: pilot.as_ref().map_or(0.0, |p| p.seconds),
        ..Default::default()
    };
    let mut gradients: Vec<Image> = Vec::with_capacity(n);
    let mut source = None;
    let mut seen_emission = None;
    let mut invalid_samples = 0;
    for k in (0..n).rev() {
        bar.set_message(format!("frame k = {k}"));
        let r = render_frame(
            frames[k],
            seed0.wrapping_add(k as u64),
            albedos.source,
            None,
            oidn && (k == 0 || opts.oidn == OidnUse::Frames),
        );
        timings.frames += r.stats.seconds;
        invalid_samples += r.stats.invalid_samples;
        let mut frame_gradient = match (opts.method, &r.gradient) {
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
            let mut frame_shot = shot.clone();
            frame_shot.camera.to_world = frames[k];
            aovs::sharpen_seen_emission(scene, &frame_shot, seen);
        }
        let mut frame_source = r.image;
        if opts.oidn == OidnUse::Frames {
            let failed = RegularizeError::Denoise;
            match opts.method {
                Method::Radiance => {
                    frame_gradient =
                        denoise::oidn(&frame_gradient, seen.as_ref(), None, AuxUse::None)
                            .map_err(failed)?;
                }
                _ => {
                    frame_gradient = denoise::oidn_signed(&frame_gradient, None, AuxUse::None)
                        .map_err(failed)?;
                    // The difference predictor adds R_s as it is: the target frame's
                    // through the same denoiser (D1).
                    if k == 0 && opts.method == Method::Difference {
                        frame_source =
                            denoise::oidn(&frame_source, seen.as_ref(), None, AuxUse::None)
                                .map_err(failed)?;
                    }
                }
            }
        }
        let spent = start.elapsed().as_secs_f64();
        timings.frames += spent;
        if k == 0 {
            timings.target_frame = r.stats.seconds;
            timings.frame_denoise = spent;
            source = Some(frame_source);
            seen_emission = seen;
        }
        gradients.push(frame_gradient);
        bar.inc(1);
    }
    gradients.reverse();
    let source = source.expect("frame 0 is rendered");

    // Step 3: reproject, blend, filter — all in the target frame.
    let start = Instant::now();
    let (w, h) = (source.width, source.height);
    let maps: Vec<Reprojection> = (1..n)
        .map(|k| {
            let mut cam = camera0.clone();
            cam.to_world = frames[k];
            match opts.reproject {
                Reproject::None => temporal::screen_shift(w, h, 0.0, 0.0),
                Reproject::Exact => reproject::exact(scene, shot, &features, &cam),
                Reproject::Shift => {
                    let point = motion_point(&opts.path, &features, w, h);
                    match reproject::screen_motion(&camera0, &cam, point) {
                        Some((dx, dy)) => temporal::screen_shift(w, h, dx, dy),
                        None => vec![None; w * h],
                    }
                }
            }
        })
        .collect();
    let mean_frames = 1.0
        + maps
            .iter()
            .map(|m| m.iter().filter(|p| p.is_some()).count() as f64)
            .sum::<f64>()
            / (w * h) as f64;
    let frame_refs: Vec<&[[f32; 3]]> = gradients.iter().map(|g| g.pixels.as_slice()).collect();
    let blended = temporal::blend(&frame_refs, &maps, w, h, opts.w_a);
    let mut denoised = blended.clone();
    if let Some(params) = &opts.spatial {
        denoised = spatial::denoise(&denoised, &source.pixels, &features, w, params);
    }
    let as_image = |pixels| Image {
        width: w,
        height: h,
        pixels,
    };
    match (opts.oidn, opts.method) {
        (OidnUse::None | OidnUse::Frames, _) => {}
        // The control's blended radiance is an image like any render's.
        (OidnUse::Difference | OidnUse::Prediction, Method::Radiance) => {
            denoised = denoise::oidn(
                &as_image(denoised),
                seen_emission.as_ref(),
                None,
                AuxUse::None,
            )
            .map_err(RegularizeError::Denoise)?
            .pixels;
        }
        (OidnUse::Difference, _) => {
            denoised = denoise::oidn_signed(&as_image(denoised), None, AuxUse::None)
                .map_err(RegularizeError::Denoise)?
                .pixels;
        }
        (OidnUse::Prediction, _) => {}
    }
    timings.denoise_and_predict = start.elapsed().as_secs_f64();

    // Step 4: c_β, then the prediction.
    let predictor = match (predictor, opts.method) {
        (Some(p), _) => p,
        (None, Method::Paper(CBeta::Fit { spp, at })) => {
            bar.set_message("fitting c_beta");
            let fit_albedo = albedos.source + (albedos.target - albedos.source) * at;
            // A seed no frame of the sequence uses.
            let cheap = render_frame(
                camera0.to_world,
                seed0.wrapping_add(n as u64 + 1_000_003),
                fit_albedo,
                Some(spp),
                false,
            );
            invalid_samples += cheap.stats.invalid_samples;
            let start = Instant::now();
            let fit = Albedos {
                target: fit_albedo,
                ..albedos
            };
            let c_beta = fit_c_beta(&fit, &source.pixels, &denoised, &cheap.image.pixels);
            timings.fit = cheap.stats.seconds + start.elapsed().as_secs_f64();
            bar.inc(1);
            Predictor::Paper { c_beta }
        }
        (None, _) => unreachable!("only a fitted c_beta leaves the predictor open"),
    };
    let start = Instant::now();
    let (mut predicted, fallbacks) = match opts.method {
        Method::Radiance => (denoised.clone(), 0),
        _ => predictor.predict(&albedos, &source.pixels, &denoised),
    };
    if opts.oidn == OidnUse::Prediction && opts.method != Method::Radiance {
        predicted = denoise::oidn(
            &as_image(predicted),
            seen_emission.as_ref(),
            None,
            AuxUse::None,
        )
        .map_err(RegularizeError::Denoise)?
        .pixels;
    }
    timings.denoise_and_predict += start.elapsed().as_secs_f64();
    bar.finish_and_clear();

    let image = as_image;
    let c_beta = match predictor {
        Predictor::Paper { c_beta } => Some(c_beta),
        _ => None,
    };
    Ok(Regularized {
        predicted: image(predicted),
        raw_gradient: gradients.swap_remove(0),
        blended: image(blended),
        gradient: image(denoised),
        seen_emission,
        source,
        albedos,
        c_beta,
        fallbacks,
        mean_frames,
        frames_rendered: n,
        timings,
        invalid_samples,
        pilot,
        pilot_unaffordable,
        oidn_check: None,
    })
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
