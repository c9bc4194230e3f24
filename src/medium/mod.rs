//! Participating media: Mitsuba 3's `homogeneous` medium with `hg` or `isotropic` phase.
//! Parsed and validated now; rendered by `volpath` (next milestone).

use glam::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub enum Phase {
    Isotropic,
    /// Henyey–Greenstein with asymmetry `g` ∈ (−1, 1) (Mitsuba's sign convention:
    /// g > 0 scatters forward).
    HenyeyGreenstein {
        g: f32,
    },
}

#[derive(Clone, Debug)]
pub struct HomogeneousMedium {
    /// Single-scattering albedo σ_s / σ_t, per channel, in [0, 1].
    pub albedo: Vec3,
    /// Extinction σ_t (already multiplied by `scale`), per channel, ≥ 0.
    pub sigma_t: Vec3,
    pub phase: Phase,
    pub sample_emitters: bool,
}
