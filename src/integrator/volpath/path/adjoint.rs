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
//! The in-scattering's term where σ_t < ρ comes from ghosts (`medium::differential`):
//! the replay forks them at tentative collisions there, with draws from a stream of the
//! sample's own (`AdjointPath::first_pass`), traces each to its end at once, and scatters
//! A · G ∂σ_s for its radiance G; the rendered path never sees them.

use glam::{Vec3, Vec3A};

use super::{Flight, PathState};
use crate::integrator::volpath::run;
use crate::integrator::volpath::{
    AdjointDefect, AdjointParams, Estimand, PathSettings, ShadowDerivative,
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
#[derive(Debug)]
pub struct AdjointPath {
    pub grads: GridGradients,
    /// ∂L/∂(the sample's radiance), per channel.
    weight: Vec3,
    replay: bool,
    /// The radiance the path gathers, from the first pass.
    total: Vec3,
    /// The current shadow ray's terms (`ShadowDerivative::record`), reused.
    shadow: Vec<(Vec3A, f32)>,
    /// The ghosts' stream (their forks' draws and paths), the sample's own.
    ghost_rng: Pcg32,
    /// The ghosts forked along the current flight (traced once it ends), reused.
    forks: Vec<Fork>,
}

/// A ghost forked at a tentative collision: where, σ_t there, its weight's rate, and
/// (once traced) its radiance.
#[derive(Clone, Copy, Debug)]
struct Fork {
    t: f32,
    p: Vec3A,
    sigma_t: f32,
    rate: f32,
    radiance: Vec3,
}

impl AdjointPath {
    pub fn new(grads: GridGradients) -> AdjointPath {
        AdjointPath {
            grads,
            weight: Vec3::ZERO,
            replay: false,
            total: Vec3::ZERO,
            shadow: Vec::new(),
            ghost_rng: Pcg32::new(0, 0),
            forks: Vec::new(),
        }
    }

    /// Starts a sample's first pass, `weight` its adjoint, `ghosts` its ghosts' stream.
    pub fn first_pass(&mut self, weight: Vec3, ghosts: Pcg32) {
        self.weight = weight;
        self.replay = false;
        self.ghost_rng = ghosts;
    }

    /// Starts the second pass of the sample whose first pass gathered `radiance`.
    pub fn second_pass(&mut self, radiance: Vec3) {
        self.total = radiance;
        self.replay = true;
    }

    /// A · (L − `gathered`): the adjoint of what the path gathers from here on, where
    /// this pass scatters (the replay).
    #[inline]
    fn after(&self, gathered: Vec3) -> Option<Vec3> {
        self.replay.then(|| self.weight * (self.total - gathered))
    }
}

/// What a shadow ray from the path is differentiated in: forward mode's extinction, or
/// this path's voxels, recorded where the pass scatters.
pub(in crate::integrator::volpath) fn shadow_derivative<'r>(
    settings: &PathSettings,
    adjoint: &'r mut Option<&mut AdjointPath>,
) -> ShadowDerivative<'r> {
    let params = match settings.estimand {
        Estimand::Adjoint(a) if a.sigma_t && a.defect != Some(AdjointDefect::Transmittance) => {
            Some(a)
        }
        _ => None,
    };
    let record = match (params, adjoint.as_deref_mut()) {
        (Some(_), Some(a)) if a.replay => {
            a.shadow.clear();
            Some(&mut a.shadow)
        }
        _ => None,
    };
    ShadowDerivative {
        extinction: settings.estimand.extinction_medium(),
        adjoint: match settings.estimand {
            Estimand::Adjoint(a) => Some(a),
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
        let (Estimand::Adjoint(a), Some(adj)) = (settings.estimand, self.adjoint.as_deref_mut())
        else {
            return;
        };
        if !(adj.replay && a.sigma_t) || adj.shadow.is_empty() {
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
    /// collisions' derivatives scattered where this pass does (1), then its ghosts.
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
        let mut adj = self.adjoint.as_deref_mut().filter(|adj| adj.replay);
        if let Some(adj) = adj.as_deref_mut() {
            adj.forks.clear();
        }
        let scale = het.scale;
        let null_terms = a.sigma_t && a.defect != Some(AdjointDefect::Transmittance);
        let ghosts = a.defect != Some(AdjointDefect::Ghosts);
        let (o, d) = (self.ray_o, self.ray_d);
        let real = a.tracking.delta_tracking(het, o, d, end, rng, |c, real| {
            let (Some(after), Some(adj)) = (after, adj.as_deref_mut()) else {
                return;
            };
            if !real && null_terms {
                let k = -scale / (c.majorant - c.sigma_t);
                het.sigma_t.scatter(c.p, after * k, &mut adj.grads.sigma_t);
            }
            let u = adj.ghost_rng.next_1d();
            if let Some(rate) = a.tracking.ghost_forks(&c, u).filter(|_| ghosts) {
                adj.forks.push(Fork {
                    t: c.t,
                    p: c.p,
                    sigma_t: c.sigma_t,
                    rate,
                    radiance: Vec3::ZERO,
                });
            }
        });
        let mut flight = Flight::through_vacuum();
        match real {
            None => {
                flight.si = hit;
                flight.t = end;
            }
            Some(c) => {
                flight.scattered = true;
                flight.t = c.t;
            }
        }
        if let Some(after) = after {
            self.trace_ghosts(scene, settings, a, het);
            if let Some(c) = real.filter(|c| c.sigma_t >= a.tracking.min_real) {
                self.real_terms(a, het, c.p, c.sigma_t, after);
            }
        }
        if let Some(c) = real {
            self.beta *= settings.albedo[mi as usize] * het.albedo.eval(c.p);
        }
        flight
    }

    /// The terms (2) of a real collision at `p` (σ_t ≥ ρ there), `after` the adjoint of
    /// what the path gathers beyond it.
    fn real_terms(
        &mut self,
        a: AdjointParams,
        het: &HeterogeneousMedium,
        p: Vec3A,
        sigma_t: f32,
        after: Vec3,
    ) {
        let Some(adj) = self.adjoint.as_deref_mut() else {
            return;
        };
        if a.defect == Some(AdjointDefect::Scattering) {
            return;
        }
        if a.sigma_t {
            het.sigma_t
                .scatter(p, after * (het.scale / sigma_t), &mut adj.grads.sigma_t);
        }
        if a.albedo {
            // ∂ ln α / ∂ value: 1 / (the volume's value); nothing where it is 0 (that
            // channel carries nothing on).
            let v = het.albedo.eval(p);
            let inv = Vec3::select(v.cmpgt(Vec3::ZERO), v.recip(), Vec3::ZERO);
            het.albedo.scatter(p, after * inv, &mut adj.grads.albedo);
        }
    }

    /// Traces the ghosts forked along the flight just made (from this path's state at
    /// its start) and scatters A · G ∂σ_s of each: ∂σ_s = α scale w for sigma_t's
    /// values, σ_t (factor) w for the albedo's.
    fn trace_ghosts(
        &mut self,
        scene: &Scene,
        settings: &PathSettings,
        a: AdjointParams,
        het: &HeterogeneousMedium,
    ) {
        let Some(adj) = self.adjoint.as_deref_mut() else {
            return;
        };
        if adj.forks.is_empty() {
            return;
        }
        let mut forks = std::mem::take(&mut adj.forks);
        let mut ghost_rng = adj.ghost_rng.clone();
        for f in forks.iter_mut() {
            let mut ghost = self.ghost(self.beta / f.rate);
            let mut flight = Flight::through_vacuum();
            flight.scattered = true;
            flight.t = f.t;
            if ghost.scatter_in_medium(scene, settings, &flight, &mut ghost_rng) {
                run(&mut ghost, scene, settings, &mut ghost_rng);
            }
            f.radiance = ghost.result;
        }
        let adj = self.adjoint.as_deref_mut().expect("checked above");
        adj.ghost_rng = ghost_rng;
        let factor = settings.albedo[a.medium as usize];
        for f in &forks {
            let ag = adj.weight * f.radiance;
            if a.sigma_t {
                let alpha = factor * het.albedo.eval(f.p);
                het.sigma_t
                    .scatter(f.p, ag * alpha * het.scale, &mut adj.grads.sigma_t);
            }
            if a.albedo {
                het.albedo
                    .scatter(f.p, ag * factor * f.sigma_t, &mut adj.grads.albedo);
            }
        }
        forks.clear();
        adj.forks = forks;
    }
}
