//! `volpath` on packets of paths in SIMD lanes: [`WIDTH`] camera paths advance together,
//! each path's state in one lane of `wide`'s `f32x8` registers (structure of arrays),
//! every branch taken by all lanes under a mask, as Mitsuba 3's LLVM backend runs its
//! wavefront. The scalar integrator (`volpath`) stays the reference: this one must
//! equal it in expectation, and the tests render the same scenes with both.
//!
//! It takes the scenes whose paths need little but lane arithmetic ([`PacketScene::new`]
//! lists them and says why a scene is refused): media in spheres and cubes behind
//! `null` or smooth `dielectric` boundaries (homogeneous ones, or one heterogeneous
//! medium, tracked in `heterogeneous`), diffuse rectangles, disks, spheres and
//! cubes in a medium or in empty space, the camera in either, lit by area emitters on
//! those surfaces, point, spot and directional emitters and a `constant` sky. A vertex
//! is then a free flight, the tests of a few shapes, an emitter sample and a phase,
//! BSDF or boundary sample. All of it runs in lanes (a single light by its own lane
//! sampler: point, directional, rectangle, or a sphere by its visible cone) but the
//! emitter's choice and direction where the scene has several emitters or another
//! shape of light (`emitter::selection`, `Emitter::sample_direction`) and the emission
//! of an emitter a path meets, which are called per lane, as the scalar path calls
//! them; the shadow rays' tests and transmittances are in lanes again. A constant sky
//! is left to BSDF and phase sampling under volpath, so a path that escapes sees it
//! with weight 1.
//!
//! The estimator is the scalar one's, step for step, with the random draws in the
//! scalar path's order (the hero channel; per vertex the roulette, the distance, the
//! emitter sample, the phase or BSDF sample), so each lane's first draws come from its
//! pixel's stratified sequences as the scalar path's do. Where it differs, the
//! expectation is the same:
//! * shadow rays are not rouletted by the clearance (their transmittance is exact
//!   either way, and in lanes cheaper than the roulette's bookkeeping);
//! * a shape's exit is its far side and its entry the near one (a sphere's roots in
//!   the forms without cancellation, a box's slabs), and the surface a path leaves is
//!   skipped instead of offsetting the ray (the side a path is on is its state);
//! * Henyey–Greenstein sampling is `medium::phase`'s by the distance from the peak, in
//!   f32 (the packet takes |g| ≤ [`MAX_ABS_G`] only); Lambert's cosine law by the
//!   polar map instead of the concentric one.

mod boundary;
mod emitters;
mod heterogeneous;
mod lanes;
mod scatter;
mod scene;
mod shapes;

use glam::{Vec3, Vec3A};
use wide::{CmpEq, CmpGe, CmpGt, CmpLt};

use super::roulette::continue_probability;
use super::sample::PathSample;
use crate::geometry::RAY_EPSILON;
use crate::medium::phase::hg_eval;
use crate::medium::{
    collision_weight, expected_pass_weight, pass_weight, sample_distance, transmittance_rgb,
};
use crate::sampling::{mis_weight, Pcg32};
use crate::scene::Scene;
use boundary::boundary_sample;
use emitters::sample_emitters;
pub use lanes::WIDTH;
use lanes::{draw_1d, draw_2d, lanes_of, mask_of, L, V3};
pub use scene::{PacketScene, PacketSettings, MAX_ABS_G};
use shapes::{medium_normal, shadow_transmittance, surface_hit, surface_normal, MediumSpan};

/// Consecutive null-boundary crossings after which a path ends (volpath's limit).
const MAX_NULL_CROSSINGS: f32 = 65536.0;

/// A medium's values in the lanes of the paths in it.
struct MediumLanes {
    sigma: V3,
    /// σ_t of each path's hero channel.
    sigma_hero: L,
    albedo: V3,
    a: V3,
    b: V3,
    g: L,
}

/// The samples of the camera rays `(o, d, tmax)` (at most [`WIDTH`], `d` unit), each
/// with its own random stream, into `out`: volpath's `sample` for each, in lanes.
pub fn sample_packet(
    scene: &Scene,
    ps: &PacketScene,
    settings: &PacketSettings,
    rays: &[(Vec3A, Vec3A, f32)],
    rngs: &mut [Pcg32],
    out: &mut [PathSample],
) {
    let n = rays.len();
    assert!(n <= WIDTH && rngs.len() == n && out.len() == n);
    let inf = L::splat(f32::INFINITY);
    let none = L::splat(-1.0);
    let ray = |k: usize| rays.get(k).copied().unwrap_or((Vec3A::ZERO, Vec3A::Z, 0.0));
    let mut o = V3::from_fn(|k| Vec3::from(ray(k).0));
    let mut d = V3::from_fn(|k| Vec3::from(ray(k).1));
    let mut tmax = L::from(std::array::from_fn::<f32, WIDTH, _>(|k| ray(k).2));
    let mut alive = mask_of(|k| k < n);
    let mut beta = V3::splat(Vec3::ONE);
    let mut d_beta = V3::splat(Vec3::ZERO);
    let mut r_u = V3::splat(Vec3::ONE);
    let mut result = V3::splat(Vec3::ZERO);
    let mut d_result = V3::splat(Vec3::ZERO);
    let mut depth = L::ZERO;
    // The medium shape each path is in, and the surface it is on (as f32; −1: none).
    let mut inside = ps.camera_shape.map_or(none, |i| L::splat(i as f32));
    let mut on_surface = none;
    // Null-boundary crossings since the last vertex (volpath's MAX_NULL_CROSSINGS: a
    // ray caught at a grazing exit would otherwise cross forever).
    let mut crossings = L::ZERO;
    // Where each path last scattered and the pdf of the direction it took there (for
    // the MIS weight of an area emitter it meets), and the emission its camera ray
    // meets first (`PathSample::seen_emission`).
    let mut last_p = o;
    let mut last_pdf = L::ONE;
    // Since the last vertex that samples emitters, only delta (dielectric) vertices:
    // an emitter met then counts in full (volpath's `specular_chain`).
    let mut specular = L::ZERO;
    // The product of the refractions' relative indices (for the roulette, η²).
    let mut eta = L::ONE;
    let mut seen_emission = V3::splat(Vec3::ZERO);
    let mut valid = if !ps.hide_emitters && ps.has_environment {
        alive
    } else {
        L::ZERO
    };
    // The hero channel, drawn first as the scalar path draws it.
    let mut hero = [0usize; WIDTH];
    for (k, h) in hero.iter_mut().enumerate().take(n) {
        *h = ((rngs[k].next_1d() * 3.0) as usize).min(2);
    }
    let hero_x = mask_of(|k| hero[k] == 0);
    let hero_y = mask_of(|k| hero[k] == 1);
    let hero_of = |v: V3| hero_x.blend(v.x, hero_y.blend(v.y, v.z));
    let max_depth = L::splat(ps.max_depth as f32);
    let rr_depth = L::splat(ps.rr_depth as f32);
    let sky = V3::splat(ps.environment);
    // The scene's one medium where it is heterogeneous (`PacketScene::new` takes no
    // other with it).
    let het = scene.media.first().and_then(|m| m.heterogeneous.as_deref());
    let single_medium = (ps.media.len() == 1).then(|| {
        let m = &ps.media[0];
        MediumLanes {
            sigma: V3::splat(m.sigma_t),
            sigma_hero: hero_of(V3::splat(m.sigma_t)),
            albedo: V3::splat(settings.albedo[0]),
            a: V3::splat(settings.factor_a[0]),
            b: V3::splat(settings.factor_b[0]),
            g: L::splat(m.g),
        }
    });

    loop {
        // ---- Termination: zero weight, depth, Russian roulette ----
        alive &= !(beta.is_zero() & d_beta.is_zero());
        alive &= depth.cmp_lt(max_depth);
        if alive.none() {
            break;
        }
        let played = alive & depth.cmp_gt(rr_depth);
        if played.any() {
            let u = draw_1d(played, rngs);
            let weight = if settings.roulette_by_target {
                beta.add(d_beta)
            } else {
                beta
            };
            let q = continue_probability(weight, d_beta, eta);
            // A NaN q fails u < q: the path ends, as the scalar one does.
            let ended = played & !u.cmp_lt(q);
            alive &= !ended;
            let go_on = played & alive;
            beta = beta.select(go_on, beta.div(q));
            d_beta = d_beta.select(go_on, d_beta.div(q));
        }

        // ---- Where each ray ends: its medium's far side, or the nearest shape ----
        let in_medium = alive & inside.cmp_ge(L::ZERO);
        let in_space = alive & !in_medium;
        let mut t_end = inf;
        let mut entered = none;
        let mut hit_surface = none;
        for (i, m) in ps.media_shapes.iter().enumerate() {
            let span = MediumSpan::new(&m.kind, o, d);
            let index = L::splat(i as f32);
            t_end = (in_medium & inside.cmp_eq(index)).blend(span.exit, t_end);
            let enters = in_space & span.enters & span.near.cmp_lt(t_end) & span.near.cmp_lt(tmax);
            t_end = enters.blend(span.near, t_end);
            entered = enters.blend(index, entered);
        }
        // The surfaces in the medium (or empty space) each path is in.
        for (k, surface) in ps.surfaces.iter().enumerate() {
            let here = alive & inside.cmp_eq(L::splat(surface.container));
            if here.none() {
                continue;
            }
            let (hit, t) = surface_hit(ps, k, o, d, on_surface);
            let hit = here & hit & t.cmp_lt(t_end) & t.cmp_lt(tmax);
            t_end = hit.blend(t, t_end);
            hit_surface = hit.blend(L::splat(k as f32), hit_surface);
            entered = hit.blend(none, entered);
        }
        let meets_surface = hit_surface.cmp_ge(L::ZERO);

        // ---- Free flight in the medium ----
        // The flights that reach the surface ahead of them, and those whose emitter
        // there was counted in expectation.
        let mut reached = L::ZERO;
        let mut counted = L::ZERO;
        let mut leaves_to_boundary = L::ZERO;
        if in_medium.any() {
            let gathered;
            let m = match &single_medium {
                Some(m) => m,
                None => {
                    gathered = gather_media(ps, settings, inside, in_medium, &hero_of);
                    &gathered
                }
            };
            if ps.area_emitters && het.is_none() {
                // ---- An area emitter ahead, counted in expectation ----
                // The flight passes to it with probability T_hero and then weighs its
                // emission by β T / mean(r T): count β T (T_hero / mean(r T)) L_e now,
                // and not again if the flight does pass (volpath's module comment).
                let ahead = in_medium & emitting(ps, hit_surface);
                if ahead.any() {
                    let p_hit = o.add(d.scale(t_end));
                    let (n, _) = surface_lanes(ps, hit_surface, p_hit, ahead);
                    let view = (p_hit, n, d);
                    let le = surface_emission(
                        scene,
                        ps,
                        hit_surface,
                        ahead,
                        view,
                        (depth, specular),
                        (last_p, last_pdf),
                    );
                    let tr = transmittance_rgb(m.sigma, t_end);
                    let pass = expected_pass_weight(tr, hero_of(tr), r_u);
                    let x = pass.mul(le);
                    let finite = ahead & x.is_finite();
                    result = result.select(finite, result.add(beta.mul(x)));
                    d_result = d_result.select(finite, d_result.add(d_beta.mul(x)));
                    counted = ahead & !le.is_zero();
                }
            }
            // The flights' ends and the albedo volume's value at collisions (1 in a
            // homogeneous medium).
            let (collided, flight, volume_albedo) = match het {
                Some(h) => {
                    // Delta tracking; the majorant is grey, so r is unchanged.
                    let f = heterogeneous::sample_flight(h, o, d, t_end, in_medium, rngs);
                    beta = beta.select(in_medium, beta.mul(f.weight));
                    d_beta = d_beta.select(in_medium, d_beta.mul(f.weight));
                    (in_medium & f.collided, f.t, f.albedo)
                }
                None => {
                    let u = draw_1d(in_medium, rngs);
                    let flight = sample_distance(m.sigma_hero, u);
                    let collided = in_medium & flight.cmp_lt(t_end);
                    if !ps.grey {
                        // Collision at t: f = T σ_t α, p_c = σ_t,c T_c; passing to the
                        // end: f = T, p_c = T_c (volpath's chromatic weights).
                        let t = collided.blend(flight, t_end);
                        let tr = transmittance_rgb(m.sigma, t);
                        let tr_hero = hero_of(tr);
                        let w_collided = collision_weight(tr, m.sigma, m.sigma_hero, tr_hero);
                        let w_passed = pass_weight(tr, tr_hero);
                        let w = w_passed.select(collided, w_collided);
                        beta = beta.select(in_medium, beta.mul(w));
                        d_beta = d_beta.select(in_medium, d_beta.mul(w));
                        r_u = r_u.select(in_medium, r_u.mul(w));
                    }
                    (collided, flight, V3::splat(Vec3::ONE))
                }
            };
            let passed = in_medium & !collided;
            // dβ without this vertex's own α (for the power tests' wrong variant only).
            let mut d_beta_before = d_beta.mul(m.albedo).mul(volume_albedo);
            // d(β α)/dα: dβ a + β b at a vertex (Gradient::vertex_factors), α the
            // render's factor times the volume's value.
            let d_beta_vertex = d_beta.mul(m.a).add(beta.mul(m.b)).mul(volume_albedo);
            d_beta = d_beta.select(collided, d_beta_vertex);
            beta = beta.select(collided, beta.mul(m.albedo.mul(volume_albedo)));
            if !ps.grey && het.is_none() {
                // Keep mean(r) = 1 (volpath's rescaling).
                let k = in_medium.blend(r_u.mean(), L::ONE);
                beta = beta.div(k);
                d_beta = d_beta.div(k);
                d_beta_before = d_beta_before.div(k);
                r_u = r_u.div(k);
            }
            alive &= !in_medium | (beta.is_finite() & r_u.is_finite() & d_beta.is_finite());
            let collided = collided & alive;
            depth = collided.blend(depth + L::ONE, depth);
            valid |= collided;
            alive &= !(collided & depth.cmp_ge(max_depth));
            let collided = collided & alive;
            specular = collided.blend(L::ZERO, specular);
            if collided.any() {
                let p = o.add(d.scale(flight));
                // ---- Emitter sampling from the medium vertex ----
                // (None from inside a dielectric: no shadow ray leaves it.)
                let nee = collided & !dielectric_of(ps, inside);
                if ps.samples_emitters && nee.any() {
                    let es = sample_emitters(scene, ps, p, nee, rngs);
                    if es.some.any() {
                        let phase = hg_eval(m.g, d.dot(es.d));
                        let ray = (p, es.d, es.dist);
                        let tr = shadow_transmittance(scene, ps, ray, inside, none, es.some, rngs);
                        let x = es.value.mul(tr).scale(phase * es.weight(phase));
                        let weight_of_x = if settings.nee_ignores_vertex {
                            d_beta_before
                        } else {
                            d_beta
                        };
                        result = result.select(es.some, result.add(beta.mul(x)));
                        d_result = d_result.select(es.some, d_result.add(weight_of_x.mul(x)));
                    }
                }
                // ---- Phase function sampling ----
                let (u1, u2) = draw_2d(collided, rngs);
                let wo = scatter::sample_hg(d, m.g, u1, u2);
                if ps.area_emitters {
                    last_p = last_p.select(collided, p);
                    last_pdf = collided.blend(hg_eval(m.g, d.dot(wo)), last_pdf);
                }
                o = o.select(collided, p);
                d = d.select(collided, wo);
            }
            crossings = collided.blend(L::ZERO, crossings);
            // On to a surface in the medium, or through the null boundary into empty
            // space.
            let passed = passed & alive;
            o = o.select(passed, o.add(d.scale(t_end)));
            reached = passed & meets_surface;
            let leaves = passed & !meets_surface;
            // (At a dielectric boundary the path stays in until the boundary's sample
            // below says otherwise.)
            leaves_to_boundary = leaves & dielectric_of(ps, inside);
            let leaves = leaves & !leaves_to_boundary;
            inside = leaves.blend(none, inside);
            crossings = leaves.blend(crossings + L::ONE, crossings);
        }

        // ---- In empty space: into a medium, onto a surface, or out to the sky ----
        let meets_medium = in_space & entered.cmp_ge(L::ZERO);
        let lands = in_space & meets_surface;
        o = o.select(meets_medium | lands, o.add(d.scale(t_end)));
        let meets_boundary = meets_medium & dielectric_of(ps, entered);
        let enters = meets_medium & !meets_boundary;
        // Paths on a surface: from empty space, or from a flight that reached it.
        let at_surface = alive & (lands | reached);
        if enters.any() {
            // The scalar path (as Mitsuba's) starts inside a medium it enters off the
            // boundary by the spawn offset (`geometry::offset_point`); in a medium whose
            // mean free path is that short the offset shows, so the packet takes it too.
            let n = medium_normals(ps, entered, o, enters);
            o = o.select(enters, o.sub(n.scale(offset_magnitude(ps, o))));
        }
        inside = enters.blend(entered, inside);
        crossings = enters.blend(crossings + L::ONE, crossings);
        alive &= !crossings.cmp_gt(L::splat(MAX_NULL_CROSSINGS));
        on_surface = in_medium.blend(none, on_surface);
        on_surface = meets_medium.blend(none, on_surface);
        let at_boundary = alive & (meets_boundary | leaves_to_boundary);
        if at_boundary.any() {
            // ---- A dielectric boundary: reflect or refract (`bsdf::Dielectric`) ----
            let shape = leaves_to_boundary.blend(inside, entered);
            let b = boundary_sample(ps, shape, at_boundary, (o, d), rngs);
            valid |= at_boundary;
            let ok = at_boundary & b.pdf.cmp_gt(L::ZERO);
            alive &= !(at_boundary & !ok);
            beta = beta.select(ok, beta.mul(b.weight));
            d_beta = d_beta.select(ok, d_beta.mul(b.weight));
            eta = ok.blend(eta * b.eta, eta);
            depth = ok.blend(depth + L::ONE, depth);
            crossings = ok.blend(L::ZERO, crossings);
            specular |= ok;
            last_p = last_p.select(ok, o);
            last_pdf = ok.blend(b.pdf, last_pdf);
            // Into the medium or out of it, by the side the new direction points to,
            // off the boundary by the spawn offset (`geometry::offset_point`).
            let into = b.wo.dot(b.n).cmp_lt(L::ZERO);
            inside = ok.blend(into.blend(shape, none), inside);
            let offset = offset_magnitude(ps, o);
            let offset = into.blend(-offset, offset);
            o = o.select(ok, o.add(b.n.scale(offset)));
            d = d.select(ok, b.wo);
        }
        let escapes = in_space & !meets_medium & !lands;
        if escapes.any() {
            let seen = if ps.hide_emitters {
                escapes & depth.cmp_gt(L::ZERO)
            } else {
                escapes
            };
            result = result.select(seen, result.add(beta.mul(sky)));
            d_result = d_result.select(seen, d_result.add(d_beta.mul(sky)));
            alive &= !escapes;
        }
        if at_surface.any() {
            // ---- A diffuse surface: emitter sampling, then Lambert's law ----
            // (Front side only: from behind, the BSDF's sample fails and the path
            // ends, as a failed sample ends the scalar one; it counts as met.)
            valid |= at_surface;
            let (n, rho) = surface_lanes(ps, hit_surface, o, at_surface);
            if ps.area_emitters {
                // ---- An area emitter's surface: its emission, MIS-weighted ----
                let seen = surface_emission(
                    scene,
                    ps,
                    hit_surface,
                    at_surface & !counted,
                    (o, n, d),
                    (depth, specular),
                    (last_p, last_pdf),
                );
                result = result.add(beta.mul(seen));
                d_result = d_result.add(d_beta.mul(seen));
                let first = at_surface
                    & depth.cmp_eq(L::ZERO)
                    & crossings.cmp_eq(L::ZERO)
                    & inside.cmp_lt(L::ZERO);
                seen_emission = seen_emission.select(first, seen);
            }
            let cos_in = -d.dot(n);
            let front = at_surface & cos_in.cmp_gt(L::ZERO);
            let nee = at_surface & (depth + L::ONE).cmp_lt(max_depth);
            if ps.samples_emitters && nee.any() {
                let es = sample_emitters(scene, ps, o, nee, rngs);
                let cos_out = es.d.dot(n);
                let lit = es.some & front & cos_out.cmp_gt(L::ZERO);
                if lit.any() {
                    let ray = (o, es.d, es.dist);
                    let tr = shadow_transmittance(scene, ps, ray, inside, hit_surface, lit, rngs);
                    let pdf = cos_out * L::splat(std::f32::consts::FRAC_1_PI);
                    let f = rho.scale(pdf * es.weight(pdf));
                    let x = f.mul(es.value).mul(tr);
                    result = result.select(lit, result.add(beta.mul(x)));
                    d_result = d_result.select(lit, d_result.add(d_beta.mul(x)));
                }
            }
            // The scalar path draws the BSDF's 1-D sample (the lobe's choice) before
            // the 2-D one; drawn here too, unused, to keep the draws in step.
            let _ = draw_1d(at_surface, rngs);
            let (u1, u2) = draw_2d(at_surface, rngs);
            let wo = scatter::sample_cosine(n, u1, u2);
            if ps.area_emitters {
                last_p = last_p.select(front, o);
                last_pdf = front.blend(wo.dot(n) * L::splat(std::f32::consts::FRAC_1_PI), last_pdf);
            }
            // Weight f cos / pdf = ρ.
            beta = beta.select(front, beta.mul(rho));
            d_beta = d_beta.select(front, d_beta.mul(rho));
            depth = front.blend(depth + L::ONE, depth);
            crossings = at_surface.blend(L::ZERO, crossings);
            specular = at_surface.blend(L::ZERO, specular);
            d = d.select(front, wo);
            on_surface = at_surface.blend(hit_surface, on_surface);
            alive &= !(at_surface & !front);
        }
        tmax = inf;
    }

    let valid = valid.move_mask();
    for (k, s) in out.iter_mut().enumerate() {
        *s = PathSample {
            radiance: result.lane(k),
            second: d_result.lane(k),
            seen_emission: seen_emission.lane(k),
            valid: valid >> k & 1 == 1,
        };
    }
}

/// The emission the lanes of `mask` see on the surfaces `surface` they met at
/// `(p, n)` along `d`, weighted as volpath's `emission_seen` weighs it: in full at
/// depth 0 (none where emitters are hidden) and after delta vertices only (`specular`),
/// else by MIS against emitter sampling from
/// the last vertex `(last_p, last_pdf)`. Per lane by the scalar code: an emitter is
/// met rarely.
fn surface_emission(
    scene: &Scene,
    ps: &PacketScene,
    surface: L,
    mask: L,
    (p, n, d): (V3, V3, V3),
    (depth, specular): (L, L),
    (last_p, last_pdf): (V3, L),
) -> V3 {
    let surface = surface.to_array();
    let (depth, last_pdf) = (depth.to_array(), last_pdf.to_array());
    let specular = specular.move_mask();
    let mut le = [Vec3::ZERO; WIDTH];
    for k in lanes_of(mask.move_mask()) {
        let Some(ei) = ps.surfaces[surface[k] as usize].emitter else {
            continue;
        };
        if depth[k] == 0.0 && ps.hide_emitters {
            continue;
        }
        let e = &scene.emitters[ei as usize];
        let (pk, nk, dk) = (p.lane_a(k), n.lane_a(k), d.lane_a(k));
        le[k] = if depth[k] == 0.0 || specular >> k & 1 == 1 {
            e.eval(nk, dk)
        } else {
            let from = last_p.lane_a(k);
            let (l, pdf) = e.eval_and_pdf(from, pk, nk, dk, &scene.geometries);
            let em_pdf = pdf * scene.emitter_selection.pdf(from, ei as usize);
            l * mis_weight(last_pdf[k], em_pdf)
        };
    }
    V3::from_fn(|k| le[k])
}

/// The outward normals of the medium shapes `shape` (indices as f32) the lanes of
/// `mask` are on at `p` (elsewhere 0).
fn medium_normals(ps: &PacketScene, shape: L, p: V3, mask: L) -> V3 {
    let mut n = V3::splat(Vec3::ZERO);
    for (i, m) in ps.media_shapes.iter().enumerate() {
        let here = mask & shape.cmp_eq(L::splat(i as f32));
        if here.any() {
            n = n.select(here, medium_normal(&m.kind, p));
        }
    }
    n
}

/// How far a ray spawned at `p` starts off its surface: `geometry::offset_magnitude`
/// in lanes, `(scale + max|p_i|) · RayEpsilon`.
#[inline(always)]
fn offset_magnitude(ps: &PacketScene, p: V3) -> L {
    (L::splat(ps.offset_scale) + p.abs().max_element()) * L::splat(RAY_EPSILON)
}

/// The lanes whose medium `shape` (indices as f32) has a dielectric boundary.
fn dielectric_of(ps: &PacketScene, shape: L) -> L {
    let mut mask = L::ZERO;
    if ps.dielectrics {
        for (i, m) in ps.media_shapes.iter().enumerate() {
            if m.dielectric.is_some() {
                mask |= shape.cmp_eq(L::splat(i as f32));
            }
        }
    }
    mask
}

/// The lanes whose `surface` (indices as f32) is an area emitter's.
fn emitting(ps: &PacketScene, surface: L) -> L {
    let mut mask = L::ZERO;
    for (k, s) in ps.surfaces.iter().enumerate() {
        if s.emitter.is_some() {
            mask |= surface.cmp_eq(L::splat(k as f32));
        }
    }
    mask
}

/// The normal and reflectance of the surfaces `surface` (indices as f32) the lanes of
/// `mask` are on at `p`.
fn surface_lanes(ps: &PacketScene, surface: L, p: V3, mask: L) -> (V3, V3) {
    let mut n = V3::splat(Vec3::Z);
    let mut rho = V3::splat(Vec3::ZERO);
    for k in 0..ps.surfaces.len() {
        let here = mask & surface.cmp_eq(L::splat(k as f32));
        if here.any() {
            n = n.select(here, surface_normal(ps, k, p));
            rho = rho.select(here, V3::splat(ps.surfaces[k].reflectance));
        }
    }
    (n, rho)
}

/// The values of the media the paths of `mask` are in (lanes elsewhere: the first
/// medium's, unused).
fn gather_media(
    ps: &PacketScene,
    settings: &PacketSettings,
    inside: L,
    mask: L,
    hero_of: &impl Fn(V3) -> L,
) -> MediumLanes {
    let shapes = inside.to_array();
    let bits = mask.move_mask();
    let medium: [usize; WIDTH] = std::array::from_fn(|k| {
        if bits >> k & 1 == 1 {
            ps.media_shapes[shapes[k] as usize].medium as usize
        } else {
            0
        }
    });
    let sigma = V3::from_fn(|k| ps.media[medium[k]].sigma_t);
    MediumLanes {
        sigma_hero: hero_of(sigma),
        sigma,
        albedo: V3::from_fn(|k| settings.albedo[medium[k]]),
        a: V3::from_fn(|k| settings.factor_a[medium[k]]),
        b: V3::from_fn(|k| settings.factor_b[medium[k]]),
        g: L::from(std::array::from_fn::<f32, WIDTH, _>(|k| {
            ps.media[medium[k]].g
        })),
    }
}

#[cfg(test)]
mod kernel_tests;
#[cfg(test)]
mod tests;
