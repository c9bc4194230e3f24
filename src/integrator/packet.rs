//! `volpath` on packets of paths in SIMD lanes: [`WIDTH`] camera paths advance together,
//! each path's state in one lane of `wide`'s `f32x8` registers (structure of arrays),
//! every branch taken by all lanes under a mask, as Mitsuba 3's LLVM backend runs its
//! wavefront. The scalar integrator (`volpath`) stays the reference: this one must
//! equal it in expectation, and the tests render the same scenes with both.
//!
//! It takes the scenes whose paths need little but lane arithmetic ([`PacketScene::new`]
//! lists them and says why a scene is refused): media in spheres and cubes behind
//! `null` or smooth `dielectric` boundaries (homogeneous ones, or one heterogeneous
//! medium, tracked by `medium::heterogeneous`), diffuse rectangles, disks, spheres and
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
//! Beside the radiance it estimates the derivatives volpath does (`volpath::Estimand`):
//! the albedo's (or the difference) in dβ, and one medium's extinction's and g's in
//! `derivatives`, each updated wherever β is, and only where the render asks for it: a
//! render that asks for none runs the paths' instance without them (`PacketPaths<false>`),
//! which carries no derivative weight at all.
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
//! * Henyey–Greenstein sampling is `medium::phase`'s kernel in f32 where the scalar
//!   path runs it in f64 (the packet takes |g| ≤ [`MAX_ABS_G`] only).
//!
//! The physics is not written here: every kernel (phase, Fresnel, the smooth
//! dielectric's sample, MIS, roulette, the hero channel's weights, cosine and cone
//! sampling, the emitters' directions, the spawn offset, flights, transmittance, tracking
//! steps) is the scalar path's, written once over `simd::Float` and run in lanes
//! (`kernel_tests` holds each lane to the scalar result).

mod boundary;
mod derivatives;
mod emitters;
mod lanes;
mod paths;
mod scene;
mod shapes;

use glam::{Vec3, Vec3A};
use wide::CmpEq;

use super::emitters::emission_met;
use super::sample::PathSample;
use super::volpath::PathSettings;
use crate::sampling::Pcg32;
use crate::scene::Scene;
pub use lanes::WIDTH;
use lanes::{lanes_of, mask_of, L, V3};
use paths::PacketPaths;
pub use scene::{PacketScene, MAX_ABS_G};
use shapes::{medium_normal, surface_normal};

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
    /// The lanes in the medium whose extinction, and whose (Henyey–Greenstein) g, is
    /// differentiated (`Estimand::extinction_medium`, `g_medium`).
    chosen_sigma: L,
    chosen_g: L,
}

/// The samples of the camera rays `(o, d, tmax)` (at most [`WIDTH`], `d` unit), each
/// with its own random stream, into `out`: volpath's `sample` for each, in lanes, one
/// vertex of every path a step ([`PacketPaths`]).
pub fn sample_packet(
    scene: &Scene,
    ps: &PacketScene,
    settings: &PathSettings,
    rays: &[(Vec3A, Vec3A, f32)],
    rngs: &mut [Pcg32],
    out: &mut [PathSample],
) {
    // A plain render runs the instance without derivatives (`PacketPaths`).
    match settings.estimand.has_derivatives() {
        true => sample_packet_in::<true>(scene, ps, settings, rays, rngs, out),
        false => sample_packet_in::<false>(scene, ps, settings, rays, rngs, out),
    }
}

/// [`sample_packet`] in the instance with derivative weights (`D`) or without.
fn sample_packet_in<const D: bool>(
    scene: &Scene,
    ps: &PacketScene,
    settings: &PathSettings,
    rays: &[(Vec3A, Vec3A, f32)],
    rngs: &mut [Pcg32],
    out: &mut [PathSample],
) {
    let n = rays.len();
    assert!(n <= WIDTH && rngs.len() == n && out.len() == n);
    let paths = PacketPaths::<D>::new(ps, settings, rays, rngs);
    paths.run((scene, ps), settings, rngs, out);
}

/// The emission the lanes of `mask` see on the surfaces `surface` they met at
/// `(p, n)` along `d`, weighted as volpath weighs it (`emitters::emission_met`): in
/// full at depth 0 (none where emitters are hidden) and after delta vertices only
/// (`specular`), else by MIS against emitter sampling from the last vertex
/// `(last_p, last_pdf)`. Per lane by the scalar code: an emitter is met rarely.
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
        let view = (p.lane_a(k), n.lane_a(k), d.lane_a(k));
        let full = depth[k] == 0.0 || specular >> k & 1 == 1;
        le[k] = emission_met(scene, ei, view, (last_p.lane_a(k), last_pdf[k]), full);
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
    settings: &PathSettings,
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
    let factors: [(Vec3, Vec3); WIDTH] = std::array::from_fn(|k| {
        let m = medium[k];
        settings
            .estimand
            .vertex_factors(m as u32, settings.albedo[m])
    });
    let (extinction, g) = (
        settings.estimand.extinction_medium(),
        settings.estimand.g_medium(),
    );
    MediumLanes {
        sigma_hero: hero_of(sigma),
        sigma,
        albedo: V3::from_fn(|k| settings.albedo[medium[k]]),
        a: V3::from_fn(|k| factors[k].0),
        b: V3::from_fn(|k| factors[k].1),
        g: L::from(std::array::from_fn::<f32, WIDTH, _>(|k| {
            ps.media[medium[k]].g
        })),
        chosen_sigma: mask_of(|k| bits >> k & 1 == 1 && extinction == Some(medium[k] as u32)),
        chosen_g: mask_of(|k| {
            bits >> k & 1 == 1 && g == Some(medium[k] as u32) && ps.media[medium[k]].hg
        }),
    }
}

#[cfg(test)]
mod kernel_tests;
#[cfg(test)]
mod plain_tests;
#[cfg(test)]
mod test_scenes;
#[cfg(test)]
mod tests;
