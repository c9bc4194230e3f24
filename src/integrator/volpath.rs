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

use super::emitters::{sample_light_at_surface, skip_emitters};
use super::roulette::continue_probability;
use super::sample::PathSample;
use crate::bsdf::Bsdf;
use crate::geometry::accel::{Crossing, CrossingList, Crossings};
use crate::geometry::{offset_point, SHADOW_EPSILON};
use crate::medium::{
    collision_weight, expected_pass_weight, pass_weight, transmittance, HomogeneousMedium,
};
use crate::sampling::mis_weight;
use crate::sampling::Pcg32;
use crate::scene::{Scene, ShapeInfo, SurfaceInteraction};

/// Null-boundary crossings a shadow ray may make before it is treated as blocked
/// (guards against a degenerate scene trapping the ray).
const MAX_SHADOW_CROSSINGS: u32 = 256;
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

/// Transmittance from `o` along unit `d` over `dist`, starting in `medium`: the product
/// of `e^{−σ_t s}` over the segments, through `null` surfaces (switching medium by the
/// side crossed) and `thindielectric` ones (times their transmission); 0 if any other
/// surface blocks the way.
///
/// Where the accelerator can, it finds every crossing in one traversal
/// ([`Scene::crossings`]); else one ray is
/// cast per crossing, as Mitsuba does.
fn shadow_transmittance(
    scene: &Scene,
    o: Vec3A,
    d: Vec3A,
    dist: f32,
    medium: Option<u32>,
    rng: &mut Pcg32,
) -> Vec3 {
    let mut hits = CrossingList::new();
    match scene.crossings(o, d, dist, &mut hits) {
        Crossings::Blocked => Vec3::ZERO,
        Crossings::Found => through_crossings(scene, o, d, dist, medium, &mut hits, rng),
        Crossings::Unsupported => shadow_transmittance_stepwise(scene, o, d, dist, medium, rng),
    }
}

/// The transmittance of a shadow ray over `dist` whose pass-through crossings
/// are `hits` (in any order): the segments between them in turn, each in the medium
/// the previous crossing entered. A surface found twice at one distance (on an edge
/// shared by two triangles) changes nothing: the second crossing enters the medium the
/// first did, after a segment of length 0.
fn through_crossings(
    scene: &Scene,
    o: Vec3A,
    d: Vec3A,
    dist: f32,
    mut medium: Option<u32>,
    hits: &mut [Crossing],
    rng: &mut Pcg32,
) -> Vec3 {
    hits.sort_unstable_by(|a, b| a.t.total_cmp(&b.t));
    let mut tr = Vec3::ONE;
    let mut start = 0.0f32;
    for h in hits.iter() {
        if let Some(m) = medium {
            tr *= segment_transmittance(scene, m, o + d * start, d, h.t - start, rng);
        }
        start = h.t;
        medium = medium_beyond(&scene.shapes[h.shape as usize], h.along_normal, medium);
    }
    if let Some(m) = medium {
        tr *= segment_transmittance(scene, m, o + d * start, d, dist - start, rng);
    }
    tr
}

/// The transmittance of a segment from `o` along `d` of length `len` in medium `m`:
/// Beer–Lambert in a homogeneous medium, ratio tracking (an unbiased estimate) in a
/// heterogeneous one.
#[inline]
fn segment_transmittance(
    scene: &Scene,
    m: u32,
    o: Vec3A,
    d: Vec3A,
    len: f32,
    rng: &mut Pcg32,
) -> Vec3 {
    let med = &scene.media[m as usize];
    match &med.heterogeneous {
        None => transmittance(med.sigma_t, len),
        Some(h) => h.transmittance(o, d, len, rng),
    }
}

/// [`shadow_transmittance`] by one closest-hit cast per crossing.
fn shadow_transmittance_stepwise(
    scene: &Scene,
    mut o: Vec3A,
    d: Vec3A,
    mut dist: f32,
    mut medium: Option<u32>,
    rng: &mut Pcg32,
) -> Vec3 {
    let mut tr = Vec3::ONE;
    for _ in 0..MAX_SHADOW_CROSSINGS {
        if dist <= 0.0 {
            return tr;
        }
        let hit = scene.intersect(o, d, dist);
        let seg = hit.map_or(dist, |h| h.t);
        if let Some(m) = medium {
            tr *= segment_transmittance(scene, m, o, d, seg, rng);
        }
        let Some(h) = hit else { return tr };
        let info = &scene.shapes[h.shape as usize];
        // Through a null or thin-dielectric surface, by what it lets through; any
        // other surface blocks.
        tr *= scene.bsdfs[info.bsdf as usize].null_transmission(h.sh_frame.n.dot(d), h.uv);
        if tr == Vec3::ZERO {
            return Vec3::ZERO;
        }
        medium = medium_after(info, h.n, d, medium);
        let o2 = offset_point(h.p, h.n, d, scene.offset_scale);
        dist -= (o2 - o).length();
        o = o2;
    }
    Vec3::ZERO
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
/// derivative asked for (0 for none).
pub fn sample(
    scene: &Scene,
    settings: &PathSettings,
    o: Vec3A,
    d: Vec3A,
    tmax: f32,
    rng: &mut Pcg32,
) -> PathSample {
    let s = &scene.integrator;
    let n_emitters = scene.emitters.len();
    let mut result = Vec3::ZERO;
    let mut seen_emission = Vec3::ZERO;
    // Mitsuba's `valid_ray`, the film's alpha: a visible environment, a scattering in a
    // medium, or a surface whose BSDF sample is not a null one.
    let mut valid = !s.hide_emitters && scene.environment.is_some();
    let mut d_result = Vec3::ZERO;
    // dβ/dα of the chosen medium's albedo (zero while no vertex in it).
    let mut d_beta = Vec3::ZERO;
    // β = f / p_hero and r_c = p_c / p_hero (see the module comment), rescaled together
    // after every free flight so that mean(r) = 1: β is then the path's weight.
    let mut beta = Vec3::ONE;
    let mut r_u = Vec3::ONE;
    let mut eta = 1.0f32;
    let mut depth: u32 = 0;
    let mut null_crossings: u32 = 0;
    let mut medium = scene.camera_medium;
    let mut specular_chain = !s.hide_emitters;
    let mut last = LastScatter { p: o, pdf: 1.0 };
    // The clearance at `ray_o`, where already looked up (see the free flight).
    let mut origin_clearance: Option<f32> = None;
    let hero = ((rng.next_1d() * 3.0) as usize).min(2);
    let (mut ray_o, mut ray_d, mut ray_tmax) = (o, d, tmax);

    loop {
        // ---- Termination: zero weight, depth, Russian roulette ----
        if (beta == Vec3::ZERO && d_beta == Vec3::ZERO) || depth >= s.max_depth {
            break;
        }
        if depth > s.rr_depth {
            // Drawn only where the roulette is played (by depth, so the same at every
            // albedo): the path's first draws, stratified (`sampling::padded`), go to
            // what shapes the image, not to a roulette that is not played.
            let u_rr = rng.next_1d();
            // The same q as without a gradient (same paths), except that a path whose β
            // is 0 but dβ is not (albedo 0) must keep q > 0 for the detached estimator.
            // The difference's paths are rouletted by the target's weight β_t = β + dβ
            // (≥ β): by β, long paths, which weigh (α_t/α)^k more at the target, would
            // end early and their survivors' 1/q give D a heavy tail; by β_t, |dβ|/q stays
            // bounded, and q is the same at every source albedo.
            let roulette_weight = match settings.gradient {
                Gradient::Difference { .. } => beta + d_beta,
                _ => beta,
            };
            let q = continue_probability(roulette_weight.into(), d_beta.into(), eta);
            if q.is_nan() || u_rr >= q {
                break;
            }
            beta /= q;
            d_beta /= q;
        }

        // ---- Free flight through the current medium ----
        // Whether the emission at this ray's end is already counted (in expectation).
        let mut emission_counted = false;
        let mut si;
        let mut in_medium = false;
        // dβ without this vertex's own α (for the power-test variant only).
        let mut d_beta_before = Vec3::ZERO;
        if let Some(mi) = medium {
            let m: &HomogeneousMedium = &scene.media[mi as usize];
            // The render's albedo of this medium (the scene's unless overridden).
            let albedo = settings.albedo[mi as usize];
            // The clearance at the flight's origin, where the vertex it starts from
            // looked it up (for its emitter sample): the same point, the same value.
            let known_clearance = origin_clearance.take();
            let (t, clearance) = if let Some(het) = m.heterogeneous.as_deref() {
                // ---- Delta tracking through a heterogeneous medium ----
                // The surface that ends the ray, then the first real collision before
                // it (medium::heterogeneous). The majorant is grey, so every channel's
                // pdf is the hero's: r is unchanged.
                let hit = scene.intersect_in_medium(mi, ray_o, ray_d, ray_tmax);
                let end = hit.as_ref().map_or(ray_tmax, |h| h.t);
                let (collision, w) = het.sample_flight(ray_o, ray_d, end, rng);
                beta *= w;
                d_beta *= w;
                match collision {
                    Some(c) => {
                        si = None;
                        // The albedo there: the render's factor on the volume (1 as
                        // loaded) times the volume's value; the gradient is the
                        // factor's, so the vertex weighs c.albedo beside it.
                        d_beta_before = d_beta * albedo * c.albedo;
                        let (a, b) = settings.gradient.vertex_factors(mi, albedo);
                        d_beta = (d_beta * a + beta * b) * c.albedo;
                        beta *= albedo * c.albedo;
                        in_medium = true;
                        (c.t, 0.0)
                    }
                    None => {
                        si = hit;
                        (end, 0.0)
                    }
                }
            } else {
                let t = m.sample_distance(hero, rng.next_1d());
                // Within the clearance no surface can be hit: the cast's answer is known.
                // In a convex medium the distance to its one shape is a clearance too, and
                // an exact one. Shadow rays are still played against the grid's alone
                // (below): against the convex one, the medium cube's shadow roulette cost
                // more in variance (+6% MSE) than it saved in time (−2%).
                let clearance = known_clearance.unwrap_or_else(|| scene.clearance.at(ray_o));
                let convex = scene.convex_media[mi as usize].as_ref();
                let skip_within = convex.map_or(clearance, |b| {
                    b.clearance(&scene.geometries, ray_o).max(clearance)
                });
                // Where the ray may end on an area emitter, it is cast in full (not only up
                // to t, nor skipped within the clearance), so the emission there can be
                // counted in expectation.
                si = if scene.may_see_area_emitter(mi, ray_o, ray_d) {
                    let full = scene.intersect_in_medium(mi, ray_o, ray_d, ray_tmax);
                    // ---- Emission at the segment's end, in expectation ----
                    // The flight passes to the hit with probability T_hero(h.t) and then weighs the
                    // emission by β T / mean(r T) (see the module comment): count that
                    // product now instead of its 0-or-1 sample, and not again at the hit.
                    if let Some(h) = &full {
                        let le = emission_seen(scene, Some(h), ray_d, depth, specular_chain, &last);
                        if le != Vec3::ZERO {
                            let tr = m.transmittance(h.t);
                            let pass: Vec3 =
                                expected_pass_weight(tr.into(), tr[hero], r_u.into()).into();
                            if pass.is_finite() {
                                result += beta * pass * le;
                                d_result += d_beta * pass * le;
                            }
                            emission_counted = true;
                        }
                    }
                    full.filter(|h| h.t < t)
                } else if t < skip_within {
                    None
                } else {
                    scene.intersect_in_medium(mi, ray_o, ray_d, t.min(ray_tmax))
                };
                let collided = si.is_none() && t.is_finite() && t <= ray_tmax;
                if m.is_grey() {
                    // Grey σ_t: f and every p_c are alike, so w = T / T = 1 for passing and
                    // σ_t T / (σ_t T) = 1 for a collision (exactly, in floating point too):
                    // only α is left, r is unchanged, and no transmittance is needed.
                    if collided {
                        d_beta_before = d_beta * albedo;
                        let (a, b) = settings.gradient.vertex_factors(mi, albedo);
                        d_beta = d_beta * a + beta * b;
                        beta *= albedo;
                        in_medium = true;
                    }
                } else {
                    match si {
                        Some(h) => {
                            // Passed the whole segment: f = T, p_c = T_c.
                            let tr = m.transmittance(h.t);
                            let w: Vec3 = pass_weight(tr.into(), tr[hero]).into();
                            beta *= w;
                            d_beta *= w;
                            r_u *= w;
                        }
                        None if collided => {
                            // Collision at t: f = T σ_t α, p_c = σ_t,c T_c.
                            let tr = m.transmittance(t);
                            let w: Vec3 = collision_weight(
                                tr.into(),
                                m.sigma_t.into(),
                                m.sigma_t[hero],
                                tr[hero],
                            )
                            .into();
                            // d(β w α)/dα = dβ w α + β w in the chosen medium.
                            d_beta_before = d_beta * w * albedo;
                            let (a, b) = settings.gradient.vertex_factors(mi, albedo);
                            d_beta = d_beta * w * a + beta * w * b;
                            beta *= w * albedo;
                            r_u *= w;
                            in_medium = true;
                        }
                        None => {
                            // Left through the far end of the ray without a collision.
                            let tr = m.transmittance(ray_tmax);
                            let w: Vec3 = pass_weight(tr.into(), tr[hero]).into();
                            beta *= w;
                            d_beta *= w;
                            r_u *= w;
                        }
                    }
                    // Keep mean(r) = 1: scaling β and r alike leaves β / mean(r) and every later
                    // update unchanged, and keeps both bounded on long chromatic paths.
                    let k = mean(r_u);
                    beta /= k;
                    d_beta /= k;
                    d_beta_before /= k;
                    r_u /= k;
                }
                (t, clearance)
            };
            if !beta.is_finite() || !r_u.is_finite() || !d_beta.is_finite() {
                break;
            }
            if in_medium {
                null_crossings = 0;
                depth += 1;
                if depth >= s.max_depth {
                    break;
                }
                valid = true;
                let p = ray_o + ray_d * t;
                // ---- Emitter sampling from the medium vertex ----
                // p lies within the flight's clearance less t, and within its own, which
                // the next flight (from p) starts with. A heterogeneous medium has no
                // use for either: its shadow rays are not rouletted, and its flights are
                // cast in full.
                let free = if m.heterogeneous.is_none() {
                    let at_p = scene.clearance.at(p);
                    origin_clearance = Some(at_p);
                    (clearance - t).max(at_p)
                } else {
                    0.0
                };
                let x = medium_emitter_sample(scene, m, medium, p, ray_d, free, rng);
                if x != Vec3::ZERO {
                    result += beta * x;
                    d_result += x * match settings.gradient {
                        Gradient::AlbedoIgnoringNeeVertex(_) => d_beta_before,
                        _ => d_beta,
                    };
                }
                specular_chain = !m.sample_emitters;
                // ---- Phase function sampling ----
                let (wo, pdf) = m.phase.sample(ray_d, rng.next_2d());
                last = LastScatter { p, pdf };
                ray_o = p;
                ray_d = wo;
                ray_tmax = f32::INFINITY;
                continue;
            }
        } else {
            si = None;
        }

        // ---- Surface interaction (or escape) ----
        if medium.is_none() {
            si = if s.hide_emitters && depth == 0 {
                skip_emitters(scene, ray_o, ray_d, ray_tmax)
            } else {
                scene.intersect(ray_o, ray_d, ray_tmax)
            };
        }
        if !emission_counted {
            let le = emission_seen(scene, si.as_ref(), ray_d, depth, specular_chain, &last);
            result += beta * le;
            d_result += d_beta * le;
            // At the camera ray's first intersection, as `aovs::seen_emission` traces it.
            if depth == 0 && null_crossings == 0 && medium.is_none() && si.is_some() {
                seen_emission = le;
            }
        }
        let Some(h) = si else { break };
        let info = &scene.shapes[h.shape as usize];
        let bsdf = &scene.bsdfs[info.bsdf as usize];

        // ---- A null boundary: the ray goes on unchanged into the next medium ----
        // What the null BSDF's sample says (wo = ray_d, weight 1, not a scattering
        // vertex, no emitter sampling), without its frame changes and random numbers.
        if matches!(bsdf, Bsdf::Null) {
            null_crossings += 1;
            if null_crossings > MAX_NULL_CROSSINGS {
                break;
            }
            medium = medium_after(info, h.n, ray_d, medium);
            ray_o = offset_point(h.p, h.n, ray_d, scene.offset_scale);
            ray_tmax = f32::INFINITY;
            continue;
        }
        let wi = h.sh_frame.to_local(-ray_d);

        // ---- Emitter sampling from the surface ----
        if bsdf.is_smooth() && n_emitters > 0 && depth + 1 < s.max_depth {
            let u = rng.next_2d();
            let transmittance = |o, d, dist| {
                let m = medium_after(info, h.n, d, medium);
                shadow_transmittance(scene, o, d, dist, m, rng)
            };
            if let Some(ls) = sample_light_at_surface(scene, &h, wi, bsdf, u, transmittance) {
                let w = if ls.delta {
                    1.0
                } else {
                    mis_weight(ls.emitter_pdf, ls.bsdf_pdf)
                };
                result += beta * ls.value * w;
                d_result += d_beta * ls.value * w;
            }
        }

        // ---- BSDF sampling ----
        let s1 = rng.next_1d();
        let s2 = rng.next_2d();
        let sampled = bsdf.sample(wi, s1, s2, h.uv);
        // A failed sample is not a null one (Mitsuba tests the sampled lobe's flags).
        valid |= !sampled.is_some_and(|b| b.null);
        let Some(bs) = sampled else {
            break;
        };
        let wo = h.sh_frame.to_world(bs.wo);
        beta *= bs.weight;
        d_beta *= bs.weight;
        eta *= bs.eta;
        if bs.null {
            null_crossings += 1;
            if null_crossings > MAX_NULL_CROSSINGS {
                break;
            }
        } else {
            null_crossings = 0;
            depth += 1;
            last = LastScatter {
                p: h.p,
                pdf: bs.pdf,
            };
            specular_chain = bs.delta;
        }
        medium = medium_after(info, h.n, wo, medium);
        ray_o = offset_point(h.p, h.n, wo, scene.offset_scale);
        ray_d = wo;
        ray_tmax = f32::INFINITY;
    }
    PathSample {
        radiance: result,
        second: d_result,
        seen_emission,
        valid,
    }
}

#[inline]
fn mean(v: Vec3) -> f32 {
    (v.x + v.y + v.z) * (1.0 / 3.0)
}

#[cfg(test)]
mod tests;
