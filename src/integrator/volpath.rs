//! Mitsuba 3's `volpath` integrator (`src/integrators/volpath.cpp`): volumetric path
//! tracing in homogeneous media with emitter sampling at surface and medium vertices,
//! combined with BSDF / phase sampling by the power heuristic. Heterogeneous media take
//! delta tracking for free flights and ratio tracking for shadow segments
//! (`medium::heterogeneous`, docs/volpath.md); what follows is about homogeneous ones.
//!
//! Semantics kept from Mitsuba (what a scene file can change):
//! * depth counts scattering vertices, in media and on non-null surfaces; crossing a
//!   `null` boundary does not count. An emitter hit after `k` vertices counts iff
//!   `k < max_depth`, and emitter sampling at the `k`-th vertex iff `k < max_depth`.
//! * Russian roulette once `depth > rr_depth`: continue with probability
//!   `q = min(max_c(β) · η², 0.95)`.
//! * `hide_emitters`: emitters seen before the first scattering vertex are dropped.
//! * emitter hits are weighted by MIS unless the path since its last vertex that could
//!   sample emitters is a specular chain (`count_direct`).
//!
//! Where the estimator differs from Mitsuba's, the expectation is the same and the
//! variance lower:
//! * Shadow rays use the exact transmittance `Π e^{−σ_t s}` of the homogeneous segments
//!   they cross (through `null` boundaries); Mitsuba estimates it by free-flight
//!   sampling (0 or `T/T[c]`).
//! * Chromatic extinction: Mitsuba samples every distance of a path with σ_t of one
//!   channel `c` picked per path and weights by `T / pdf_c`. Here the channel is picked
//!   the same way (the "hero"), but the estimate is weighted by the path pdf averaged
//!   over channels (one-sample MIS over channels, balance heuristic, as in pbrt-v4):
//!   `f / ((1/3) Σ_c p_c) = β / mean(r)` with `β = f / p_hero`, `r_c = p_c / p_hero`.
//!   For grey σ_t, r = (1,1,1) and this is Mitsuba's estimator exactly.
//! * Shadow rays from medium vertices are cast with probability q, a bound on their
//!   transmittance from the scene's clearance (`geometry::clearance`), and weighted 1/q.
//! * The emitter to sample is picked by an estimate of what each delivers at the vertex
//!   (`emitter::selection`), not uniformly; emitter hits are MIS-weighted with the same
//!   probabilities.
//! * An area emitter at the end of a medium segment is counted in expectation: the
//!   flight passes to it with probability T_hero and then weighs its emission by
//!   β T / mean(r T), so β T (T_hero / mean(r T)) L_e is added for every path, and not
//!   again when the flight does pass (Mitsuba adds L_e or nothing: the variance of a
//!   light seen through fog). Only segments whose ray may reach an area emitter's
//!   bounding sphere within the medium are cast in full for this.
//!
//! Free flights shorter than the clearance of their origin are not cast: no surface can
//! be that close, so the cast's answer is known. In a medium that fills one convex
//! shape with nothing else inside (`geometry::convex`), the clearance is the distance
//! to that shape, and a flight that is cast tests that shape alone.
//!
//! Albedo gradient (the paper, Sec. 4.1, Eq. 6–8). Sampling depends on σ_t only, so a
//! path's pdf does not depend on the albedo α of the chosen medium, and its weight
//! holds α_c once per scattering vertex in that medium: d f_c / d α_c = (k / α_c) f_c.
//! It is computed in forward mode, `dβ` beside `β` (exact at α = 0 too, where k/α is
//! not), with Russian roulette detached: `q` divides both. MIS weights and channel pdfs
//! do not depend on α.

use glam::{Vec3, Vec3A};

use super::emitters::emission_met;
use super::sample::PathSample;
use crate::geometry::SHADOW_EPSILON;
use crate::medium::differential::DifferentialTracking;
use crate::medium::Medium;
use crate::sampling::mis_weight;
use crate::sampling::Pcg32;
use crate::scene::{Scene, ShapeInfo, SurfaceInteraction};
use crate::simd::{Float, Vector3};

/// Consecutive null-boundary crossings (no scattering between them: depth does not
/// grow, and Russian roulette may not run) after which a path ends. Only a degenerate
/// scene gets here (a ray caught between coincident surfaces); without the limit the
/// render would hang.
const MAX_NULL_CROSSINGS: u32 = 1 << 16;

/// The medium on the side of the surface that direction `d` points into
/// (Mitsuba's `target_medium`), or `current` when the surface is no medium boundary.
#[inline]
fn medium_after(info: &ShapeInfo, n: Vec3A, d: Vec3A, current: Option<u32>) -> Option<u32> {
    medium_beyond(info, d.dot(n) > 0.0, current)
}

/// [`medium_after`] by the side crossed: along the geometric normal (`d · n > 0`),
/// out to the exterior.
#[inline]
fn medium_beyond(info: &ShapeInfo, along_normal: bool, current: Option<u32>) -> Option<u32> {
    if info.interior.is_none() && info.exterior.is_none() {
        current
    } else if along_normal {
        info.exterior
    } else {
        info.interior
    }
}

/// An emitter sample from a medium vertex: what it adds (phase · L · T / p_select,
/// MIS-weighted), ∂ ln T / ∂θ of its shadow ray for a differentiated extinction, and
/// its direction (for the phase's own derivative).
struct MediumLight {
    value: Vec3,
    d_log_tr: Vec3,
    d: Vec3A,
}

/// Emitter sampling from the point `p` in `medium`, light leaving it against `d_in`,
/// MIS-weighted (power heuristic) against phase sampling; None when nothing arrives.
/// `clearance` is a distance `p` is known to lie from every surface (0 if none is
/// known), for the shadow ray's roulette; `diff` what its transmittance
/// is differentiated in.
#[inline]
fn medium_emitter_sample(
    scene: &Scene,
    medium: u32,
    p: Vec3A,
    d_in: Vec3A,
    clearance: f32,
    diff: &mut ShadowDerivative,
    rng: &mut Pcg32,
) -> Option<MediumLight> {
    let m: &Medium = &scene.media[medium as usize];
    // (Where no emitter sample can arrive, none is drawn: see Scene::emitters_unreachable.)
    if !m.sample_emitters || scene.emitters_unreachable[medium as usize] {
        return None;
    }
    // None where there is no emitter to pick (none at all, or only a sky left to
    // phase sampling).
    let (idx, u, p_select) = scene.emitter_selection.select(p, rng.next_2d())?;
    let e = &scene.emitters[idx];
    let es = e.sample_direction(p, u, &scene.geometries, &scene.bsphere)?;
    let phase_val = m.phase.eval(d_in.dot(es.d));
    let dist = (es.p - p).length() * (1.0 - SHADOW_EPSILON);
    // Russian roulette on the shadow ray by the bound on what it can carry: it runs at
    // least min(clearance, dist) in this medium, so T ≤ q = e^{−min_c σ_t,c · min(clearance,
    // dist)}. Cast with probability q, weighted 1/q: the estimate stays unbiased and, as
    // T/q ≤ 1, never exceeds the exact one's bound (at most the variance of Mitsuba's
    // 0-or-1 transmittance estimate).
    // (No such bound in a heterogeneous medium: its σ_t may be 0 anywhere.)
    let sigma_min = match m.heterogeneous {
        None => m.sigma_t.min_element(),
        Some(_) => 0.0,
    };
    let q = if sigma_min > 0.0 && clearance > 0.0 {
        (-sigma_min * dist.min(clearance)).exp()
    } else {
        1.0
    };
    let ray = ShadowRay {
        o: p,
        d: es.d,
        dist,
        medium: Some(medium),
    };
    if q < 1.0 && !(q > 0.0 && rng.next_1d() < q) {
        return None;
    }
    let through = shadow_transmittance(scene, ray, diff, rng);
    let mut tr = Vec3::from(through.tr);
    if q < 1.0 {
        tr /= q;
    }
    if tr == Vec3::ZERO {
        return None;
    }
    let w = if es.delta {
        1.0
    } else {
        mis_weight(es.pdf * p_select, phase_val)
    };
    Some(MediumLight {
        value: phase_val * es.weight * tr / p_select * w,
        d_log_tr: through.d_log.into(),
        d: es.d,
    })
}

/// Where the path last scattered (for MIS of emitter hits).
#[derive(Clone, Copy)]
struct LastScatter {
    p: Vec3A,
    /// Solid-angle pdf of the direction sampled there (BSDF or phase function).
    pdf: f32,
}

/// The emission the path sees at the end of its ray (`hit`, or the environment where
/// None) along `ray_d`, MIS-weighted against emitter sampling at the vertex it last
/// scattered at (full weight at depth 0 and after a specular chain); zero where
/// nothing emits or emitters are hidden.
#[inline]
fn emission_seen(
    scene: &Scene,
    hit: Option<&SurfaceInteraction>,
    ray_d: Vec3A,
    depth: u32,
    specular_chain: bool,
    last: &LastScatter,
) -> Vec3 {
    let emitter = match hit {
        Some(h) => scene.shapes[h.shape as usize].emitter,
        None => scene.environment,
    };
    let Some(ei) = emitter else {
        return Vec3::ZERO;
    };
    if depth == 0 && scene.integrator.hide_emitters {
        return Vec3::ZERO;
    }
    let (p_end, n_end) = hit.map_or((last.p, Vec3A::ZERO), |h| (h.p, h.sh_frame.n));
    let full = depth == 0 || specular_chain;
    emission_met(scene, ei, (p_end, n_end, ray_d), (last.p, last.pdf), full)
}

/// What a render estimates beside the radiance: a derivative, a difference, or nothing.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Estimand {
    #[default]
    RadianceOnly,
    /// d(radiance_c)/d(albedo_c) of this medium.
    AlbedoDerivative(u32),
    /// A deliberately wrong variant for the power tests: NEE contributions do not count
    /// the vertex they are made from (k − 1 instead of k).
    #[doc(hidden)]
    AlbedoDerivativeIgnoringNeeVertex(u32),
    /// R(α_t) − R(α) of this medium, α the albedo rendered with and α_t `target`, in the
    /// same paths: each path's contribution f carries α^k for its k scattering vertices
    /// in the medium and its sampling does not depend on α, so f · ((α_t / α)^k − 1) is
    /// an unbiased sample of the difference (Eq. 6–8 integrated from α to α_t instead of
    /// differentiated; Russian roulette detached as for the derivative, its q from the
    /// target's weight β_t, the same at every source albedo).
    AlbedoDifference { medium: u32, target: Vec3 },
    /// Derivatives in several parameters of one medium at once (`Differentiated`): the
    /// albedo's in `PathSample::d_albedo`, the extinction's and the phase asymmetry's in
    /// `PathSample::d_sigma` and `d_g`.
    MediumDerivatives { medium: u32, params: Differentiated },
    /// Reverse mode in the voxels of one grid medium (`integrator::backward`): its
    /// flights and shadow rays are tracked by `medium::differential`, in both passes of
    /// path replay (`sample_adjoint`), so that both take the same paths.
    Adjoint(AdjointParams),
}

/// Which voxels of which medium a reverse-mode render differentiates, and its tracking.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdjointParams {
    pub medium: u32,
    /// The sigma_t grid's values (before `scale`).
    pub sigma_t: bool,
    /// The albedo grid's values.
    pub albedo: bool,
    pub tracking: DifferentialTracking,
    /// A deliberately wrong estimator, for the power tests.
    #[doc(hidden)]
    pub defect: Option<AdjointDefect>,
}

/// The terms a deliberately wrong reverse mode leaves out (the power tests').
#[doc(hidden)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AdjointDefect {
    /// The null collisions' terms (flights and shadow rays): the transmittance's.
    Transmittance,
    /// The real collisions' terms: the scattering weight's.
    Scattering,
    /// No ghost paths: nothing where σ_t = 0 (delta tracking's support).
    Ghosts,
}

/// Which parameters of one medium a render differentiates (`Estimand::MediumDerivatives`).
///
/// Each is forward mode beside β with sampling detached (the paper's Eq. 6–8 for the
/// albedo, generalised): a path's pdf is held fixed and its contribution f
/// differentiated factor by factor, so a sample of ∂f/∂θ / p is β times the sum of
/// ∂ ln(factor)/∂θ over the path's factors that depend on θ. MIS weights are detached
/// too: they sum to 1 at every θ, so their derivatives cancel in expectation.
/// * extinction (homogeneous; d/dσ_t,c per channel, σ_t with `scale` applied): a
///   segment of length s in the medium attenuates by e^{−σ_t s}, ∂ ln = −s; a collision
///   weighs σ_s = α σ_t, ∂ ln = 1/σ_t; a shadow ray's transmittance through the medium
///   likewise (−s per segment in it).
/// * extinction of a heterogeneous medium: d/d`scale`, σ_t(x) = scale · σ(x): a segment
///   attenuates by e^{−scale ∫σ}, ∂ ln = −∫σ, estimated without bias by one uniform
///   point of the segment, (length) σ(x_u), drawn apart from the tracking; a real
///   collision ∂ ln = 1/scale. Delta tracking and ratio tracking are unbiased for any
///   function of where they end, so the factors' derivatives ride on their weights.
/// * g (HG phase): each phase value on the path, sampled (f/p = 1) or evaluated for an
///   emitter sample, ∂ ln p_HG / ∂g (`medium::phase::hg_log_derivative_g`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Differentiated {
    pub albedo: bool,
    pub extinction: bool,
    pub g: bool,
    /// A deliberately wrong estimator for the power tests: the shadow rays' ∂ ln T
    /// left out of the extinction's derivative.
    #[doc(hidden)]
    pub without_shadow_term: bool,
}

impl Differentiated {
    /// Every parameter: the albedo, the extinction and g.
    pub const ALL: Differentiated = Differentiated {
        albedo: true,
        extinction: true,
        g: true,
        without_shadow_term: false,
    };
}

impl Estimand {
    fn medium(self) -> Option<u32> {
        match self {
            Estimand::RadianceOnly => None,
            Estimand::AlbedoDerivative(m)
            | Estimand::AlbedoDerivativeIgnoringNeeVertex(m)
            | Estimand::AlbedoDifference { medium: m, .. } => Some(m),
            Estimand::MediumDerivatives { medium, params } => params.albedo.then_some(medium),
            Estimand::Adjoint(_) => None,
        }
    }

    /// The medium whose extinction is differentiated, if any.
    #[inline]
    pub fn extinction_medium(self) -> Option<u32> {
        match self {
            Estimand::MediumDerivatives { medium, params } if params.extinction => Some(medium),
            _ => None,
        }
    }

    /// Whether the shadow rays' term of the extinction's derivative is left out (the
    /// power tests' wrong estimator).
    #[inline]
    pub(crate) fn without_shadow_term(self) -> bool {
        matches!(self, Estimand::MediumDerivatives { params, .. } if params.without_shadow_term)
    }

    /// The medium whose phase asymmetry g is differentiated, if any.
    #[inline]
    pub fn g_medium(self) -> Option<u32> {
        match self {
            Estimand::MediumDerivatives { medium, params } if params.g => Some(medium),
            _ => None,
        }
    }

    /// Whether the render estimates any derivative or difference (dβ, dσ or dg).
    #[inline]
    pub fn has_derivatives(self) -> bool {
        !matches!(self, Estimand::RadianceOnly)
    }

    /// Whether the paths are rouletted by the target's weight β_t = β + dβ instead of β
    /// (the difference's: `PathState::survives` says why).
    #[inline]
    pub fn roulette_by_target(self) -> bool {
        matches!(self, Estimand::AlbedoDifference { .. })
    }

    /// The weight the roulette goes by: the path's β, or the target's β + dβ
    /// ([`Estimand::roulette_by_target`]), for a path or lanes.
    #[inline(always)]
    pub fn roulette_weight<F: Float>(self, beta: Vector3<F>, d_beta: Vector3<F>) -> Vector3<F> {
        match self.roulette_by_target() {
            true => beta.add(d_beta),
            false => beta,
        }
    }

    /// Whether a medium vertex's emitter sample is weighed by dβ without the vertex's
    /// own albedo (the power tests' wrong derivative).
    #[inline]
    pub(crate) fn nee_ignores_vertex(self) -> bool {
        matches!(self, Estimand::AlbedoDerivativeIgnoringNeeVertex(_))
    }

    /// Whether the render estimates the albedo's derivative (or the difference) into
    /// `PathSample::d_albedo`.
    pub fn has_d_albedo(self) -> bool {
        match self {
            Estimand::RadianceOnly | Estimand::Adjoint(_) => false,
            Estimand::MediumDerivatives { params, .. } => params.albedo,
            _ => true,
        }
    }

    /// How a scattering vertex in medium `mi` of albedo `albedo` updates dβ, the
    /// derivative's (or the difference's) weight: dβ' = w (dβ · a + β · b) with (a, b)
    /// returned here and w the flight's weight. The derivative of β w α: (α, 1) in the
    /// chosen medium. The difference β_t − β with β_t = β (α_t / α)^k: β_t' − β' =
    /// w (dβ α_t + β (α_t − α)), so (α_t, α_t − α), without dividing by α. In other
    /// media α scales both: (α, 0).
    #[inline]
    pub(super) fn vertex_factors(self, mi: u32, albedo: Vec3) -> (Vec3, Vec3) {
        match self {
            Estimand::AlbedoDifference { medium, target } if medium == mi => {
                (target, target - albedo)
            }
            g if g.medium() == Some(mi) => (albedo, Vec3::ONE),
            _ => (albedo, Vec3::ZERO),
        }
    }
}

/// What a render fixes for all its paths besides the scene: each medium's albedo (the
/// scene's or the render's override) and the derivative asked for.
#[derive(Clone, Copy, Debug)]
pub struct PathSettings<'a> {
    pub albedo: &'a [Vec3],
    pub estimand: Estimand,
}

/// One radiance sample along the camera ray (o, d), the camera sitting in
/// `scene.camera_medium`, with the media's albedos of `settings`, and the sample of the
/// derivative asked for (0 for none): Mitsuba's loop, each of its steps one method of
/// [`PathState`] (`volpath::path`).
pub fn sample(
    scene: &Scene,
    settings: &PathSettings,
    o: Vec3A,
    d: Vec3A,
    tmax: f32,
    rng: &mut Pcg32,
) -> PathSample {
    sample_with(scene, settings, (o, d, tmax), rng, None)
}

/// One pass of path replay backpropagation (Vicini et al. 2021) for the camera ray
/// `ray`: the first pass (`AdjointPath::new`) gathers the path's radiance, the second
/// (`AdjointPath::replay`, from the same random stream, so along the same path)
/// scatters each factor's derivative times the adjoint of what the path gathers after
/// it into the voxels (`volpath::path::adjoint`). Memory does not grow with the path.
pub fn sample_adjoint(
    scene: &Scene,
    settings: &PathSettings,
    ray: (Vec3A, Vec3A, f32),
    rng: &mut Pcg32,
    adjoint: &mut AdjointPath,
) -> PathSample {
    sample_with(scene, settings, ray, rng, Some(adjoint))
}

fn sample_with(
    scene: &Scene,
    settings: &PathSettings,
    (o, d, tmax): (Vec3A, Vec3A, f32),
    rng: &mut Pcg32,
    adjoint: Option<&mut AdjointPath>,
) -> PathSample {
    let mut path = PathState::new(scene, (o, d, tmax), rng, adjoint);
    run(&mut path, scene, settings, rng);
    path.sample()
}

/// Mitsuba's loop from `path`'s state on, until the path ends.
fn run(path: &mut PathState, scene: &Scene, settings: &PathSettings, rng: &mut Pcg32) {
    loop {
        // ---- Termination: zero weight, depth, Russian roulette ----
        if !path.survives(scene, settings, rng) {
            break;
        }
        // ---- Free flight through the current medium ----
        let flight = match path.medium {
            Some(mi) => path.free_flight(scene, settings, mi, rng),
            None => Flight::through_vacuum(),
        };
        if path.medium.is_some() && !path.weights_finite() {
            break;
        }
        if flight.scattered {
            // ---- A scattering vertex in the medium ----
            if !path.scatter_in_medium(scene, settings, &flight, rng) {
                break;
            }
            continue;
        }
        // ---- Surface interaction (or escape) ----
        if !path.at_surface(scene, settings, flight, rng) {
            break;
        }
    }
}

#[inline]
fn mean(v: Vec3) -> f32 {
    (v.x + v.y + v.z) * (1.0 / 3.0)
}

mod path;
mod shadow;
#[cfg(test)]
mod tests;

pub use path::{AdjointPath, GridGradients};
use path::{Flight, PathState};
use shadow::{shadow_transmittance, ShadowDerivative, ShadowRay};
