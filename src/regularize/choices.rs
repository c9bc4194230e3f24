//! The method's options from what a caller chose (the CLI's `regularize` flags, the
//! Python module's `regularize` keywords): the defaults that depend on other choices
//! (the factor, the spatial filter), the medium by id, the camera path with its orbit
//! centre. One place, so both callers run the method with the same options.

use glam::Vec3;

use super::pipeline::{CBeta, Method, OidnUse, Options, PilotSize, Reproject};
use super::sequence::{image_centre_point, CameraPath};
use super::spatial::BilateralParams;
use crate::scene::shot::Shot;
use crate::scene::{MediumChoiceError, Scene};

/// The source factor: a number, or chosen by the pilot (the difference predictor).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Factor {
    Auto,
    Fixed(f32),
}

/// How the camera moves over the frames.
#[derive(Clone, Debug, PartialEq)]
pub enum Motion {
    Static,
    /// Degrees per frame about `target` (None: the first visible point at the image
    /// centre).
    Orbit {
        degrees: f32,
        target: Option<Vec3>,
    },
    Dolly(f32),
    /// Sensor transforms in time order, the last the target frame (a camera-path file).
    Path(CameraPath),
}

/// What a caller chose; `Default` is the CLI's defaults.
#[derive(Clone, Debug)]
pub struct Choices {
    /// The medium's XML id (None: the scene's only one).
    pub medium: Option<String>,
    pub method: Method,
    /// None: `Auto` with the difference predictor, 0.95 with the others.
    pub factor: Option<Factor>,
    pub pilot: PilotSize,
    pub frames: usize,
    pub w_a: f64,
    pub reproject: Reproject,
    pub motion: Motion,
    /// None: on with the difference predictor, off with the others.
    pub spatial: Option<bool>,
    /// Filter with Open Image Denoise (`OidnUse::Frames`) instead of the bilateral
    /// filter. None: with the difference predictor when the library loads.
    pub oidn: Option<bool>,
    /// Pick the frame's pipeline by `pick`'s check (where it applies: the difference
    /// predictor through OIDN, more than one frame).
    pub pick: bool,
    /// With one frame through OIDN: check whether OIDN lowers the error, and keep plain
    /// volpath where it does not (`Options::oidn_check`).
    pub oidn_check: bool,
    pub show_progress: bool,
}

impl Default for Choices {
    fn default() -> Self {
        Choices {
            medium: None,
            method: Method::Difference,
            factor: None,
            pilot: PilotSize::default(),
            frames: 11,
            w_a: 0.1,
            reproject: Reproject::Exact,
            motion: Motion::Static,
            spatial: None,
            oidn: None,
            pick: true,
            oidn_check: false,
            show_progress: false,
        }
    }
}

/// The difference predictor's source factor when OIDN filters and none is given: the
/// factor measured best with every frame denoised (docs/regularize.md); the pilot's
/// model is of the bilateral filter, not of OIDN.
pub const DEFAULT_FACTOR: f32 = 0.2;

/// A choice that cannot be made for the scene.
#[derive(Clone, Debug)]
pub enum ChoiceError {
    Medium(MediumChoiceError),
    /// An orbit without a centre, and the image centre sees no surface.
    NoOrbitCentre,
}

impl std::fmt::Display for ChoiceError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ChoiceError::Medium(e) => write!(f, "{e}"),
            ChoiceError::NoOrbitCentre => write!(f, "the image centre sees no surface"),
        }
    }
}

impl std::error::Error for ChoiceError {}

/// The method's options for `scene` through `shot`, and the target frame's shot (a
/// camera path's last transform, else `shot`).
pub fn options(scene: &Scene, shot: &Shot, c: &Choices) -> Result<(Options, Shot), ChoiceError> {
    let medium = scene
        .medium_index(c.medium.as_deref())
        .map_err(ChoiceError::Medium)?;
    let mut target_shot = shot.clone();
    let path = match &c.motion {
        Motion::Static => CameraPath::Static,
        Motion::Orbit { degrees, target } => CameraPath::Orbit {
            degrees_per_frame: *degrees,
            target: match target {
                Some(t) => *t,
                None => image_centre_point(scene, shot).ok_or(ChoiceError::NoOrbitCentre)?,
            },
        },
        Motion::Dolly(d) => CameraPath::Dolly {
            distance_per_frame: *d,
        },
        Motion::Path(p) => {
            if let CameraPath::Transforms(list) = p {
                if let Some(last) = list.last() {
                    target_shot.camera.to_world = *last;
                }
            }
            p.clone()
        }
    };
    let difference = c.method == Method::Difference;
    // The predictors whose filtered image is radiance-like (a difference, radiance).
    let filtered = difference || c.method == Method::Radiance;
    let oidn = c
        .oidn
        .unwrap_or_else(|| filtered && crate::denoise::oidn::load().is_ok());
    // `auto` leaves the factor to the pilot; 0.95 is then a placeholder it replaces.
    let (factor, auto_factor) = match c.factor {
        Some(Factor::Auto) => (0.95, Some(c.pilot)),
        Some(Factor::Fixed(f)) => (f, None),
        // One frame through OIDN: R_s + D is plain volpath's estimate on every path, and
        // OIDN on the two parts measured no better than on their sum, so the default is
        // the plain render through OIDN (`render --denoise oidn`, bit for bit).
        None if difference && oidn && c.frames == 1 => (1.0, None),
        None if difference && oidn => (DEFAULT_FACTOR, None),
        None => (0.95, difference.then_some(c.pilot)),
    };
    let options = Options {
        medium,
        factor,
        frames: c.frames,
        w_a: c.w_a,
        path,
        reproject: c.reproject,
        spatial: c
            .spatial
            .unwrap_or(filtered && !oidn)
            .then(BilateralParams::default),
        oidn: match oidn {
            true => OidnUse::Frames,
            false => OidnUse::None,
        },
        auto_factor,
        method: c.method,
        pick: c.pick && difference && oidn && c.frames > 1,
        oidn_check: c.oidn_check,
        show_progress: c.show_progress,
    };
    Ok((options, target_shot))
}

/// c_β as a caller spells it: a number, or `fit` (fitted to a cheap render).
pub fn parse_c_beta(text: &str, fit_spp: u32, fit_at: f32) -> Option<CBeta> {
    if text == "fit" {
        return Some(CBeta::Fit {
            spp: fit_spp,
            at: fit_at,
        });
    }
    text.parse::<f32>()
        .ok()
        .filter(|c| c.is_finite())
        .map(CBeta::Fixed)
}

/// The source factor as a caller spells it: a number, or `auto` (chosen by the pilot).
pub fn parse_factor(text: &str) -> Option<Factor> {
    if text == "auto" {
        return Some(Factor::Auto);
    }
    text.parse::<f32>()
        .ok()
        .filter(|f| f.is_finite())
        .map(Factor::Fixed)
}
