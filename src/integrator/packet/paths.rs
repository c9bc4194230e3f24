//! A packet's paths between their vertices, in lanes, and the steps of volpath's loop
//! on them (`sample_packet` runs them in order): the roulette, where each ray ends, the
//! free flight and the medium vertex, the crossings into media and through dielectric
//! boundaries, the escape to the sky, and the diffuse surface vertex.

use glam::{Vec3, Vec3A};
use wide::{CmpEq, CmpGe, CmpGt, CmpLt};

use super::boundary::boundary_sample;
use super::derivatives::Derivatives;
use super::emitters::sample_emitters;
use super::lanes::{mask_of, L, V3, WIDTH};
use super::shapes::{shadow_transmittance, surface_hit, MediumSpan};
use super::{
    dielectric_of, emitting, gather_media, medium_normals, surface_emission, surface_lanes,
    MediumLanes, PacketScene, MAX_NULL_CROSSINGS,
};
use crate::geometry::{offset_point, to_world};
use crate::integrator::roulette::roulette;
use crate::integrator::sample::PathSample;
use crate::integrator::volpath::PathSettings;
use crate::medium::heterogeneous::HeterogeneousMedium;
use crate::medium::phase::{direction_at, hg_eval, hg_log_derivative_g, hg_sample_angle};
use crate::medium::{
    collision_weight, collision_weight_d_sigma, expected_pass_weight, hero_channel, pass_weight,
    sample_distance, transmittance_rgb, Tracked, Transmitted,
};
use crate::sampling::warp::cosine_hemisphere;
use crate::sampling::{Pcg32, Sampler};
use crate::scene::Scene;
use crate::simd::Float;

/// A shadow ray's ∂ ln T, or zero for the power tests' estimator without it.
#[inline(always)]
fn shadow_score(ctx: &Context, shadow: &Transmitted<L>) -> V3 {
    match ctx.settings.estimand.without_shadow_term() {
        true => V3::splat(Vec3::ZERO),
        false => shadow.d_log,
    }
}

/// "None" for a lane's shape index (as f32).
const NONE: f32 = -1.0;

/// What every step reads: the scene, its packet form, the render's settings.
pub(super) struct Context<'a> {
    pub(super) scene: &'a Scene,
    pub(super) ps: &'a PacketScene,
    pub(super) settings: &'a PathSettings<'a>,
    /// The scene's one medium where it is heterogeneous (`PacketScene::new` takes no
    /// other with it).
    het: Option<&'a HeterogeneousMedium>,
    /// The medium's values where the scene has one homogeneous medium.
    single_medium: Option<MediumLanes>,
}

/// Where each lane's ray ends, before the free flight.
struct RayEnds {
    /// In a medium, and in empty space.
    in_medium: L,
    in_space: L,
    t_end: L,
    /// The medium shape the ray enters there (−1: none), and the surface it meets.
    entered: L,
    hit_surface: L,
    meets_surface: L,
}

/// What the free flights left to the next steps.
struct Passage {
    /// The flights that reached the surface ahead of them.
    reached: L,
    /// Those whose emitter there was counted in expectation.
    counted: L,
    /// Those that reached their medium's dielectric boundary.
    leaves_to_boundary: L,
}

/// The paths of a packet, one a lane: weights, rays, where they are, what they gathered.
/// `D`: whether the render estimates a derivative (`Estimand` other than
/// `RadianceOnly`). A plain render's packet is the instance without, in which dβ, dσ and
/// dg (all zero there) are neither carried nor updated: it does none of their arithmetic.
pub(super) struct PacketPaths<const D: bool> {
    o: V3,
    d: V3,
    tmax: L,
    alive: L,
    beta: V3,
    d_beta: V3,
    r_u: V3,
    result: V3,
    d_result: V3,
    depth: L,
    /// The medium shape each path is in, and the surface it is on (as f32; −1: none).
    medium_shape: L,
    on_surface: L,
    /// Null-boundary crossings since the last vertex (volpath's MAX_NULL_CROSSINGS: a
    /// ray caught at a grazing exit would otherwise cross forever).
    crossings: L,
    /// Where each path last scattered and the pdf of the direction it took there (for
    /// the MIS weight of an area emitter it meets).
    last_p: V3,
    last_pdf: L,
    /// Since the last vertex that samples emitters, only delta (dielectric) vertices:
    /// an emitter met then counts in full (volpath's `specular_chain`).
    specular: L,
    /// The product of the refractions' relative indices (for the roulette, η²).
    eta: L,
    /// The emission each camera ray meets first (`PathSample::seen_emission`).
    seen_emission: V3,
    valid: L,
    /// The hero channel: x, y where these are set, else z.
    hero_x: L,
    hero_y: L,
    /// The derivatives in a medium's extinction and g, where asked for.
    derivs: Derivatives<D>,
}

impl<'a> Context<'a> {
    pub(super) fn new<const D: bool>(
        scene: &'a Scene,
        ps: &'a PacketScene,
        settings: &'a PathSettings<'a>,
        paths: &PacketPaths<D>,
    ) -> Self {
        let estimand = settings.estimand;
        let single_medium = (ps.media.len() == 1).then(|| {
            let m = &ps.media[0];
            let (a, b) = estimand.vertex_factors(0, settings.albedo[0]);
            MediumLanes {
                sigma: V3::splat(m.sigma_t),
                sigma_hero: paths.hero_of(V3::splat(m.sigma_t)),
                albedo: V3::splat(settings.albedo[0]),
                a: V3::splat(a),
                b: V3::splat(b),
                g: L::splat(m.g),
                chosen_sigma: L::mask(estimand.extinction_medium() == Some(0)),
                chosen_g: L::mask(estimand.g_medium() == Some(0) && m.hg),
            }
        });
        Context {
            scene,
            ps,
            settings,
            het: scene.media.first().and_then(|m| m.heterogeneous.as_deref()),
            single_medium,
        }
    }
}

impl<const D: bool> PacketPaths<D> {
    /// The camera rays `(o, d, tmax)` (at most [`WIDTH`]), each lane's hero channel
    /// drawn first from its stream, as the scalar path draws it.
    pub(super) fn new(
        ps: &PacketScene,
        settings: &PathSettings,
        rays: &[(Vec3A, Vec3A, f32)],
        rngs: &mut [Pcg32],
    ) -> Self {
        let n = rays.len();
        let none = L::splat(NONE);
        let ray = |k: usize| rays.get(k).copied().unwrap_or((Vec3A::ZERO, Vec3A::Z, 0.0));
        let o = V3::from_fn(|k| Vec3::from(ray(k).0));
        let alive = mask_of(|k| k < n);
        let mut hero = [0usize; WIDTH];
        for (k, h) in hero.iter_mut().enumerate().take(n) {
            *h = hero_channel(rngs[k].next_1d());
        }
        PacketPaths {
            o,
            d: V3::from_fn(|k| Vec3::from(ray(k).1)),
            tmax: L::from(std::array::from_fn::<f32, WIDTH, _>(|k| ray(k).2)),
            alive,
            beta: V3::splat(Vec3::ONE),
            d_beta: V3::splat(Vec3::ZERO),
            r_u: V3::splat(Vec3::ONE),
            result: V3::splat(Vec3::ZERO),
            d_result: V3::splat(Vec3::ZERO),
            depth: L::ZERO,
            medium_shape: ps.camera_shape.map_or(none, |i| L::splat(i as f32)),
            on_surface: none,
            crossings: L::ZERO,
            last_p: o,
            last_pdf: L::ONE,
            specular: L::ZERO,
            eta: L::ONE,
            seen_emission: V3::splat(Vec3::ZERO),
            valid: if !ps.hide_emitters && ps.has_environment {
                alive
            } else {
                L::ZERO
            },
            hero_x: mask_of(|k| hero[k] == 0),
            hero_y: mask_of(|k| hero[k] == 1),
            derivs: Derivatives::new(settings),
        }
    }

    /// Every vertex of the paths, until none is left, and their samples into `out`.
    #[inline(always)]
    pub(super) fn run(
        mut self,
        (scene, ps): (&Scene, &PacketScene),
        settings: &PathSettings,
        rngs: &mut [Pcg32],
        out: &mut [PathSample],
    ) {
        let ctx = Context::new(scene, ps, settings, &self);
        while self.step(&ctx, rngs) {}
        self.write(out);
    }

    /// dβ and the medium's derivative weights times `w` in the lanes of `mask`, where β
    /// takes `w` (nothing in the instance without derivatives).
    #[inline(always)]
    fn scale_derivatives(&mut self, mask: L, w: V3) {
        if D {
            self.d_beta = self.d_beta.select(mask, self.d_beta.mul(w));
            self.derivs.scale(mask, w);
        }
    }

    /// Each lane's hero channel of `v`.
    #[inline(always)]
    fn hero_of(&self, v: V3) -> L {
        self.hero_x.blend(v.x, self.hero_y.blend(v.y, v.z))
    }

    /// The samples of the first `out.len()` lanes.
    pub(super) fn write(&self, out: &mut [PathSample]) {
        let valid = self.valid.move_mask();
        for (k, s) in out.iter_mut().enumerate() {
            *s = PathSample {
                radiance: self.result.lane(k),
                d_albedo: self.d_result.lane(k),
                d_sigma: self.derivs.sigma_result.lane(k),
                d_g: self.derivs.g_result.lane(k),
                seen_emission: self.seen_emission.lane(k),
                valid: valid >> k & 1 == 1,
            };
        }
    }

    /// One vertex of every live path. False once none is left.
    #[inline(always)]
    pub(super) fn step(&mut self, ctx: &Context, rngs: &mut [Pcg32]) -> bool {
        // ---- Termination: zero weight, depth, Russian roulette ----
        if !self.survive(ctx, rngs) {
            return false;
        }
        // ---- Where each ray ends: its medium's far side, or the nearest shape ----
        let ends = self.ray_ends(ctx.ps);
        // ---- Free flight in the medium ----
        let passage = if ends.in_medium.any() {
            self.free_flight(ctx, &ends, rngs)
        } else {
            Passage {
                reached: L::ZERO,
                counted: L::ZERO,
                leaves_to_boundary: L::ZERO,
            }
        };
        // ---- In empty space: into a medium, onto a surface, or out to the sky ----
        self.cross(ctx, &ends, &passage, rngs);
        self.tmax = L::splat(f32::INFINITY);
        true
    }

    /// Ends the lanes without weight or past max_depth, and plays the Russian roulette
    /// past rr_depth (`integrator::roulette`). False once no lane is left.
    #[inline(always)]
    fn survive(&mut self, ctx: &Context, rngs: &mut [Pcg32]) -> bool {
        let ps = ctx.ps;
        let zero = match D {
            true => self.beta.is_zero() & self.d_beta.is_zero(),
            false => self.beta.is_zero(),
        };
        self.alive &= !self.derivs.zero_of(zero);
        self.alive &= self.depth.cmp_lt(L::splat(ps.max_depth as f32));
        if self.alive.none() {
            return false;
        }
        let played = self.alive & self.depth.cmp_gt(L::splat(ps.rr_depth as f32));
        if played.any() {
            let u = rngs.draw_1d(played);
            let weight = ctx
                .settings
                .estimand
                .roulette_weight(self.beta, self.d_beta);
            let d_beta = if D {
                self.d_beta
            } else {
                V3::splat(Vec3::ZERO)
            };
            let (goes_on, q) = roulette(weight, d_beta, self.eta, u);
            let ended = played & !goes_on;
            self.alive &= !ended;
            let go_on = played & self.alive;
            self.beta = self.beta.select(go_on, self.beta.div(q));
            if D {
                self.d_beta = self.d_beta.select(go_on, self.d_beta.div(q));
                self.derivs.div(go_on, q);
            }
        }
        true
    }

    /// Where each ray ends: its medium shape's far side, or (in empty space) the nearest
    /// medium shape it enters, and the nearest surface in the medium it is in.
    #[inline(always)]
    fn ray_ends(&self, ps: &PacketScene) -> RayEnds {
        let none = L::splat(NONE);
        let (o, d, medium_shape) = (self.o, self.d, self.medium_shape);
        let in_medium = self.alive & medium_shape.cmp_ge(L::ZERO);
        let in_space = self.alive & !in_medium;
        let mut t_end = L::splat(f32::INFINITY);
        let mut entered = none;
        let mut hit_surface = none;
        for (i, m) in ps.media_shapes.iter().enumerate() {
            let span = MediumSpan::new(&m.kind, o, d);
            let index = L::splat(i as f32);
            t_end = (in_medium & medium_shape.cmp_eq(index)).blend(span.exit, t_end);
            let enters =
                in_space & span.enters & span.near.cmp_lt(t_end) & span.near.cmp_lt(self.tmax);
            t_end = enters.blend(span.near, t_end);
            entered = enters.blend(index, entered);
        }
        // The surfaces in the medium (or empty space) each path is in.
        for (k, surface) in ps.surfaces.iter().enumerate() {
            let here = self.alive & medium_shape.cmp_eq(L::splat(surface.container));
            if here.none() {
                continue;
            }
            let (hit, t) = surface_hit(ps, k, o, d, self.on_surface);
            let hit = here & hit & t.cmp_lt(t_end) & t.cmp_lt(self.tmax);
            t_end = hit.blend(t, t_end);
            hit_surface = hit.blend(L::splat(k as f32), hit_surface);
            entered = hit.blend(none, entered);
        }
        RayEnds {
            in_medium,
            in_space,
            t_end,
            entered,
            meets_surface: hit_surface.cmp_ge(L::ZERO),
            hit_surface,
        }
    }

    /// The free flights of the lanes in a medium: the emission ahead counted in
    /// expectation, the distance (or delta tracking), the vertex's weights, the medium
    /// vertex, or the passage to the surface or boundary ahead.
    #[inline(always)]
    fn free_flight(&mut self, ctx: &Context, ends: &RayEnds, rngs: &mut [Pcg32]) -> Passage {
        let in_medium = ends.in_medium;
        let gathered;
        let m = match &ctx.single_medium {
            Some(m) => m,
            None => {
                let hero_of = |v: V3| self.hero_of(v);
                gathered =
                    gather_media(ctx.ps, ctx.settings, self.medium_shape, in_medium, &hero_of);
                &gathered
            }
        };
        let counted = if ctx.ps.area_emitters && ctx.het.is_none() {
            self.emission_ahead(ctx, ends, m)
        } else {
            L::ZERO
        };
        let (collided, flight, d_beta_before) = self.flight_ends(ctx, ends, m, rngs);
        let passed = in_medium & !collided;
        let mut finite = self.beta.is_finite() & self.r_u.is_finite();
        if D {
            finite &= self.d_beta.is_finite();
        }
        self.alive &= !in_medium | self.derivs.finite_of(finite);
        let collided = collided & self.alive;
        self.depth = collided.blend(self.depth + L::ONE, self.depth);
        self.valid |= collided;
        self.alive &= !(collided & self.depth.cmp_ge(L::splat(ctx.ps.max_depth as f32)));
        let collided = collided & self.alive;
        self.specular = collided.blend(L::ZERO, self.specular);
        if collided.any() {
            self.scatter_in_medium(ctx, m, (collided, flight), d_beta_before, rngs);
        }
        self.crossings = collided.blend(L::ZERO, self.crossings);
        // On to a surface in the medium, or through the null boundary into empty space.
        let passed = passed & self.alive;
        self.o = self.o.select(passed, self.o.add(self.d.scale(ends.t_end)));
        let reached = passed & ends.meets_surface;
        let leaves = passed & !ends.meets_surface;
        // (At a dielectric boundary the path stays in until the boundary's sample says
        // otherwise.)
        let leaves_to_boundary = leaves & dielectric_of(ctx.ps, self.medium_shape);
        let leaves = leaves & !leaves_to_boundary;
        self.medium_shape = leaves.blend(L::splat(NONE), self.medium_shape);
        self.crossings = leaves.blend(self.crossings + L::ONE, self.crossings);
        Passage {
            reached,
            counted,
            leaves_to_boundary,
        }
    }

    /// An area emitter ahead, counted in expectation: the flight passes to it with
    /// probability T_hero and then weighs its emission by β T / mean(r T): count β T
    /// (T_hero / mean(r T)) L_e now, and not again if the flight does pass (volpath's
    /// module comment). The lanes whose emission was counted.
    #[inline(always)]
    fn emission_ahead(&mut self, ctx: &Context, ends: &RayEnds, m: &MediumLanes) -> L {
        let ahead = ends.in_medium & emitting(ctx.ps, ends.hit_surface);
        if ahead.none() {
            return L::ZERO;
        }
        let p_hit = self.o.add(self.d.scale(ends.t_end));
        let (n, _) = surface_lanes(ctx.ps, ends.hit_surface, p_hit, ahead);
        let view = (p_hit, n, self.d);
        let le = surface_emission(
            ctx.scene,
            ctx.ps,
            ends.hit_surface,
            ahead,
            view,
            (self.depth, self.specular),
            (self.last_p, self.last_pdf),
        );
        let tr = transmittance_rgb(m.sigma, ends.t_end);
        let pass = expected_pass_weight(tr, self.hero_of(tr), self.r_u);
        let x = pass.mul(le);
        let finite = ahead & x.is_finite();
        self.result = self
            .result
            .select(finite, self.result.add(self.beta.mul(x)));
        if D {
            self.d_result = self
                .d_result
                .select(finite, self.d_result.add(self.d_beta.mul(x)));
            // ∂T/∂σ_t = −t T in the differentiated medium.
            let d_log = V3::all(m.chosen_sigma.blend(-ends.t_end, L::ZERO));
            self.derivs
                .gather_light(finite, x, self.beta, (d_log, L::ZERO));
        }
        ahead & !le.is_zero()
    }

    /// The flights' ends and their weights: the lanes that collided, where, and dβ
    /// without this vertex's own α (for the power tests' wrong variant only). β and dβ
    /// take the vertex's α (the render's factor times the albedo volume's value).
    #[inline(always)]
    fn flight_ends(
        &mut self,
        ctx: &Context,
        ends: &RayEnds,
        m: &MediumLanes,
        rngs: &mut [Pcg32],
    ) -> (L, L, V3) {
        let in_medium = ends.in_medium;
        // d/d scale in a heterogeneous medium, added once β has its α.
        let mut scale_score = None;
        let (collided, flight, volume_albedo) = match ctx.het {
            Some(h) => {
                // Delta tracking; the majorant is grey, so r is unchanged.
                let walk = L::majorant_walk(h, self.o, self.d, (L::ZERO, ends.t_end));
                let f = h.delta_tracking(self.o, self.d, walk, in_medium, rngs);
                self.beta = self.beta.select(in_medium, self.beta.mul(f.weight));
                self.scale_derivatives(in_medium, f.weight);
                if self.derivs.sigma_on() {
                    let mask = in_medium & m.chosen_sigma;
                    let ray = (self.o, self.d);
                    let score = h.flight_scale_score(ray, &f, ends.t_end, mask);
                    scale_score = Some((mask, score));
                }
                (in_medium & f.collided, f.t, f.albedo)
            }
            None => {
                let u = rngs.draw_1d(in_medium);
                let flight = sample_distance(m.sigma_hero, u);
                let collided = in_medium & flight.cmp_lt(ends.t_end);
                if !ctx.ps.grey {
                    // Collision at t: f = T σ_t α, p_c = σ_t,c T_c; passing to the end:
                    // f = T, p_c = T_c (volpath's chromatic weights).
                    let t = collided.blend(flight, ends.t_end);
                    let tr = transmittance_rgb(m.sigma, t);
                    let tr_hero = self.hero_of(tr);
                    let w_collided = collision_weight(tr, m.sigma, m.sigma_hero, tr_hero);
                    let w_passed = pass_weight(tr, tr_hero);
                    let w = w_passed.select(collided, w_collided);
                    self.scale_derivatives(in_medium, w);
                    if self.derivs.sigma_on() {
                        // ∂f/∂σ_t over the same p: T (1 − σ_t t) at a collision, −t T
                        // passing (volpath's `Differentiated`).
                        let dw = collision_weight_d_sigma(tr, m.sigma, t, m.sigma_hero, tr_hero);
                        let dw = w_passed.scale(-t).select(collided, dw);
                        self.derivs
                            .add_sigma(in_medium & m.chosen_sigma, self.beta, dw);
                    }
                    self.beta = self.beta.select(in_medium, self.beta.mul(w));
                    self.r_u = self.r_u.select(in_medium, self.r_u.mul(w));
                }
                if ctx.ps.grey && self.derivs.sigma_on() {
                    // ∂ ln(σ_t e^{−σ_t t}) = 1/σ_t − t at a collision, −t passing a
                    // (finite) stretch; f / p = 1.
                    let s = collided.blend(L::ONE / m.sigma_hero - flight, -ends.t_end);
                    let finite = collided | ends.t_end.is_finite();
                    let mask = in_medium & m.chosen_sigma & finite;
                    self.derivs.add_sigma(mask, self.beta, V3::all(s));
                }
                (collided, flight, V3::splat(Vec3::ONE))
            }
        };
        let mut d_beta_before = self.d_beta;
        if D {
            d_beta_before = self.d_beta.mul(m.albedo).mul(volume_albedo);
            // d(β α)/dα: dβ a + β b at a vertex (Estimand::vertex_factors).
            let d_beta_vertex = self
                .d_beta
                .mul(m.a)
                .add(self.beta.mul(m.b))
                .mul(volume_albedo);
            self.d_beta = self.d_beta.select(collided, d_beta_vertex);
        }
        self.beta = self
            .beta
            .select(collided, self.beta.mul(m.albedo.mul(volume_albedo)));
        self.derivs.scale(collided, m.albedo.mul(volume_albedo));
        if let Some((mask, score)) = scale_score {
            self.derivs.add_sigma(mask, self.beta, score);
        }
        if !ctx.ps.grey && ctx.het.is_none() {
            // Keep mean(r) = 1 (volpath's rescaling).
            let k = in_medium.blend(self.r_u.mean(), L::ONE);
            self.beta = self.beta.div(k);
            if D {
                self.d_beta = self.d_beta.div(k);
                self.derivs.div_all(k);
                d_beta_before = d_beta_before.div(k);
            }
            self.r_u = self.r_u.div(k);
        }
        (collided, flight, d_beta_before)
    }

    /// The medium vertices at `flight` of the lanes of `collided`: emitter sampling
    /// (none from inside a dielectric: no shadow ray leaves it), then the phase sample.
    #[inline(always)]
    fn scatter_in_medium(
        &mut self,
        ctx: &Context,
        m: &MediumLanes,
        (collided, flight): (L, L),
        d_beta_before: V3,
        rngs: &mut [Pcg32],
    ) {
        let (ps, d) = (ctx.ps, self.d);
        let p = self.o.add(d.scale(flight));
        let nee = collided & !dielectric_of(ps, self.medium_shape);
        if ps.samples_emitters && nee.any() {
            let es = sample_emitters(ctx.scene, ps, p, nee, rngs);
            if es.some.any() {
                let cos = d.dot(es.d);
                let phase = hg_eval(m.g, cos);
                let ray = (p, es.d, es.dist);
                let from = (self.medium_shape, L::splat(NONE));
                let extinction = ctx.settings.estimand.extinction_medium();
                let shadow =
                    shadow_transmittance(ctx.scene, ps, ray, from, es.some, extinction, rngs);
                let x = es.value.mul(shadow.tr).scale(phase * es.weight(phase));
                self.result = self
                    .result
                    .select(es.some, self.result.add(self.beta.mul(x)));
                if D {
                    let weight_of_x = if ctx.settings.estimand.nee_ignores_vertex() {
                        d_beta_before
                    } else {
                        self.d_beta
                    };
                    self.d_result = self
                        .d_result
                        .select(es.some, self.d_result.add(weight_of_x.mul(x)));
                }
                // The shadow ray's ∂ ln T and the phase value's ∂ ln p / ∂g.
                let g_score = if self.derivs.g_on() {
                    let score = hg_log_derivative_g(m.g, L::ONE - cos);
                    m.chosen_g.blend(score, L::ZERO)
                } else {
                    L::ZERO
                };
                let d_log = shadow_score(ctx, &shadow);
                self.derivs
                    .gather_light(es.some, x, self.beta, (d_log, g_score));
            }
        }
        // ---- Phase function sampling ----
        let (u1, u2) = rngs.draw_2d(collided);
        // Exact sampling (in f32: the packet takes only moderate |g|): the weight is 1.
        let w = hg_sample_angle(m.g, u1);
        let wo = direction_at(d, w, u2);
        if self.derivs.g_on() {
            // f / p = 1 (exact sampling): with p detached, ∂f/∂g / p = ∂ ln p / ∂g.
            let score = hg_log_derivative_g(m.g, w);
            self.derivs
                .add_g_score(collided & m.chosen_g, self.beta, score);
        }
        if ps.area_emitters {
            self.last_p = self.last_p.select(collided, p);
            self.last_pdf = collided.blend(hg_eval(m.g, d.dot(wo)), self.last_pdf);
        }
        self.o = self.o.select(collided, p);
        self.d = self.d.select(collided, wo);
    }

    /// The lanes in empty space (into a medium, onto a surface, out to the sky) and at
    /// dielectric boundaries, and the diffuse surfaces reached from either.
    #[inline(always)]
    fn cross(&mut self, ctx: &Context, ends: &RayEnds, passage: &Passage, rngs: &mut [Pcg32]) {
        let (ps, none) = (ctx.ps, L::splat(NONE));
        let in_space = ends.in_space;
        let meets_medium = in_space & ends.entered.cmp_ge(L::ZERO);
        let lands = in_space & ends.meets_surface;
        self.o = self
            .o
            .select(meets_medium | lands, self.o.add(self.d.scale(ends.t_end)));
        let meets_boundary = meets_medium & dielectric_of(ps, ends.entered);
        let enters = meets_medium & !meets_boundary;
        // Paths on a surface: from empty space, or from a flight that reached it.
        let at_surface = self.alive & (lands | passage.reached);
        if enters.any() {
            // The scalar path (as Mitsuba's) starts inside a medium it enters off the
            // boundary by the spawn offset (`geometry::offset_point`); in a medium whose
            // mean free path is that short the offset shows, so the packet takes it too.
            let n = medium_normals(ps, ends.entered, self.o, enters);
            let spawned = offset_point(self.o, n, self.d, ps.offset_scale);
            self.o = self.o.select(enters, spawned);
        }
        self.medium_shape = enters.blend(ends.entered, self.medium_shape);
        self.crossings = enters.blend(self.crossings + L::ONE, self.crossings);
        self.alive &= !self.crossings.cmp_gt(L::splat(MAX_NULL_CROSSINGS));
        self.on_surface = ends.in_medium.blend(none, self.on_surface);
        self.on_surface = meets_medium.blend(none, self.on_surface);
        let at_boundary = self.alive & (meets_boundary | passage.leaves_to_boundary);
        if at_boundary.any() {
            let shape = passage
                .leaves_to_boundary
                .blend(self.medium_shape, ends.entered);
            self.through_boundary(ps, shape, at_boundary, rngs);
        }
        let escapes = in_space & !meets_medium & !lands;
        if escapes.any() {
            let seen = if ps.hide_emitters {
                escapes & self.depth.cmp_gt(L::ZERO)
            } else {
                escapes
            };
            let sky = V3::splat(ps.environment);
            self.result = self
                .result
                .select(seen, self.result.add(self.beta.mul(sky)));
            if D {
                self.d_result = self
                    .d_result
                    .select(seen, self.d_result.add(self.d_beta.mul(sky)));
                self.derivs.gather(seen, sky);
            }
            self.alive &= !escapes;
        }
        if at_surface.any() {
            self.at_surface(ctx, (at_surface, ends.hit_surface), passage.counted, rngs);
        }
    }

    /// A dielectric boundary of the medium shapes `shape` for the lanes of `at_boundary`:
    /// reflect or refract (`bsdf::Dielectric`).
    #[inline(always)]
    fn through_boundary(&mut self, ps: &PacketScene, shape: L, at_boundary: L, rngs: &mut [Pcg32]) {
        let b = boundary_sample(ps, shape, at_boundary, (self.o, self.d), rngs);
        self.valid |= at_boundary;
        let ok = at_boundary & b.pdf.cmp_gt(L::ZERO);
        self.alive &= !(at_boundary & !ok);
        self.beta = self.beta.select(ok, self.beta.mul(b.weight));
        self.scale_derivatives(ok, b.weight);
        self.eta = ok.blend(self.eta * b.eta, self.eta);
        self.depth = ok.blend(self.depth + L::ONE, self.depth);
        self.crossings = ok.blend(L::ZERO, self.crossings);
        self.specular |= ok;
        self.last_p = self.last_p.select(ok, self.o);
        self.last_pdf = ok.blend(b.pdf, self.last_pdf);
        // Into the medium or out of it, by the side the new direction points to, off the
        // boundary by the spawn offset (`geometry::offset_point`).
        let into = b.wo.dot(b.n).cmp_lt(L::ZERO);
        self.medium_shape = ok.blend(into.blend(shape, L::splat(NONE)), self.medium_shape);
        let spawned = offset_point(self.o, b.n, b.wo, ps.offset_scale);
        self.o = self.o.select(ok, spawned);
        self.d = self.d.select(ok, b.wo);
    }

    /// A diffuse surface (`hit_surface`) for the lanes of `at_surface`: its emission
    /// (unless `counted` in expectation), emitter sampling, then Lambert's law. (Front
    /// side only: from behind, the BSDF's sample fails and the path ends, as a failed
    /// sample ends the scalar one; it counts as met.)
    #[inline(always)]
    fn at_surface(
        &mut self,
        ctx: &Context,
        (at_surface, hit_surface): (L, L),
        counted: L,
        rngs: &mut [Pcg32],
    ) {
        let ps = ctx.ps;
        self.valid |= at_surface;
        let (n, rho) = surface_lanes(ps, hit_surface, self.o, at_surface);
        if ps.area_emitters {
            // ---- An area emitter's surface: its emission, MIS-weighted ----
            let seen = surface_emission(
                ctx.scene,
                ps,
                hit_surface,
                at_surface & !counted,
                (self.o, n, self.d),
                (self.depth, self.specular),
                (self.last_p, self.last_pdf),
            );
            self.result = self.result.add(self.beta.mul(seen));
            if D {
                self.d_result = self.d_result.add(self.d_beta.mul(seen));
                self.derivs.gather(at_surface & !counted, seen);
            }
            let first = at_surface
                & self.depth.cmp_eq(L::ZERO)
                & self.crossings.cmp_eq(L::ZERO)
                & self.medium_shape.cmp_lt(L::ZERO);
            self.seen_emission = self.seen_emission.select(first, seen);
        }
        let cos_in = -self.d.dot(n);
        let front = at_surface & cos_in.cmp_gt(L::ZERO);
        let nee = at_surface & (self.depth + L::ONE).cmp_lt(L::splat(ps.max_depth as f32));
        if ps.samples_emitters && nee.any() {
            let es = sample_emitters(ctx.scene, ps, self.o, nee, rngs);
            let cos_out = es.d.dot(n);
            let lit = es.some & front & cos_out.cmp_gt(L::ZERO);
            if lit.any() {
                let ray = (self.o, es.d, es.dist);
                let from = (self.medium_shape, hit_surface);
                let extinction = ctx.settings.estimand.extinction_medium();
                let shadow = shadow_transmittance(ctx.scene, ps, ray, from, lit, extinction, rngs);
                let pdf = cos_out * L::splat(std::f32::consts::FRAC_1_PI);
                let f = rho.scale(pdf * es.weight(pdf));
                let x = f.mul(es.value).mul(shadow.tr);
                self.result = self.result.select(lit, self.result.add(self.beta.mul(x)));
                if D {
                    self.d_result = self
                        .d_result
                        .select(lit, self.d_result.add(self.d_beta.mul(x)));
                    let d_log = shadow_score(ctx, &shadow);
                    self.derivs
                        .gather_light(lit, x, self.beta, (d_log, L::ZERO));
                }
            }
        }
        // The scalar path draws the BSDF's 1-D sample (the lobe's choice) before the 2-D
        // one; drawn here too, unused, to keep the draws in step.
        let _ = rngs.draw_1d(at_surface);
        let (u1, u2) = rngs.draw_2d(at_surface);
        let wo = to_world(n, cosine_hemisphere(u1, u2));
        if ps.area_emitters {
            self.last_p = self.last_p.select(front, self.o);
            self.last_pdf = front.blend(
                wo.dot(n) * L::splat(std::f32::consts::FRAC_1_PI),
                self.last_pdf,
            );
        }
        // Weight f cos / pdf = ρ.
        self.beta = self.beta.select(front, self.beta.mul(rho));
        self.scale_derivatives(front, rho);
        self.depth = front.blend(self.depth + L::ONE, self.depth);
        self.crossings = at_surface.blend(L::ZERO, self.crossings);
        self.specular = at_surface.blend(L::ZERO, self.specular);
        self.d = self.d.select(front, wo);
        self.on_surface = at_surface.blend(hit_surface, self.on_surface);
        self.alive &= !(at_surface & !front);
    }
}
