//! What one camera path returns to the render driver.

use glam::Vec3;

/// One camera path's contributions: its radiance, the derivatives or the difference
/// asked for (0 for none), and the part of the radiance that is emission seen
/// directly: the emitting surface at the camera ray's first intersection, the camera in
/// no medium (the part a denoiser keeps out: `denoise`; `aovs::sharpen_seen_emission`
/// traces the same quantity). The environment is not part of it: a sky is smooth, and
/// the denoiser did better with it left in (docs/denoise.md).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PathSample {
    pub radiance: Vec3,
    /// The albedo's derivative, or the difference asked for (`volpath::Estimand`).
    pub d_albedo: Vec3,
    /// The derivatives in the chosen medium's extinction and phase asymmetry, where
    /// asked for (`volpath::Differentiated`; 0 otherwise).
    pub d_sigma: Vec3,
    pub d_g: Vec3,
    pub seen_emission: Vec3,
    /// Mitsuba's `valid_ray`, the film's alpha: the path met something (a visible
    /// environment, a scattering in a medium, a surface it did not pass through).
    pub valid: bool,
}
