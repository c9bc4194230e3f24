//! Mitsuba 3's `volpath` integrator (`src/integrators/volpath.cpp`): volumetric path
//! tracing in homogeneous media with emitter sampling at surface and medium vertices,
//! combined with BSDF / phase sampling by the power heuristic.
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
use crate::bsdf::Bsdf;
use crate::geometry::accel::{Crossing, CrossingList, Crossings};
use crate::geometry::{offset_point, SHADOW_EPSILON};
use crate::medium::{transmittance, HomogeneousMedium};
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
fn shadow_transmittance(scene: &Scene, o: Vec3A, d: Vec3A, dist: f32, medium: Option<u32>) -> Vec3 {
    let mut hits = CrossingList::new();
    match scene.crossings(o, d, dist, &mut hits) {
        Crossings::Blocked => Vec3::ZERO,
        Crossings::Found => through_crossings(scene, dist, medium, &mut hits),
        Crossings::Unsupported => shadow_transmittance_stepwise(scene, o, d, dist, medium),
    }
}

/// The transmittance of a shadow ray over `dist` whose pass-through crossings
/// are `hits` (in any order): the segments between them in turn, each in the medium
/// the previous crossing entered. A surface found twice at one distance (on an edge
/// shared by two triangles) changes nothing: the second crossing enters the medium the
/// first did, after a segment of length 0.
fn through_crossings(
    scene: &Scene,
    dist: f32,
    mut medium: Option<u32>,
    hits: &mut [Crossing],
) -> Vec3 {
    hits.sort_unstable_by(|a, b| a.t.total_cmp(&b.t));
    let mut tr = Vec3::ONE;
    let mut start = 0.0f32;
    for h in hits.iter() {
        if let Some(m) = medium {
            tr *= transmittance(scene.media[m as usize].sigma_t, h.t - start);
        }
        start = h.t;
        medium = medium_beyond(&scene.shapes[h.shape as usize], h.along_normal, medium);
    }
    if let Some(m) = medium {
        tr *= transmittance(scene.media[m as usize].sigma_t, dist - start);
    }
    tr
}

/// [`shadow_transmittance`] by one closest-hit cast per crossing.
fn shadow_transmittance_stepwise(
    scene: &Scene,
    mut o: Vec3A,
    d: Vec3A,
    mut dist: f32,
    mut medium: Option<u32>,
) -> Vec3 {
    let mut tr = Vec3::ONE;
    for _ in 0..MAX_SHADOW_CROSSINGS {
        if dist <= 0.0 {
            return tr;
        }
        let hit = scene.intersect(o, d, dist);
        let seg = hit.map_or(dist, |h| h.t);
        if let Some(m) = medium {
            tr *= transmittance(scene.media[m as usize].sigma_t, seg);
        }
        let Some(h) = hit else { return tr };
        let info = &scene.shapes[h.shape as usize];
        // Through a null or thin-dielectric surface, by what it lets through; any
        // other surface blocks.
        tr *= scene.bsdfs[info.bsdf as usize].null_transmission(h.sh_frame.n.dot(d));
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
/// from every surface (0 if none is known), for the shadow ray's roulette.
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
    let sigma_min = m.sigma_t.min_element();
    let free = free.max(scene.clearance.at(p));
    let q = if sigma_min > 0.0 && free > 0.0 {
        (-sigma_min * dist.min(free)).exp()
    } else {
        1.0
    };
    let tr = if q >= 1.0 {
        shadow_transmittance(scene, p, es.d, dist, medium)
    } else if q > 0.0 && rng.next_1d() < q {
        shadow_transmittance(scene, p, es.d, dist, medium) / q
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
    let le = e.eval(n_end, ray_d);
    let w = if depth == 0 || specular_chain {
        1.0
    } else {
        let em_pdf = e.pdf_direction(last.p, p_end, n_end, ray_d, &scene.geometries)
            * scene.emitter_selection.pdf(last.p, ei as usize);
        mis_weight(last.pdf, em_pdf)
    };
    le * w
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
    /// differentiated; Russian roulette detached as for the derivative).
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
    fn vertex_factors(self, mi: u32, albedo: Vec3) -> (Vec3, Vec3) {
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
) -> (Vec3, Vec3) {
    let s = &scene.integrator;
    let n_emitters = scene.emitters.len();
    let mut result = Vec3::ZERO;
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
    let hero = ((rng.next_1d() * 3.0) as usize).min(2);
    let (mut ray_o, mut ray_d, mut ray_tmax) = (o, d, tmax);

    loop {
        // ---- Termination: zero weight, depth, Russian roulette ----
        if (beta == Vec3::ZERO && d_beta == Vec3::ZERO) || depth >= s.max_depth {
            break;
        }
        let u_rr = rng.next_1d();
        if depth > s.rr_depth {
            // The same q as without a gradient (same paths), except that a path whose β
            // is 0 but dβ is not (albedo 0) must keep q > 0 for the detached estimator.
            let w = match beta.max_element() {
                b if b > 0.0 => b,
                _ => d_beta.abs().max_element(),
            };
            let q = (w * eta * eta).min(0.95);
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
            let t = m.sample_distance(hero, rng.next_1d());
            // Within the clearance no surface can be hit: the cast's answer is known.
            // In a convex medium the distance to its one shape is a clearance too, and
            // an exact one. Shadow rays are still played against the grid's alone
            // (below): against the convex one, the medium cube's shadow roulette cost
            // more in variance (+6% MSE) than it saved in time (−2%).
            let clearance = scene.clearance.at(ray_o);
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
                        let pass = tr * (tr[hero] / mean(r_u * tr));
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
                        let w = tr / tr[hero];
                        beta *= w;
                        d_beta *= w;
                        r_u *= w;
                    }
                    None if collided => {
                        // Collision at t: f = T σ_t α, p_c = σ_t,c T_c.
                        let tr = m.transmittance(t);
                        let p_hero = m.sigma_t[hero] * tr[hero];
                        let w = tr * m.sigma_t / p_hero;
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
                        let w = tr / tr[hero];
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
            if !beta.is_finite() || !r_u.is_finite() || !d_beta.is_finite() {
                break;
            }
            if in_medium {
                null_crossings = 0;
                depth += 1;
                if depth >= s.max_depth {
                    break;
                }
                let p = ray_o + ray_d * t;
                // ---- Emitter sampling from the medium vertex ----
                // p lies within the flight's clearance less t.
                let x = medium_emitter_sample(scene, m, medium, p, ray_d, clearance - t, rng);
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
            let transmittance = |o, d, dist| {
                shadow_transmittance(scene, o, d, dist, medium_after(info, h.n, d, medium))
            };
            if let Some(ls) =
                sample_light_at_surface(scene, &h, wi, bsdf, rng.next_2d(), transmittance)
            {
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
        let Some(bs) = bsdf.sample(wi, s1, s2, h.uv) else {
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
    (result, d_result)
}

#[inline]
fn mean(v: Vec3) -> f32 {
    (v.x + v.y + v.z) * (1.0 / 3.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::load::BuildOverrides;
    use crate::sampling::warp::square_to_uniform_sphere;

    /// Two null cubes around media (one chromatic and turned) and a blocking cube, in
    /// the BVH together.
    const CUBES: &str = r#"
        <shape type="cube">
            <transform name="to_world"><scale value="0.5"/><translate x="-1"/></transform>
            <bsdf type="null"/>
            <medium type="homogeneous" name="interior">
                <float name="sigma_t" value="2"/><float name="albedo" value="0.5"/></medium>
        </shape>
        <shape type="cube">
            <transform name="to_world"><rotate y="1" angle="30"/><scale value="0.6"/>
                <translate x="0.8"/></transform>
            <bsdf type="null"/>
            <medium type="homogeneous" name="interior">
                <rgb name="sigma_t" value="0.2, 0.6, 1"/><float name="scale" value="5"/>
                <float name="albedo" value="0.5"/></medium>
        </shape>
        <shape type="cube">
            <transform name="to_world"><scale value="0.4"/><translate y="1.5"/></transform>
            <bsdf type="diffuse"/>
        </shape>"#;

    /// Analytic shapes beside the BVH: a blocking sphere, a null sphere around a medium
    /// and a null rectangle that bounds no medium (crossing it changes nothing).
    const ANALYTIC: &str = r#"
        <shape type="sphere">
            <point name="center" x="0" y="-1.5" z="0"/><float name="radius" value="0.4"/>
        </shape>
        <shape type="sphere">
            <point name="center" x="0.9" y="-1" z="1.5"/><float name="radius" value="0.6"/>
            <bsdf type="null"/>
            <medium type="homogeneous" name="interior">
                <float name="sigma_t" value="3"/><float name="albedo" value="0.5"/></medium>
        </shape>
        <shape type="rectangle">
            <transform name="to_world"><scale value="0.5"/><translate x="-1" y="1.2" z="-0.8"/>
            </transform>
            <bsdf type="null"/>
        </shape>"#;

    /// The scene with the cubes (if `cubes`) as boxes beside the BVH, as loaded (see
    /// `geometry::cuboid`), or as triangles in it (`boxes` false).
    fn scene_with(test: &str, cubes: bool, boxes: bool) -> Scene {
        let mut scene = scene(test, cubes);
        if !boxes {
            for g in &mut scene.geometries {
                if let crate::geometry::shape::Geometry::Mesh(m) = g {
                    m.cube_to_world = None;
                }
            }
            let refs: Vec<_> = scene.geometries.iter().collect();
            scene.accel = crate::geometry::accel::Accel::build(&refs);
        }
        scene
    }

    /// A scene of [`ANALYTIC`], after [`CUBES`] if `cubes`, written to a file of the
    /// test's own (tests run in parallel).
    fn scene(test: &str, cubes: bool) -> Scene {
        let xml = format!(
            r#"<scene version="3.0.0">
            <sensor type="perspective"><film type="hdrfilm">
                <integer name="width" value="4"/><integer name="height" value="4"/></film>
            </sensor>{}{ANALYTIC}</scene>"#,
            if cubes { CUBES } else { "" }
        );
        load_xml(test, &xml)
    }

    /// Loads a scene file's text, written to a file named after `name` (each test its
    /// own name: tests run in parallel).
    fn load_xml(name: &str, xml: &str) -> Scene {
        let dir = std::env::temp_dir().join(format!("mediareg_volpath_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(format!("{name}.xml"));
        std::fs::write(&path, xml).unwrap();
        crate::load_scene(&path, &Default::default(), &BuildOverrides::default())
            .unwrap_or_else(|e| panic!("{name}: {e}"))
    }

    /// Where the ray o + t d is inside the box (local [-1, 1]³ mapped by `to_local`
    /// from the world), as (t_in, t_out) with t in world units, if it meets it.
    fn box_interval(to_local: glam::Affine3A, o: Vec3A, d: Vec3A) -> Option<(f32, f32)> {
        let (lo, ld) = (
            to_local.transform_point3a(o),
            to_local.transform_vector3a(d),
        );
        let (a, b) = ((-Vec3A::ONE - lo) / ld, (Vec3A::ONE - lo) / ld);
        let (t0, t1) = (a.min(b).max_element(), a.max(b).min_element());
        (t0 < t1).then_some((t0, t1))
    }

    /// Where the ray o + t d (unit d) is inside the sphere (c, r), if it meets it:
    /// |o + t d − c|² = r².
    fn sphere_interval(c: Vec3A, r: f32, o: Vec3A, d: Vec3A) -> Option<(f32, f32)> {
        let oc = o - c;
        let (b, c) = (oc.dot(d), oc.length_squared() - r * r);
        let disc = b * b - c;
        (disc > 0.0).then(|| (-b - disc.sqrt(), -b + disc.sqrt()))
    }

    /// The exact transmittance of the shadow ray in [`scene`]`(_, cubes)`: the media's
    /// intervals clipped to (0, dist), crossed in order (the medium before the first
    /// crossing is `medium`, after one the entered shape's or none), 0 if a blocker lies
    /// on the way. Media are numbered as the scene numbers them (in file order).
    fn exact(o: Vec3A, d: Vec3A, dist: f32, medium: Option<u32>, cubes: bool) -> Vec3 {
        use glam::{Affine3A, Quat};
        let on_way = |t: f32| t > 0.0 && t < dist;
        let crosses = |i: Option<(f32, f32)>| i.is_some_and(|(a, b)| on_way(a) || on_way(b));
        // (interval, σ_t) of each medium, in file order.
        let mut media = Vec::new();
        if cubes {
            let blocker = Affine3A::from_scale_rotation_translation(
                Vec3::splat(0.4),
                Quat::IDENTITY,
                Vec3::new(0.0, 1.5, 0.0),
            );
            if crosses(box_interval(blocker.inverse(), o, d)) {
                return Vec3::ZERO;
            }
            let cube = |scale: f32, angle: f32, x: f32| {
                let q = Quat::from_rotation_y(angle.to_radians());
                let m =
                    Affine3A::from_scale_rotation_translation(Vec3::splat(scale), q, Vec3::X * x);
                box_interval(m.inverse(), o, d)
            };
            media.push((cube(0.5, 0.0, -1.0), Vec3::splat(2.0)));
            media.push((cube(0.6, 30.0, 0.8), Vec3::new(1.0, 3.0, 5.0)));
        }
        if crosses(sphere_interval(Vec3A::new(0.0, -1.5, 0.0), 0.4, o, d)) {
            return Vec3::ZERO;
        }
        let ball = sphere_interval(Vec3A::new(0.9, -1.0, 1.5), 0.6, o, d);
        media.push((ball, Vec3::splat(3.0)));
        // Crossings: (t, the medium after it).
        let mut crossings = Vec::new();
        for (k, (interval, _)) in media.iter().enumerate() {
            if let Some((a, b)) = *interval {
                crossings.extend(
                    [(a, Some(k)), (b, None)]
                        .into_iter()
                        .filter(|x| on_way(x.0)),
                );
            }
        }
        crossings.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (mut depth, mut start) = (Vec3::ZERO, 0.0);
        let mut current = medium.map(|m| m as usize);
        for (t, after) in crossings.into_iter().chain([(dist, None)]) {
            if let Some(m) = current {
                depth += media[m].1 * (t - start);
            }
            (start, current) = (t, after);
        }
        (-depth).exp()
    }

    /// One search for all crossings gives the exact transmittance on random shadow
    /// rays from inside and outside the media, with cubes (as triangles in a BVH, or as
    /// boxes) and without (the analytic shapes alone). (One cast per crossing is off
    /// where a ray grazes a face:
    /// its next cast starts at a point moved off the ray along the normal, which shifts
    /// the following crossing by offset / |cos|.)
    #[test]
    fn crossings_in_one_traversal_give_the_exact_transmittance() {
        for (cubes, boxes) in [(true, false), (true, true), (false, false)] {
            let scene = scene_with(&format!("random_rays_{cubes}_{boxes}"), cubes, boxes);
            let n_media = scene.media.len();
            assert_eq!(n_media, if cubes { 3 } else { 1 });
            // The null sphere's index: after the cubes and the blocking sphere.
            let ball = if cubes { 4 } else { 1 };
            let mut rng = Pcg32::new(7, 3);
            let (mut blocked, mut multi, mut in_ball) = (0, 0, 0);
            let mut hits = CrossingList::new();
            for _ in 0..20_000 {
                let u = Vec3A::new(rng.next_1d(), rng.next_1d(), rng.next_1d());
                let o = Vec3A::new(-2.0, -2.0, -1.0) + u * Vec3A::new(4.0, 4.0, 3.0);
                let d = square_to_uniform_sphere(rng.next_2d());
                let dist = 5.0 * rng.next_1d();
                // Start in any medium or none (the rules are the same for every start).
                let k = (rng.next_1d() * (n_media + 1) as f32) as usize % (n_media + 1);
                let medium = (k < n_media).then_some(k as u32);
                let g = &scene.geometries;
                match scene
                    .accel
                    .crossings(g, &scene.shadow_pass, o, d, dist, &mut hits)
                {
                    Crossings::Blocked => blocked += 1,
                    Crossings::Found => {
                        multi += usize::from(hits.len() >= 2);
                        in_ball += usize::from(hits.iter().any(|h| h.shape == ball));
                    }
                    Crossings::Unsupported => panic!("unsupported without thin dielectrics"),
                }
                let tr = shadow_transmittance(&scene, o, d, dist, medium);
                let want = exact(o, d, dist, medium, cubes);
                assert!(
                    (tr - want).abs().max_element() <= 1e-4 * want.max_element() + 1e-6,
                    "o {o} d {d} dist {dist} medium {medium:?}: {tr} vs {want}"
                );
            }
            assert!(
                blocked > 300 && multi > 300 && in_ball > 500,
                "{blocked} blocked, {multi} with 2+ crossings, {in_ball} through the ball"
            );
        }
    }

    /// A ray through the diagonal shared by two triangles of a cube's face may hit both
    /// (it does here): the face is still crossed once.
    #[test]
    fn a_crossing_found_twice_on_a_shared_edge_counts_once() {
        // Cubes as triangles: a box is one primitive, met once.
        let scene = scene_with("shared_edge", true, false);
        let mut repeats = 0;
        // The first cube spans x in [-1.5, -0.5], y and z in [-0.5, 0.5]; σ_t = 2. Rays
        // along z through its faces z = ±0.5 on either diagonal, and the centre.
        for (x, y) in [(-0.8, 0.2), (-0.8, -0.2), (-1.0, 0.0)] {
            for dir in [1.0f32, -1.0] {
                let o = Vec3A::new(x, y, -2.0 * dir);
                let d = Vec3A::new(0.0, 0.0, dir);
                let mut hits = CrossingList::new();
                let g = &scene.geometries;
                let found = scene
                    .accel
                    .crossings(g, &scene.shadow_pass, o, d, 4.0, &mut hits);
                repeats += usize::from(found == Crossings::Found && hits.len() > 2);
                // From outside: 1 unit in the medium. Starting "in" it outside the cube
                // (the rules do not check): 1.5 units of it, then the cube's 1 unit,
                // then none after leaving it.
                for (medium, depth) in [(None, 1.0f32), (Some(0), 2.5)] {
                    let tr = shadow_transmittance(&scene, o, d, 4.0, medium);
                    let want = (-2.0 * depth).exp();
                    assert!(
                        (tr.x - want).abs() < 1e-3 * want,
                        "({x}, {y}) dir {dir} medium {medium:?}: {tr} vs {want}"
                    );
                }
            }
        }
        assert!(
            repeats > 0,
            "no ray hit a face twice: the case is not tested"
        );
    }

    /// An area emitter seen through a medium that only absorbs (albedo 0): a path
    /// either passes to it or dies at its collision, so the estimate of Mitsuba's
    /// estimator is L or 0 at random. Counted in expectation, every sample is the exact
    /// L e^{−σ_t t}.
    #[test]
    fn an_emitter_seen_through_a_medium_is_counted_in_expectation() {
        let xml = r#"<scene version="3.0.0">
            <medium type="homogeneous" id="fog">
                <float name="sigma_t" value="0.7"/><float name="albedo" value="0"/></medium>
            <sensor type="perspective"><ref id="fog"/><film type="hdrfilm">
                <integer name="width" value="4"/><integer name="height" value="4"/></film>
            </sensor>
            <shape type="sphere"><float name="radius" value="10"/><bsdf type="null"/>
                <ref name="interior" id="fog"/></shape>
            <shape type="sphere"><point name="center" x="0" y="0" z="3"/>
                <float name="radius" value="0.5"/>
                <emitter type="area"><rgb name="radiance" value="2, 3, 4"/></emitter></shape>
        </scene>"#;
        let scene = load_xml("emitter_in_fog", xml);
        assert!(scene.camera_medium.is_some());
        let albedo: Vec<Vec3> = scene.media.iter().map(|m| m.albedo).collect();
        let le = Vec3::new(2.0, 3.0, 4.0);
        let o = Vec3A::ZERO;
        for x in [0.0f32, 0.1, -0.15] {
            let d = Vec3A::new(x, 0.0, 1.0).normalize();
            // The near hit of o + t d with the sphere (c, 0.5): t = b − √(b² − |c|² + r²).
            let c = Vec3A::new(0.0, 0.0, 3.0);
            let b = d.dot(c);
            let t = b - (b * b - c.length_squared() + 0.25).sqrt();
            let want = le * (-0.7 * t).exp();
            for k in 0..200 {
                let mut rng = Pcg32::new(11, k);
                let settings = PathSettings {
                    albedo: &albedo,
                    gradient: Gradient::None,
                };
                let (l, _) = sample(&scene, &settings, o, d, f32::INFINITY, &mut rng);
                assert!(
                    (l - want).abs().max_element() <= 1e-4 * want.max_element(),
                    "direction {d}, sample {k}: {l} vs {want}"
                );
            }
        }
    }

    /// A medium that fills one convex shape with nothing else inside casts against that
    /// shape alone (`Scene::intersect_in_medium`, `geometry::convex`): from points inside,
    /// its hits are the scene's, and its clearance is the distance to the nearest face
    /// plane (found here from the mesh's own triangles) or to the sphere. Media filling
    /// two shapes, with another shape within reach, outside a shape, around the camera
    /// or in an open shape get no such shape.
    #[test]
    fn a_convex_medium_casts_against_its_shape_alone() {
        use crate::geometry::convex::ConvexBoundary;
        use crate::geometry::shape::Geometry;
        let scene_of = |name: &str, extra: &str, camera_medium: &str| {
            let xml = format!(
                r#"<scene version="3.0.0">
            <medium type="homogeneous" id="fog">
                <float name="sigma_t" value="2"/><float name="albedo" value="0.9"/></medium>
            <medium type="homogeneous" id="ball">
                <float name="sigma_t" value="3"/><float name="albedo" value="0.9"/></medium>
            <sensor type="perspective">{camera_medium}<film type="hdrfilm">
                <integer name="width" value="4"/><integer name="height" value="4"/></film>
            </sensor>
            <shape type="cube"><transform name="to_world">
                    <scale x="0.6" y="0.3" z="0.8"/><rotate x="1" y="1" angle="35"/>
                    <scale x="1.3" y="1" z="0.7"/><translate x="0.2" z="-0.1"/></transform>
                <bsdf type="null"/><ref name="interior" id="fog"/></shape>
            <shape type="sphere"><point name="center" x="3" y="0" z="0"/>
                <float name="radius" value="0.7"/>
                <bsdf type="dielectric"/><ref name="interior" id="ball"/></shape>
            <shape type="rectangle"><transform name="to_world"><scale value="5"/>
                <rotate x="1" angle="-90"/><translate y="-1.5"/></transform></shape>
            <shape type="sphere"><point name="center" x="0" y="2.5" z="0"/>
                <float name="radius" value="0.3"/>
                <emitter type="area"><rgb name="radiance" value="5, 5, 5"/></emitter></shape>
            {extra}
        </scene>"#
            );
            load_xml(&format!("convex_{name}"), &xml)
        };
        let scene = scene_of("box_and_ball", "", "");
        let mut rng = Pcg32::new(9, 3);
        for (mi, name) in [(0u32, "box"), (1, "ball")] {
            let b = scene.convex_media[mi as usize]
                .as_ref()
                .unwrap_or_else(|| panic!("{name}: no convex shape found"));
            let shape = b.shape();
            // A point inside and its exact distance to the surface.
            let inside = |rng: &mut Pcg32| match (b, &scene.geometries[shape as usize]) {
                (ConvexBoundary::Box { .. }, Geometry::Mesh(m)) => {
                    let to_world = m.cube_to_world.unwrap();
                    let l = (rng.next_2d().extend(rng.next_1d()) * 2.0 - glam::Vec3::ONE) * 0.98;
                    let p = Vec3A::from(to_world.transform_point3(l));
                    let planes = (0..m.triangles.len() as u32).map(|ti| {
                        let [a, b, c] = m.vertices(ti);
                        ((b - a).cross(c - a).normalize().dot(p - a)).abs()
                    });
                    (p, planes.fold(f32::INFINITY, f32::min))
                }
                (ConvexBoundary::Sphere(_), Geometry::Sphere(s)) => {
                    let p = s.center
                        + square_to_uniform_sphere(rng.next_2d())
                            * (0.98 * s.radius * rng.next_1d().cbrt());
                    (p, s.radius - (p - s.center).length())
                }
                _ => panic!("{name}: the convex shape is not the one filled"),
            };
            for _ in 0..2000 {
                let (p, distance) = inside(&mut rng);
                let clearance = b.clearance(&scene.geometries, p);
                assert!(
                    clearance <= distance && clearance >= 0.999 * distance - 1e-6,
                    "{name}: clearance {clearance} at {p}, distance {distance}"
                );
                let d = square_to_uniform_sphere(rng.next_2d());
                let full = scene.intersect(p, d, f32::INFINITY).unwrap();
                let own = scene
                    .intersect_in_medium(mi, p, d, f32::INFINITY)
                    .unwrap_or_else(|| panic!("{name}: no exit from {p} along {d}"));
                assert_eq!(
                    (own.shape, full.shape),
                    (shape, shape),
                    "{name}: {p} along {d}"
                );
                assert!(
                    (own.t - full.t).abs() <= 1e-5 * full.t.max(1.0) && own.t >= clearance,
                    "{name}: exit at {} against the scene's {}, clearance {clearance}",
                    own.t,
                    full.t
                );
                assert!((own.p - full.p).length() <= 1e-5 && own.n.dot(full.n) > 0.9999);
            }
        }
        let none = [
            (
                "two_shapes",
                r#"<shape type="sphere"><point name="center" x="0" y="0" z="3"/>
                    <float name="radius" value="0.2"/><bsdf type="null"/>
                    <ref name="interior" id="fog"/></shape>"#,
                "",
            ),
            (
                "bead_inside",
                r#"<shape type="sphere"><point name="center" x="0.2" y="0" z="-0.1"/>
                    <float name="radius" value="0.1"/></shape>"#,
                "",
            ),
            (
                "fog_outside_a_shape",
                r#"<shape type="sphere"><point name="center" x="0" y="0" z="3"/>
                    <float name="radius" value="0.2"/><bsdf type="null"/>
                    <ref name="exterior" id="fog"/></shape>"#,
                "",
            ),
            ("camera_in_fog", "", r#"<ref id="fog"/>"#),
        ];
        for (name, extra, camera) in none {
            let scene = scene_of(name, extra, camera);
            assert!(scene.convex_media[0].is_none(), "{name}: found convex");
            assert!(
                scene.convex_media[1].is_some(),
                "{name}: the ball is still convex"
            );
        }
        let open = load_xml(
            "convex_rectangle",
            r#"<scene version="3.0.0"><medium type="homogeneous" id="fog"/>
            <sensor type="perspective"><film type="hdrfilm">
                <integer name="width" value="4"/><integer name="height" value="4"/></film>
            </sensor>
            <shape type="rectangle"><bsdf type="null"/><ref name="interior" id="fog"/></shape>
            </scene>"#,
        );
        assert!(
            open.convex_media[0].is_none(),
            "an open rectangle found convex"
        );
    }

    /// A medium sealed in closed shapes that block shadow rays, with no emitter inside,
    /// skips emitter sampling (`Scene::emitters_unreachable`), and every emitter sample
    /// it skips would have been 0. Open, passing or partly passing boundaries, an
    /// emitter inside, or the medium outside some shape keep the sampling.
    #[test]
    fn a_sealed_medium_skips_only_emitter_samples_that_cannot_arrive() {
        let scene_of = |name: &str, boundary: &str, bsdf: &str, extra: &str| {
            let xml = format!(
                r#"<scene version="3.0.0">
            <medium type="homogeneous" id="juice">
                <float name="sigma_t" value="2"/><float name="albedo" value="0.9"/></medium>
            <sensor type="perspective"><film type="hdrfilm">
                <integer name="width" value="4"/><integer name="height" value="4"/></film>
            </sensor>
            <shape type="{boundary}"><bsdf type="{bsdf}"/><ref name="interior" id="juice"/></shape>
            <shape type="sphere"><point name="center" x="2" y="2" z="0"/>
                <float name="radius" value="0.3"/>
                <emitter type="area"><rgb name="radiance" value="5, 5, 5"/></emitter></shape>
            <emitter type="point"><point name="position" x="-2" y="1" z="1"/></emitter>
            <emitter type="directional"><vector name="direction" x="0" y="-1" z="0"/></emitter>
            <emitter type="constant"/>
            {extra}
        </scene>"#
            );
            load_xml(&format!("sealed_{name}"), &xml)
        };
        let sealed = [
            ("glass_ball", "sphere", "dielectric", ""),
            ("glass_cube", "cube", "dielectric", ""),
            ("diffuse_ball", "sphere", "diffuse", ""),
        ];
        for (name, boundary, bsdf, extra) in sealed {
            let mut scene = scene_of(name, boundary, bsdf, extra);
            assert!(scene.emitters_unreachable[0], "{name}: not found sealed");
            // What the skipped samples would have been: 0 at every point inside.
            scene.emitters_unreachable[0] = false;
            let m = &scene.media[0];
            let mut rng = Pcg32::new(5, 1);
            for _ in 0..2000 {
                let p = square_to_uniform_sphere(rng.next_2d()) * (0.95 * rng.next_1d().cbrt());
                let d_in = square_to_uniform_sphere(rng.next_2d());
                let x = medium_emitter_sample(&scene, m, Some(0), p, d_in, 0.0, &mut rng);
                assert_eq!(x, Vec3::ZERO, "{name}: an emitter sample from {p} arrived");
            }
        }
        let open = [
            ("null_ball", "sphere", "null", ""),
            ("thin_glass_ball", "sphere", "thindielectric", ""),
            ("rectangle", "rectangle", "dielectric", ""),
            (
                "point_light_inside",
                "sphere",
                "dielectric",
                r#"<emitter type="point"><point name="position" x="0.1" y="0" z="0"/></emitter>"#,
            ),
            (
                "area_light_inside",
                "sphere",
                "dielectric",
                r#"<shape type="sphere"><float name="radius" value="0.1"/>
                    <emitter type="area"/></shape>"#,
            ),
            (
                "juice_around_a_bead",
                "sphere",
                "dielectric",
                r#"<shape type="sphere"><float name="radius" value="0.1"/><bsdf type="null"/>
                    <ref name="exterior" id="juice"/></shape>"#,
            ),
        ];
        for (name, boundary, bsdf, extra) in open {
            let scene = scene_of(name, boundary, bsdf, extra);
            assert!(!scene.emitters_unreachable[0], "{name}: found sealed");
        }
    }
}
