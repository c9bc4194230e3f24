//! Reverse mode in a grid medium's voxels by path replay backpropagation (Vicini,
//! Speierer and Jakob 2021): a path's contribution to L = Σ A · I is a sum of terms C_j
//! (each emitter hit or emitter sample, weighted by the adjoint A of its pixel), each a
//! product of factors f_i met before it, so
//!
//!   ∂L/∂θ = Σ_j C_j Σ_{i ≤ j} ∂ ln f_i / ∂θ = Σ_i ∂ ln f_i / ∂θ · (Σ_{j ≥ i} C_j).      (1)
//!
//! The first pass gathers the path's total A · L; the second replays it from the same
//! random stream, and at each factor f_i scatters ∂ ln f_i / ∂θ times A · (L − what was
//! gathered before f_i) into the voxels: no memory per vertex. The factors that depend
//! on the voxels are the tracking weights of `medium::differential` (its (2)): a null
//! collision's −∂σ_t/σ_n and a real collision's ∂σ_t/σ_t + ∂α/α along flights, and the
//! null factors of ratio tracking along shadow rays, whose terms are recorded as the
//! ray is tracked and scattered with its own contribution once that is known.
//!
//! A real collision where σ_t = 0 has weight 0 but derivative α ∂σ_t / rate: the path
//! goes on as a ghost with weight β α / rate (what it would carry per unit of σ_t), its
//! later contributions G are gathered apart, and the collision scatters A · G · scale.
//! The ghost carries no other derivative (they would be of second order), and a second
//! such collision ends it.

use glam::{Vec3, Vec3A};

use super::{Flight, PathState};
use crate::integrator::volpath::{
    AdjointDefect, AdjointParams, Gradient, PathSettings, ShadowDerivative,
};
use crate::medium::heterogeneous::HeterogeneousMedium;
use crate::sampling::Pcg32;
use crate::scene::Scene;

/// The gradient buffers of one thread: ∂L/∂value for each stored value of the medium's
/// sigma_t and albedo grids (laid out as their data; empty where not asked for).
#[derive(Clone, Debug, Default)]
pub struct GridGradients {
    pub sigma_t: Vec<f32>,
    pub albedo: Vec<f32>,
}

/// Reverse mode's state of one thread's paths: the buffers, and the path under way.
#[derive(Debug, Default)]
pub struct AdjointPath {
    pub grads: GridGradients,
    /// ∂L/∂(the sample's radiance), per channel.
    weight: Vec3,
    replay: bool,
    /// The radiance the path gathers before it becomes a ghost (all of it if it never
    /// does), from the first pass.
    total: Vec3,
    /// What the ghost gathers, from the first pass.
    ghost_total: Vec3,
    /// What the path had gathered when it became a ghost (this pass).
    ghost_at: Option<Vec3>,
    /// The current shadow ray's terms (`ShadowDerivative::record`), reused.
    shadow: Vec<(Vec3A, f32)>,
}

impl AdjointPath {
    pub fn new(grads: GridGradients) -> AdjointPath {
        AdjointPath {
            grads,
            ..AdjointPath::default()
        }
    }

    /// Starts a sample's first pass, `weight` its adjoint.
    pub fn first_pass(&mut self, weight: Vec3) {
        self.weight = weight;
        self.replay = false;
        self.ghost_at = None;
    }

    /// Starts the second pass of the sample whose first pass gathered `radiance`.
    pub fn second_pass(&mut self, radiance: Vec3) {
        let at = self.ghost_at.take().unwrap_or(radiance);
        self.total = at;
        self.ghost_total = radiance - at;
        self.replay = true;
    }

    /// A · (L − `gathered`): the adjoint of what the path gathers from here on, where
    /// this pass scatters (the replay, before any ghost).
    #[inline]
    fn after(&self, gathered: Vec3) -> Option<Vec3> {
        (self.replay && self.ghost_at.is_none()).then(|| self.weight * (self.total - gathered))
    }
}

/// What a shadow ray from the path is differentiated in: forward mode's extinction, or
/// this path's voxels, recorded where the pass scatters.
pub(in crate::integrator::volpath) fn shadow_derivative<'r>(
    settings: &PathSettings,
    adjoint: &'r mut Option<&mut AdjointPath>,
) -> ShadowDerivative<'r> {
    let params = match settings.gradient {
        Gradient::Adjoint(a) if a.sigma_t && a.defect != Some(AdjointDefect::Transmittance) => {
            Some(a)
        }
        _ => None,
    };
    let record = match (params, adjoint.as_deref_mut()) {
        (Some(_), Some(a)) if a.replay && a.ghost_at.is_none() => {
            a.shadow.clear();
            Some(&mut a.shadow)
        }
        _ => None,
    };
    ShadowDerivative {
        extinction: settings.gradient.extinction_medium(),
        adjoint: match settings.gradient {
            Gradient::Adjoint(a) => Some(a),
            _ => None,
        },
        record,
    }
}

impl PathState<'_> {
    /// The shadow ray just recorded brought `contribution` (radiance): its ratio
    /// tracking's terms scatter A · contribution each (1).
    pub(super) fn scatter_shadow(
        &mut self,
        scene: &Scene,
        settings: &PathSettings,
        contribution: Vec3,
    ) {
        let (Gradient::Adjoint(a), Some(adj)) = (settings.gradient, self.adjoint.as_deref_mut())
        else {
            return;
        };
        if !(adj.replay && adj.ghost_at.is_none() && a.sigma_t) || adj.shadow.is_empty() {
            return;
        }
        let Some(het) = scene.media[a.medium as usize].heterogeneous.as_deref() else {
            return;
        };
        let c = adj.weight * contribution;
        for &(p, k) in &adj.shadow {
            het.sigma_t.scatter(p, c * k, &mut adj.grads.sigma_t);
        }
        adj.shadow.clear();
    }

    /// A free flight through the medium whose voxels are differentiated: the surface
    /// that ends the ray, then differential delta tracking up to it, its null and real
    /// collisions' derivatives scattered where this pass does (1).
    #[inline(always)]
    pub(super) fn differential_tracking(
        &mut self,
        scene: &Scene,
        settings: &PathSettings,
        a: AdjointParams,
        het: &HeterogeneousMedium,
        rng: &mut Pcg32,
    ) -> Flight {
        let mi = a.medium;
        let hit = scene.intersect_in_medium(mi, self.ray_o, self.ray_d, self.ray_tmax);
        let end = hit.as_ref().map_or(self.ray_tmax, |h| h.t);
        let after = self
            .adjoint
            .as_deref()
            .and_then(|adj| adj.after(self.result));
        let mut grads = self.adjoint.as_deref_mut().map(|adj| &mut adj.grads);
        let scale = het.scale;
        let null_terms = a.sigma_t && a.defect != Some(AdjointDefect::Transmittance);
        let real_terms = a.defect != Some(AdjointDefect::Scattering);
        let (real, w) =
            a.tracking
                .sample_flight(het, self.ray_o, self.ray_d, end, rng, |p, sigma_n| {
                    if let (Some(after), Some(g), true) = (after, grads.as_deref_mut(), null_terms) {
                        het.sigma_t
                            .scatter(p, after * (-scale / sigma_n), &mut g.sigma_t);
                    }
                });
        self.beta *= w;
        let mut flight = Flight::through_vacuum();
        let Some(c) = real else {
            flight.si = hit;
            flight.t = end;
            return flight;
        };
        flight.scattered = true;
        flight.t = c.t;
        let alpha = settings.albedo[mi as usize] * c.albedo;
        if c.sigma_t > 0.0 {
            if let (Some(after), Some(g), true) = (after, grads, real_terms) {
                if a.sigma_t {
                    het.sigma_t
                        .scatter(c.p, after * (scale / c.sigma_t), &mut g.sigma_t);
                }
                if a.albedo {
                    // ∂ ln α / ∂ value: 1 / (the volume's value); nothing where it is 0
                    // (that channel carries nothing on).
                    let inv =
                        Vec3::select(c.albedo.cmpgt(Vec3::ZERO), c.albedo.recip(), Vec3::ZERO);
                    het.albedo.scatter(c.p, after * inv, &mut g.albedo);
                }
            }
            self.beta *= alpha * (c.sigma_t / c.rate);
            return flight;
        }
        // σ_t = 0: the path goes on as a ghost carrying ∂σ_s alone.
        match self.adjoint.as_deref_mut() {
            Some(adj) if a.sigma_t && adj.ghost_at.is_none() && a.defect != Some(AdjointDefect::Ghosts) => {
                if adj.replay {
                    let c_ghost = adj.weight * adj.ghost_total * scale;
                    het.sigma_t.scatter(c.p, c_ghost, &mut adj.grads.sigma_t);
                }
                adj.ghost_at = Some(self.result);
                self.beta *= alpha / c.rate;
            }
            _ => self.beta = Vec3::ZERO,
        }
        flight
    }
}
