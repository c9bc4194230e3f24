//! What `pipeline::regularize` is asked: the `Options` and the choices they name (the
//! reprojection, the predictor and its c_β, where OIDN filters), and the checks that
//! refuse options before anything is rendered (`RegularizeError`, `validate`).

use super::pilot::PilotSize;
use super::sequence::CameraPath;
use super::spatial::BilateralParams;
use crate::denoise::OidnError;
use crate::error::SceneError;
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
    /// Pick the target frame's pipeline (the method, its control, the guarded control,
    /// plain + OIDN, plain) by `pick`'s check; with the difference predictor, OIDN on
    /// every frame and more than one frame only (else ignored).
    pub pick: bool,
    /// One plain frame through OIDN (`frames` 1): keep plain volpath where `fallback`'s
    /// check finds that OIDN raises the error. Off, the frame is `render --denoise
    /// oidn`'s image and costs what it costs; on, the check costs one more OIDN run.
    pub oidn_check: bool,
    pub show_progress: bool,
}

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
            pick: false,
            oidn_check: false,
            show_progress: false,
        }
    }
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

/// The options' checks that need no render: the integrator, the medium, the pilot's
/// size, the factor, the frames and their blend weight.
pub(super) fn validate(scene: &Scene, opts: &Options) -> Result<(), RegularizeError> {
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
    Ok(())
}
