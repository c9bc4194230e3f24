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

use super::sample::PathSample;
use crate::geometry::SHADOW_EPSILON;
use crate::medium::HomogeneousMedium;
use crate::sampling::mis_weight;
use crate::sampling::Pcg32;
use crate::scene::{Scene, ShapeInfo, SurfaceInteraction};

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

/// Emitter sampling from the medium point `p` of `m` (in `medium`), light leaving it
/// against `d_in`: phase · L · T / p_select, MIS-weighted (power heuristic) against
/// phase sampling; zero when nothing arrives. `free` is a distance `p` is known to lie
/// from every surface (the clearance there, or 0 if none is known), for the shadow
/// ray's roulette.
#[inline]
fn medium_emitter_sample(
    scene: &Scene,
    m: &HomogeneousMedium,
    medium: Option<u32>,
    p: Vec3A,
    d_in: Vec3A,
    free: f32,
    rng: &mut Pcg32,
) -> Vec3 {
    // (Where no emitter sample can arrive, none is drawn: see Scene::emitters_unreachable.)
    if !m.sample_emitters || medium.is_some_and(|mi| scene.emitters_unreachable[mi as usize]) {
        return Vec3::ZERO;
    }
    // None where there is no emitter to pick (none at all, or only a sky left to
    // phase sampling).
    let Some((idx, u, p_select)) = scene.emitter_selection.select(p, rng.next_2d()) else {
        return Vec3::ZERO;
    };
    let e = &scene.emitters[idx];
    let Some(es) = e.sample_direction(p, u, &scene.geometries, &scene.bsphere) else {
        return Vec3::ZERO;
    };
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
    let q = if sigma_min > 0.0 && free > 0.0 {
        (-sigma_min * dist.min(free)).exp()
    } else {
        1.0
    };
    let tr = if q >= 1.0 {
        shadow_transmittance(scene, p, es.d, dist, medium, rng)
    } else if q > 0.0 && rng.next_1d() < q {
        shadow_transmittance(scene, p, es.d, dist, medium, rng) / q
    } else {
        return Vec3::ZERO;
    };
    if tr == Vec3::ZERO {
        return Vec3::ZERO;
    }
    let w = if es.delta {
        1.0
    } else {
        mis_weight(es.pdf * p_select, phase_val)
    };
    phase_val * es.weight * tr / p_select * w
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
    let e = &scene.emitters[ei as usize];
    let (p_end, n_end) = hit.map_or((last.p, Vec3A::ZERO), |h| (h.p, h.sh_frame.n));
    if depth == 0 || specular_chain {
        return e.eval(n_end, ray_d);
    }
    let (le, pdf) = e.eval_and_pdf(last.p, p_end, n_end, ray_d, &scene.geometries);
    let em_pdf = pdf * scene.emitter_selection.pdf(last.p, ei as usize);
    le * mis_weight(last.pdf, em_pdf)
}

/// Which derivative to estimate beside the radiance.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Gradient {
    #[default]
    None,
    /// d(radiance_c)/d(albedo_c) of this medium.
    Albedo(u32),
    /// A deliberately wrong variant for the power tests: NEE contributions do not count
    /// the vertex they are made from (k − 1 instead of k).
    #[doc(hidden)]
    AlbedoIgnoringNeeVertex(u32),
    /// R(α_t) − R(α) of this medium, α the albedo rendered with and α_t `target`, in the
    /// same paths: each path's contribution f carries α^k for its k scattering vertices
    /// in the medium and its sampling does not depend on α, so f · ((α_t / α)^k − 1) is
    /// an unbiased sample of the difference (Eq. 6–8 integrated from α to α_t instead of
    /// differentiated; Russian roulette detached as for the derivative, its q from the
    /// target's weight β_t, the same at every source albedo).
    Difference { medium: u32, target: Vec3 },
}

impl Gradient {
    fn medium(self) -> Option<u32> {
        match self {
            Gradient::None => None,
            Gradient::Albedo(m)
            | Gradient::AlbedoIgnoringNeeVertex(m)
            | Gradient::Difference { medium: m, .. } => Some(m),
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
            Gradient::Difference { medium, target } if medium == mi => (target, target - albedo),
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
    pub gradient: Gradient,
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
    let mut path = PathState::new(scene, (o, d, tmax), rng);
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
        if !path.at_surface(scene, flight, rng) {
            break;
        }
    }
    path.sample()
}

#[inline]
fn mean(v: Vec3) -> f32 {
    (v.x + v.y + v.z) * (1.0 / 3.0)
}

mod path;
mod shadow;
#[cfg(test)]
mod tests;

use path::{Flight, PathState};
use shadow::shadow_transmittance;
