//! Which derivative a render estimates beside the radiance, chosen from what a caller
//! asked for (the CLI's `--gradient albedo --medium ID`, the Python module's
//! `gradient="albedo", medium=ID`): one check, worded by each caller for its flags.

use super::volpath::Gradient;
use crate::scene::{IntegratorKind, MediumChoiceError, Scene};

/// Why the albedo derivative cannot be rendered for a scene.
#[derive(Clone, Debug)]
pub enum GradientError {
    /// The scene's integrator ignores media (only volpath estimates the derivative).
    NeedsVolpath,
    /// The medium asked for is not there, or several are and none was named.
    Medium(MediumChoiceError),
}

impl std::fmt::Display for GradientError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            GradientError::NeedsVolpath => write!(
                f,
                "the albedo gradient needs the volpath integrator (the scene's integrator ignores media)"
            ),
            GradientError::Medium(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for GradientError {}

/// d(radiance)/d(albedo) of the medium with XML id `medium` (or the scene's only one).
pub fn albedo_gradient(scene: &Scene, medium: Option<&str>) -> Result<Gradient, GradientError> {
    if scene.integrator.kind != IntegratorKind::Volpath {
        return Err(GradientError::NeedsVolpath);
    }
    scene
        .medium_index(medium)
        .map(Gradient::Albedo)
        .map_err(GradientError::Medium)
}
