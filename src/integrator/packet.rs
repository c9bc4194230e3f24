//! `volpath` on packets of paths in SIMD lanes: [`WIDTH`] camera paths advance together,
//! each path's state in one lane of `wide`'s `f32x8` registers (structure of arrays),
//! every branch taken by all lanes under a mask, as Mitsuba 3's LLVM backend runs its
//! wavefront. The scalar integrator (`volpath`) stays the reference: this one must
//! equal it in expectation, and the tests render the same scenes with both.
//!
//! It takes the scenes whose paths need nothing but lane arithmetic (see
//! [`PacketScene::new`] for the list and the reason a scene is refused): media in
//! `null`-bounded spheres in empty space under a `constant` sky, the white furnace and
//! its kin. There every vertex is a free flight, a sphere test and a phase sample,
//! the parts that dominate a homogeneous medium's profile, and no emitter is sampled
//! (under `volpath` a constant sky is left to phase sampling: `emitter::selection`), so
//! the MIS weight of the sky is 1.
//!
//! The estimator is the scalar one's, step for step, including the order of the random
//! draws (the hero channel, then per vertex the roulette, the distance, the phase
//! sample), so each lane's first draws come from its pixel's stratified sequences as
//! the scalar path's do:
//! * free flight with the hero channel's σ_t, weighted by the channel-averaged pdf
//!   (`β / mean(r)`, volpath's module comment); grey media skip the transmittances;
//! * the exit of the sphere a path is in is its far root, the entry of a sphere from
//!   empty space the near one, each in the cancellation-free form of the quadratic's
//!   roots (no spawn offsets: the side a path is on is its state, not a guess from
//!   the geometry);
//! * Henyey–Greenstein sampling by the distance from the peak, as `medium::phase`
//!   does (in f32 here: the packet takes |g| ≤ [`MAX_ABS_G`] only).

use glam::{Vec3, Vec3A};
use wide::{f32x8, CmpEq, CmpGe, CmpGt, CmpLe, CmpLt};

use super::sample::PathSample;
use super::volpath::{Gradient, PathSettings};
use crate::bsdf::Bsdf;
use crate::emitter::Emitter;
use crate::geometry::shape::Geometry;
use crate::medium::Phase;
use crate::sampling::Pcg32;
use crate::scene::{IntegratorKind, Scene};

/// Paths in a packet.
pub const WIDTH: usize = 8;

/// The largest |g| of a Henyey–Greenstein medium the packet takes: its sampling is in
/// f32, which resolves the peak (width ~(1 − |g|)² in 1 − cos θ) well below this.
pub const MAX_ABS_G: f32 = 0.95;

type L = f32x8;

/// Three lanes registers: a vector (or an RGB value) per path.
#[derive(Clone, Copy)]
struct V3 {
    x: L,
    y: L,
    z: L,
}

impl V3 {
    #[inline(always)]
    fn splat(v: Vec3) -> V3 {
        V3 {
            x: L::splat(v.x),
            y: L::splat(v.y),
            z: L::splat(v.z),
        }
    }

    #[inline(always)]
    fn from_lanes(v: &[Vec3A; WIDTH]) -> V3 {
        V3 {
            x: L::from(std::array::from_fn::<f32, WIDTH, _>(|k| v[k].x)),
            y: L::from(std::array::from_fn::<f32, WIDTH, _>(|k| v[k].y)),
            z: L::from(std::array::from_fn::<f32, WIDTH, _>(|k| v[k].z)),
        }
    }

    #[inline(always)]
    fn lane(&self, k: usize) -> Vec3 {
        Vec3::new(
            self.x.as_array_ref()[k],
            self.y.as_array_ref()[k],
            self.z.as_array_ref()[k],
        )
    }

    #[inline(always)]
    fn add(self, o: V3) -> V3 {
        V3 {
            x: self.x + o.x,
            y: self.y + o.y,
            z: self.z + o.z,
        }
    }

    #[inline(always)]
    fn sub(self, o: V3) -> V3 {
        V3 {
            x: self.x - o.x,
            y: self.y - o.y,
            z: self.z - o.z,
        }
    }

    /// Componentwise product.
    #[inline(always)]
    fn mul(self, o: V3) -> V3 {
        V3 {
            x: self.x * o.x,
            y: self.y * o.y,
            z: self.z * o.z,
        }
    }

    #[inline(always)]
    fn scale(self, s: L) -> V3 {
        V3 {
            x: self.x * s,
            y: self.y * s,
            z: self.z * s,
        }
    }

    #[inline(always)]
    fn div(self, s: L) -> V3 {
        V3 {
            x: self.x / s,
            y: self.y / s,
            z: self.z / s,
        }
    }

    #[inline(always)]
    fn dot(self, o: V3) -> L {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    #[inline(always)]
    fn max_element(self) -> L {
        self.x.max(self.y).max(self.z)
    }

    #[inline(always)]
    fn abs(self) -> V3 {
        V3 {
            x: self.x.abs(),
            y: self.y.abs(),
            z: self.z.abs(),
        }
    }

    #[inline(always)]
    fn mean(self) -> L {
        (self.x + self.y + self.z) * L::splat(1.0 / 3.0)
    }

    /// Lanes where every component is 0.
    #[inline(always)]
    fn is_zero(self) -> L {
        let z = L::ZERO;
        self.x.cmp_eq(z) & self.y.cmp_eq(z) & self.z.cmp_eq(z)
    }

    #[inline(always)]
    fn is_finite(self) -> L {
        self.x.is_finite() & self.y.is_finite() & self.z.is_finite()
    }

    /// `t` where `mask` is set, else `self`.
    #[inline(always)]
    fn select(self, mask: L, t: V3) -> V3 {
        V3 {
            x: mask.blend(t.x, self.x),
            y: mask.blend(t.y, self.y),
            z: mask.blend(t.z, self.z),
        }
    }

    /// e^{−σ t} per channel (σ = 0: 1 at any t).
    #[inline(always)]
    fn transmittance(sigma: V3, t: L) -> V3 {
        let f = |s: L| s.cmp_gt(L::ZERO).blend((-(s * t)).exp(), L::ONE);
        V3 {
            x: f(sigma.x),
            y: f(sigma.y),
            z: f(sigma.z),
        }
    }
}

/// A medium sphere of the packet's scene.
#[derive(Clone, Copy, Debug)]
struct PacketSphere {
    center: Vec3,
    radius2: f32,
    medium: u32,
}

/// A medium's extinction and phase function (the albedo is the render's).
#[derive(Clone, Copy, Debug)]
struct PacketMedium {
    sigma_t: Vec3,
    /// Henyey–Greenstein's g (0: isotropic).
    g: f32,
}

/// What the packet kernel needs of a scene it takes: its media spheres, their media,
/// the sky, and the integrator's settings.
#[derive(Clone, Debug)]
pub struct PacketScene {
    spheres: Vec<PacketSphere>,
    media: Vec<PacketMedium>,
    /// The sky's radiance (0 where there is none).
    environment: Vec3,
    has_environment: bool,
    max_depth: u32,
    rr_depth: u32,
    hide_emitters: bool,
    /// Every medium's σ_t is the same in all channels: no transmittance is needed.
    grey: bool,
}

impl PacketScene {
    /// The packet form of `scene`, or why its paths need the scalar integrator. Taken:
    /// `volpath` with the camera in empty space; shapes that are all `null` spheres (no
    /// flipped normals, no emitter) each bounding a homogeneous medium inside (none
    /// outside), no two overlapping; isotropic or Henyey–Greenstein (|g| ≤
    /// [`MAX_ABS_G`]) phase functions; no emitter but a `constant` sky.
    pub fn new(scene: &Scene) -> Result<PacketScene, String> {
        if scene.integrator.kind != IntegratorKind::Volpath {
            return Err("the integrator is not volpath".into());
        }
        if scene.camera_medium.is_some() {
            return Err("the camera is inside a medium".into());
        }
        if scene.ray_log.is_some() {
            return Err("casts are being logged".into());
        }
        let mut spheres = Vec::new();
        for (shape, geometry) in scene.shapes.iter().zip(&scene.geometries) {
            let Geometry::Sphere(s) = geometry else {
                return Err("a shape is not a sphere".into());
            };
            let (Some(medium), None) = (shape.interior, shape.exterior) else {
                return Err("a sphere does not bound a medium inside empty space".into());
            };
            if s.flip_normals || shape.emitter.is_some() {
                return Err("a sphere has flipped normals or emits".into());
            }
            if !matches!(scene.bsdfs[shape.bsdf as usize], Bsdf::Null) {
                return Err("a sphere's boundary is not null".into());
            }
            spheres.push(PacketSphere {
                center: Vec3::from(s.center),
                radius2: s.radius * s.radius,
                medium,
            });
        }
        for (i, a) in spheres.iter().enumerate() {
            for b in &spheres[..i] {
                let reach = a.radius2.sqrt() + b.radius2.sqrt();
                if a.center.distance(b.center) <= reach {
                    return Err("two medium spheres touch or overlap".into());
                }
            }
        }
        let mut media = Vec::new();
        for m in &scene.media {
            if m.heterogeneous.is_some() {
                return Err("a medium is heterogeneous".into());
            }
            let g = match m.phase {
                Phase::Isotropic => 0.0,
                Phase::HenyeyGreenstein { g } if g.abs() <= MAX_ABS_G => g,
                _ => {
                    return Err(format!(
                        "a phase function is not isotropic or hg with |g| <= {MAX_ABS_G}"
                    ))
                }
            };
            media.push(PacketMedium {
                sigma_t: m.sigma_t,
                g,
            });
        }
        let environment = match scene.emitters.as_slice() {
            [] => Vec3::ZERO,
            [Emitter::Constant { radiance }] if scene.environment == Some(0) => *radiance,
            _ => return Err("an emitter is not a constant sky".into()),
        };
        let grey = scene.media.iter().all(|m| m.is_grey());
        Ok(PacketScene {
            spheres,
            media,
            environment,
            has_environment: scene.environment.is_some(),
            max_depth: scene.integrator.max_depth,
            rr_depth: scene.integrator.rr_depth,
            hide_emitters: scene.integrator.hide_emitters,
            grey,
        })
    }
}

/// A render's per-medium values: its albedo and the factors (a, b) by which a vertex
/// there updates dβ (`Gradient::vertex_factors`).
#[derive(Clone, Debug)]
pub struct PacketSettings {
    albedo: Vec<Vec3>,
    factor_a: Vec<Vec3>,
    factor_b: Vec<Vec3>,
    /// The difference's paths are rouletted by β + dβ (volpath's roulette).
    roulette_by_target: bool,
}

impl PacketSettings {
    pub fn new(settings: &PathSettings) -> PacketSettings {
        let n = settings.albedo.len();
        let (factor_a, factor_b) = (0..n)
            .map(|m| {
                settings
                    .gradient
                    .vertex_factors(m as u32, settings.albedo[m])
            })
            .unzip();
        PacketSettings {
            albedo: settings.albedo.to_vec(),
            factor_a,
            factor_b,
            roulette_by_target: matches!(settings.gradient, Gradient::Difference { .. }),
        }
    }
}

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

/// The lanes where bit k of `bits` is set.
#[inline(always)]
fn lanes_of(bits: i32) -> impl Iterator<Item = usize> {
    (0..WIDTH).filter(move |k| bits >> k & 1 == 1)
}

/// All-ones where `cond`, per lane.
#[inline(always)]
fn mask_of(cond: impl Fn(usize) -> bool) -> L {
    L::from(std::array::from_fn::<f32, WIDTH, _>(|k| {
        if cond(k) {
            f32::from_bits(u32::MAX)
        } else {
            0.0
        }
    }))
}

/// One uniform draw per lane of `mask` from its path's stream (0 elsewhere).
#[inline(always)]
fn draw_1d(mask: L, rngs: &mut [Pcg32]) -> L {
    let mut u = [0f32; WIDTH];
    for k in lanes_of(mask.move_mask()) {
        u[k] = rngs[k].next_1d();
    }
    L::from(u)
}

/// Two uniform draws (one `next_2d`) per lane of `mask`.
#[inline(always)]
fn draw_2d(mask: L, rngs: &mut [Pcg32]) -> (L, L) {
    let (mut u, mut v) = ([0f32; WIDTH], [0f32; WIDTH]);
    for k in lanes_of(mask.move_mask()) {
        let s = rngs[k].next_2d();
        (u[k], v[k]) = (s.x, s.y);
    }
    (L::from(u), L::from(v))
}

/// The direction after a Henyey–Greenstein scattering of light travelling along `d`
/// (unit), from uniform `u1`, `u2`: `medium::phase`'s sampling in lanes. With
/// a = |g|, q = 1 + a − 2au and s = (1 − a²)/q, the distance from the peak is
///   w = (1 − a) u (s + 1 − a) / q,
/// cos θ = 1 − w for g ≥ 0 and w − 1 for g < 0 (the peak backwards); g = 0 gives
/// w = 2u, the isotropic law. The frame around `d` is `geometry::Frame::new`'s.
#[inline(always)]
fn sample_hg(d: V3, g: L, u1: L, u2: L) -> V3 {
    let one = L::ONE;
    let two = L::splat(2.0);
    let a = g.abs();
    let q = one + a - two * a * u1;
    let s = (one - a * a) / q;
    let w = ((one - a) * u1 * (s + one - a) / q).max(L::ZERO).min(two);
    let w = g.cmp_ge(L::ZERO).blend(w, two - w);
    let cos_theta = one - w;
    let sin_theta = (w * (two - w)).max(L::ZERO).sqrt();
    let (sin_phi, cos_phi) = (L::splat(2.0 * std::f32::consts::PI) * u2).sin_cos();
    let (lx, ly, lz) = (sin_theta * cos_phi, sin_theta * sin_phi, cos_theta);
    // Frame::new(d): Duff et al.'s branchless orthonormal basis.
    let sign = one.copysign(d.z);
    let fa = -one / (sign + d.z);
    let fb = d.x * d.y * fa;
    let s = V3 {
        x: one + sign * d.x * d.x * fa,
        y: sign * fb,
        z: -sign * d.x,
    };
    let t = V3 {
        x: fb,
        y: sign + d.y * d.y * fa,
        z: -d.y,
    };
    s.scale(lx).add(t.scale(ly)).add(d.scale(lz))
}

/// The samples of the camera rays `(o, d, tmax)` (at most [`WIDTH`], `d` unit), each
/// with its own random stream, into `out`: volpath's `sample` for each, in lanes.
pub fn sample_packet(
    scene: &PacketScene,
    settings: &PacketSettings,
    rays: &[(Vec3A, Vec3A, f32)],
    rngs: &mut [Pcg32],
    out: &mut [PathSample],
) {
    let n = rays.len();
    assert!(n <= WIDTH && rngs.len() == n && out.len() == n);
    let inf = L::splat(f32::INFINITY);
    let none = L::splat(-1.0);
    let mut o = V3::from_lanes(&std::array::from_fn(|k| {
        rays.get(k).map_or(Vec3A::ZERO, |r| r.0)
    }));
    let mut d = V3::from_lanes(&std::array::from_fn(|k| {
        rays.get(k).map_or(Vec3A::Z, |r| r.1)
    }));
    let mut tmax = L::from(std::array::from_fn::<f32, WIDTH, _>(|k| {
        rays.get(k).map_or(0.0, |r| r.2)
    }));
    let mut alive = mask_of(|k| k < n);
    let mut beta = V3::splat(Vec3::ONE);
    let mut d_beta = V3::splat(Vec3::ZERO);
    let mut r_u = V3::splat(Vec3::ONE);
    let mut result = V3::splat(Vec3::ZERO);
    let mut d_result = V3::splat(Vec3::ZERO);
    let mut depth = L::ZERO;
    // The sphere whose medium each path is in (as f32; −1: empty space).
    let mut sphere = none;
    let mut valid = if !scene.hide_emitters && scene.has_environment {
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
    let max_depth = L::splat(scene.max_depth as f32);
    let rr_depth = L::splat(scene.rr_depth as f32);
    let sky = V3::splat(scene.environment);
    let single_medium = (scene.media.len() == 1).then(|| {
        let m = &scene.media[0];
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
            let w = weight.max_element();
            let w = w.cmp_gt(L::ZERO).blend(w, d_beta.abs().max_element());
            let q = w.min(L::splat(0.95));
            // A NaN q fails u < q: the path ends, as the scalar one does.
            let ended = played & !u.cmp_lt(q);
            alive &= !ended;
            let go_on = played & alive;
            beta = beta.select(go_on, beta.div(q));
            d_beta = d_beta.select(go_on, d_beta.div(q));
        }

        // ---- Where each ray ends: its sphere's far side, or the nearest sphere ----
        let in_medium = alive & sphere.cmp_ge(L::ZERO);
        let in_space = alive & !in_medium;
        let mut t_end = inf;
        let mut entered = none;
        for (i, s) in scene.spheres.iter().enumerate() {
            let oc = o.sub(V3::splat(s.center));
            let b = oc.dot(d);
            let c = oc.dot(oc) - L::splat(s.radius2);
            let disc = b * b - c;
            let root = disc.max(L::ZERO).sqrt();
            let index = L::splat(i as f32);
            // From inside (c ≤ 0) the far root, −b + √disc, in the form without
            // cancellation for b > 0: −c / (b + √disc).
            let far = b
                .cmp_le(L::ZERO)
                .blend(root - b, -c / (b + root))
                .max(L::ZERO);
            t_end = (in_medium & sphere.cmp_eq(index)).blend(far, t_end);
            // From outside (c > 0, heading in: b < 0) the near root c / (−b + √disc).
            let near = c / (root - b);
            let enters = in_space
                & b.cmp_lt(L::ZERO)
                & c.cmp_gt(L::ZERO)
                & disc.cmp_gt(L::ZERO)
                & near.cmp_lt(t_end)
                & near.cmp_lt(tmax);
            t_end = enters.blend(near, t_end);
            entered = enters.blend(index, entered);
        }

        // ---- Free flight in the medium ----
        if in_medium.any() {
            let gathered;
            let m = match &single_medium {
                Some(m) => m,
                None => {
                    gathered = gather_media(scene, settings, sphere, in_medium, &hero_of);
                    &gathered
                }
            };
            let u = draw_1d(in_medium, rngs);
            let flight = -(L::ONE - u).ln() / m.sigma_hero;
            let flight = m.sigma_hero.cmp_gt(L::ZERO).blend(flight, inf);
            let collided = in_medium & flight.cmp_lt(t_end);
            let passed = in_medium & !collided;
            if !scene.grey {
                // Collision at t: f = T σ_t α, p_c = σ_t,c T_c; passing to the end:
                // f = T, p_c = T_c (volpath's chromatic weights).
                let t = collided.blend(flight, t_end);
                let tr = V3::transmittance(m.sigma, t);
                let tr_hero = hero_of(tr);
                let w_collided = tr.mul(m.sigma).div(m.sigma_hero * tr_hero);
                let w_passed = tr.div(tr_hero);
                let w = w_passed.select(collided, w_collided);
                beta = beta.select(in_medium, beta.mul(w));
                d_beta = d_beta.select(in_medium, d_beta.mul(w));
                r_u = r_u.select(in_medium, r_u.mul(w));
            }
            // d(β α)/dα: dβ a + β b at a vertex (Gradient::vertex_factors).
            d_beta = d_beta.select(collided, d_beta.mul(m.a).add(beta.mul(m.b)));
            beta = beta.select(collided, beta.mul(m.albedo));
            if !scene.grey {
                // Keep mean(r) = 1 (volpath's rescaling).
                let k = in_medium.blend(r_u.mean(), L::ONE);
                beta = beta.div(k);
                d_beta = d_beta.div(k);
                r_u = r_u.div(k);
            }
            alive &= !in_medium | (beta.is_finite() & r_u.is_finite() & d_beta.is_finite());
            let collided = collided & alive;
            depth = collided.blend(depth + L::ONE, depth);
            valid |= collided;
            alive &= !(collided & depth.cmp_ge(max_depth));
            let collided = collided & alive;
            if collided.any() {
                // ---- Phase function sampling ----
                let (u1, u2) = draw_2d(collided, rngs);
                let wo = sample_hg(d, m.g, u1, u2);
                o = o.select(collided, o.add(d.scale(flight)));
                d = d.select(collided, wo);
            }
            // Through the null boundary into empty space.
            let passed = passed & alive;
            o = o.select(passed, o.add(d.scale(t_end)));
            sphere = passed.blend(none, sphere);
        }

        // ---- In empty space: into a sphere's medium, or out to the sky ----
        let enters = in_space & entered.cmp_ge(L::ZERO);
        o = o.select(enters, o.add(d.scale(t_end)));
        sphere = enters.blend(entered, sphere);
        let escapes = in_space & !enters;
        if escapes.any() {
            let seen = if scene.hide_emitters {
                escapes & depth.cmp_gt(L::ZERO)
            } else {
                escapes
            };
            result = result.select(seen, result.add(beta.mul(sky)));
            d_result = d_result.select(seen, d_result.add(d_beta.mul(sky)));
            alive &= !escapes;
        }
        tmax = inf;
    }

    let valid = valid.move_mask();
    for (k, s) in out.iter_mut().enumerate() {
        *s = PathSample {
            radiance: result.lane(k),
            second: d_result.lane(k),
            seen_emission: Vec3::ZERO,
            valid: valid >> k & 1 == 1,
        };
    }
}

/// The values of the media the paths of `mask` are in (lanes elsewhere: the first
/// medium's, unused).
fn gather_media(
    scene: &PacketScene,
    settings: &PacketSettings,
    sphere: L,
    mask: L,
    hero_of: &impl Fn(V3) -> L,
) -> MediumLanes {
    let spheres = sphere.to_array();
    let bits = mask.move_mask();
    let medium: [usize; WIDTH] = std::array::from_fn(|k| {
        if bits >> k & 1 == 1 {
            scene.spheres[spheres[k] as usize].medium as usize
        } else {
            0
        }
    });
    let v3 = |f: &dyn Fn(usize) -> Vec3| {
        let v: [Vec3A; WIDTH] = std::array::from_fn(|k| Vec3A::from(f(medium[k])));
        V3::from_lanes(&v)
    };
    let sigma = v3(&|m| scene.media[m].sigma_t);
    MediumLanes {
        sigma_hero: hero_of(sigma),
        sigma,
        albedo: v3(&|m| settings.albedo[m]),
        a: v3(&|m| settings.factor_a[m]),
        b: v3(&|m| settings.factor_b[m]),
        g: L::from(std::array::from_fn::<f32, WIDTH, _>(|k| {
            scene.media[medium[k]].g
        })),
    }
}

#[cfg(test)]
mod tests;
