//! The paper's method (Wu et al. 2024, "Efficient participating media rendering with
//! differentiable regularization"): render at a lower source albedo α_s, estimate
//! d(radiance)/d(albedo) in the same paths (`integrator::volpath`, `Estimand::AlbedoDerivative`),
//! denoise the gradient, and predict the image at the target albedo α_t.
//!
//! `pipeline` runs the whole method (`options`: what it is asked, and the options it
//! refuses); the steps are `sequence` (camera paths), `reproject` and `temporal`
//! (Eq. 9–10), `spatial` (a still-image denoiser), `predict` (Eq. 11–12), `fit` (c_β
//! without a reference), `pilot` (the source factor without a reference, for the
//! difference predictor), `fallback` (one plain frame, through OIDN where that lowers
//! the error), `pick` (which pipeline a sequence's frame comes from) and `choices` (the options from a caller's choices, shared by the CLI and
//! the Python module).

pub mod choices;
pub mod fallback;
pub mod fit;
pub mod options;
pub mod pick;
pub mod pilot;
pub mod pipeline;
pub mod predict;
pub mod reproject;
pub mod sequence;
pub mod spatial;
pub mod temporal;

pub use choices::{ChoiceError, Choices, Factor, Motion};
pub use pipeline::{
    regularize, CBeta, Method, OidnUse, Options, RegularizeError, Regularized, Reproject,
};
