//! One volpath path's state between its vertices and the steps of Mitsuba's loop
//! (`volpath.cpp`'s `sample`): the roulette, the free flight (delta tracking in a
//! heterogeneous medium, the hero channel's distance in a homogeneous one), the
//! scattering vertex in a medium, and the surface vertex. The module comment of
//! `volpath` says what the estimator is; `sample` there runs these steps in order.

use glam::{Vec3, Vec3A};

use super::{
    emission_seen, mean, medium_after, medium_emitter_sample, shadow_transmittance, Estimand,
    LastScatter, MediumLight, PathSettings, ShadowRay, MAX_NULL_CROSSINGS,
};
use crate::bsdf::Bsdf;
use crate::integrator::emitters::{sample_light_at_surface, skip_emitters};
use crate::integrator::roulette::roulette;
use crate::integrator::sample::PathSample;
use crate::medium::heterogeneous::HeterogeneousMedium;
use crate::medium::{
    collision_weight, collision_weight_d_sigma, expected_pass_weight, pass_weight, Medium,
};
use crate::medium::{hero_channel, Tracked};
use crate::sampling::{mis_weight, Pcg32};
use crate::scene::{Scene, SurfaceInteraction};

mod adjoint;
use adjoint::shadow_derivative;
pub use adjoint::{AdjointPath, GridGradients};

/// A path between its vertices: its weights, where its ray is, what it has gathered.
pub(super) struct PathState<'a> {
    /// β = f / p_hero, rescaled with r after every free flight so that mean(r) = 1: β is
    /// then the path's weight (the module comment of `volpath`).
    beta: Vec3,
    /// dβ/dα of the chosen medium's albedo (zero while no vertex in it), or the
    /// difference's weight.
    d_beta: Vec3,
    /// d β / dθ for the chosen medium's extinction and phase asymmetry
    /// (`volpath::Differentiated`; zero where not asked for).
    d_sigma: Vec3,
    d_g: Vec3,
    /// r_c = p_c / p_hero.
    r_u: Vec3,
    /// The product of the refractions' relative indices (for the roulette, η²).
    eta: f32,
    depth: u32,
    null_crossings: u32,
    pub(super) medium: Option<u32>,
    /// Since the last vertex that samples emitters, only delta ones: an emitter met now
    /// counts in full.
    specular_chain: bool,
    last: LastScatter,
    /// The clearance at `ray_o`, where already looked up (see the free flight).
    origin_clearance: Option<f32>,
    hero: usize,
    ray_o: Vec3A,
    ray_d: Vec3A,
    ray_tmax: f32,
    result: Vec3,
    d_result: Vec3,
    d_sigma_result: Vec3,
    d_g_result: Vec3,
    seen_emission: Vec3,
    /// Mitsuba's `valid_ray`, the film's alpha: a visible environment, a scattering in a
    /// medium, or a surface whose BSDF sample is not a null one.
    valid: bool,
    /// Reverse mode's state of this path (`adjoint`), in either pass.
    adjoint: Option<&'a mut AdjointPath>,
}

/// What a free flight found.
pub(super) struct Flight {
    /// Scattered in the medium at `t` (else it reached `si`, or escaped).
    pub(super) scattered: bool,
    t: f32,
    /// The clearance at the flight's origin (0 where unused).
    clearance: f32,
    si: Option<SurfaceInteraction>,
    /// Whether the emission at the ray's end is already counted (in expectation).
    emission_counted: bool,
    /// dβ without this vertex's own α (for the power-test variant only).
    d_beta_before: Vec3,
}

impl Flight {
    /// No medium: the surface step casts the ray.
    pub(super) fn through_vacuum() -> Flight {
        Flight {
            scattered: false,
            t: 0.0,
            clearance: 0.0,
            si: None,
            emission_counted: false,
            d_beta_before: Vec3::ZERO,
        }
    }
}

impl<'a> PathState<'a> {
    /// The camera ray `(o, d, tmax)`, its hero channel drawn first.
    pub(super) fn new(
        scene: &Scene,
        (o, d, tmax): (Vec3A, Vec3A, f32),
        rng: &mut Pcg32,
        adjoint: Option<&'a mut AdjointPath>,
    ) -> Self {
        let s = &scene.integrator;
        PathState {
            beta: Vec3::ONE,
            d_beta: Vec3::ZERO,
            d_sigma: Vec3::ZERO,
            d_g: Vec3::ZERO,
            r_u: Vec3::ONE,
            eta: 1.0,
            depth: 0,
            null_crossings: 0,
            medium: scene.camera_medium,
            specular_chain: !s.hide_emitters,
            last: LastScatter { p: o, pdf: 1.0 },
            origin_clearance: None,
            hero: hero_channel(rng.next_1d()),
            ray_o: o,
            ray_d: d,
            ray_tmax: tmax,
            result: Vec3::ZERO,
            d_result: Vec3::ZERO,
            d_sigma_result: Vec3::ZERO,
            d_g_result: Vec3::ZERO,
            seen_emission: Vec3::ZERO,
            valid: !s.hide_emitters && scene.environment.is_some(),
            adjoint,
        }
    }

    /// A path that scatters in the current medium at `t` along the current ray with
    /// weight `beta`, as this one would there (its depth, hero, chain state), with none
    /// of its derivatives: a ghost (`adjoint`).
    fn ghost(&self, beta: Vec3) -> PathState<'static> {
        PathState {
            beta,
            d_beta: Vec3::ZERO,
            d_sigma: Vec3::ZERO,
            d_g: Vec3::ZERO,
            r_u: self.r_u,
            eta: self.eta,
            depth: self.depth,
            null_crossings: 0,
            medium: self.medium,
            specular_chain: self.specular_chain,
            last: self.last,
            origin_clearance: None,
            hero: self.hero,
            ray_o: self.ray_o,
            ray_d: self.ray_d,
            ray_tmax: self.ray_tmax,
            result: Vec3::ZERO,
            d_result: Vec3::ZERO,
            d_sigma_result: Vec3::ZERO,
            d_g_result: Vec3::ZERO,
            seen_emission: Vec3::ZERO,
            valid: self.valid,
            adjoint: None,
        }
    }

    /// What the path gathered.
    pub(super) fn sample(&self) -> PathSample {
        PathSample {
            radiance: self.result,
            d_albedo: self.d_result,
            d_sigma: self.d_sigma_result,
            d_g: self.d_g_result,
            seen_emission: self.seen_emission,
            valid: self.valid,
        }
    }

    /// Whether the path goes on: some weight left, below max_depth, and past rr_depth
    /// through the Russian roulette (which then divides its weights by q).
    #[inline(always)]
    pub(super) fn survives(
        &mut self,
        scene: &Scene,
        settings: &PathSettings,
        rng: &mut Pcg32,
    ) -> bool {
        let s = &scene.integrator;
        let no_weight = self.beta == Vec3::ZERO
            && self.d_beta == Vec3::ZERO
            && self.d_sigma == Vec3::ZERO
            && self.d_g == Vec3::ZERO;
        if no_weight || self.depth >= s.max_depth {
            return false;
        }
        if self.depth > s.rr_depth {
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
            let (beta, d_beta) = (self.beta.into(), self.d_beta.into());
            let w = settings.estimand.roulette_weight(beta, d_beta);
            let (goes_on, q) = roulette(w, d_beta, self.eta, u_rr);
            if !goes_on {
                return false;
            }
            self.beta /= q;
            self.d_beta /= q;
            self.d_sigma /= q;
            self.d_g /= q;
        }
        true
    }

    /// Whether β, r and dβ are all finite (else the path ends).
    #[inline(always)]
    pub(super) fn weights_finite(&self) -> bool {
        self.beta.is_finite()
            && self.r_u.is_finite()
            && self.d_beta.is_finite()
            && self.d_sigma.is_finite()
            && self.d_g.is_finite()
    }

    /// The free flight through medium `mi` from the ray's origin.
    #[inline(always)]
    pub(super) fn free_flight(
        &mut self,
        scene: &Scene,
        settings: &PathSettings,
        mi: u32,
        rng: &mut Pcg32,
    ) -> Flight {
        let m: &Medium = &scene.media[mi as usize];
        // The clearance at the flight's origin, where the vertex it starts from looked it
        // up (for its emitter sample): the same point, the same value.
        let known_clearance = self.origin_clearance.take();
        match m.heterogeneous.as_deref() {
            Some(het) => match settings.estimand {
                Estimand::Adjoint(a) if a.medium == mi => {
                    self.differential_tracking(scene, settings, a, het, rng)
                }
                _ => self.delta_tracking(scene, settings, mi, het, rng),
            },
            None => self.homogeneous_flight(scene, settings, mi, known_clearance, rng),
        }
    }

    /// Delta tracking through a heterogeneous medium: the surface that ends the ray,
    /// then the first real collision before it (`medium::heterogeneous`). The majorant
    /// is grey, so every channel's pdf is the hero's: r is unchanged.
    #[inline(always)]
    fn delta_tracking(
        &mut self,
        scene: &Scene,
        settings: &PathSettings,
        mi: u32,
        het: &HeterogeneousMedium,
        rng: &mut Pcg32,
    ) -> Flight {
        // The render's albedo of this medium (the scene's unless overridden).
        let albedo = settings.albedo[mi as usize];
        let hit = scene.intersect_in_medium(mi, self.ray_o, self.ray_d, self.ray_tmax);
        let end = hit.as_ref().map_or(self.ray_tmax, |h| h.t);
        let ray = (self.ray_o.into(), self.ray_d.into());
        let walk = f32::majorant_walk(het, ray.0, ray.1, (0.0, end));
        let f = het.delta_tracking(ray.0, ray.1, walk, true, rng);
        let w = Vec3::from(f.weight);
        self.beta *= w;
        self.d_beta *= w;
        self.d_sigma *= w;
        self.d_g *= w;
        let mut flight = Flight::through_vacuum();
        if f.collided {
            // The albedo there: the render's factor on the volume (1 as loaded) times
            // the volume's value; the gradient is the factor's, so the vertex weighs
            // the volume's value beside it.
            let volume_albedo = Vec3::from(f.albedo);
            flight.d_beta_before = self.d_beta * albedo * volume_albedo;
            let (a, b) = settings.estimand.vertex_factors(mi, albedo);
            self.d_beta = (self.d_beta * a + self.beta * b) * volume_albedo;
            self.beta *= albedo * volume_albedo;
            self.d_sigma *= albedo * volume_albedo;
            self.d_g *= albedo * volume_albedo;
            flight.scattered = true;
            flight.t = f.t;
        } else {
            flight.si = hit;
            flight.t = end;
        }
        // d/d scale (`volpath::Differentiated`), with β's α at a collision.
        if settings.estimand.extinction_medium() == Some(mi) {
            let score = het.flight_scale_score(ray, &f, end, true);
            self.d_sigma += self.beta * Vec3::from(score);
        }
        flight
    }

    /// A free flight in a homogeneous medium: a distance from the hero channel's σ_t,
    /// the surface cast for only where it may be nearer, then the chromatic weights.
    #[inline(always)]
    fn homogeneous_flight(
        &mut self,
        scene: &Scene,
        settings: &PathSettings,
        mi: u32,
        known_clearance: Option<f32>,
        rng: &mut Pcg32,
    ) -> Flight {
        let m = &scene.media[mi as usize];
        let t = m.sample_distance(self.hero, rng.next_1d());
        // Within the clearance no surface can be hit: the cast's answer is known. In a
        // convex medium the distance to its one shape is a clearance too, and an exact
        // one. Shadow rays are still played against the grid's alone (below): against
        // the convex one, the medium cube's shadow roulette cost more in variance (+6%
        // MSE) than it saved in time (−2%).
        let clearance = known_clearance.unwrap_or_else(|| scene.clearance.at(self.ray_o));
        let convex = scene.convex_media[mi as usize].as_ref();
        let skip_within = convex.map_or(clearance, |b| {
            b.clearance(&scene.geometries, self.ray_o).max(clearance)
        });
        let mut flight = Flight::through_vacuum();
        flight.t = t;
        flight.clearance = clearance;
        // Where the ray may end on an area emitter, it is cast in full (not only up to t,
        // nor skipped within the clearance), so the emission there can be counted in
        // expectation.
        flight.si = if scene.may_see_area_emitter(mi, self.ray_o, self.ray_d) {
            let full = scene.intersect_in_medium(mi, self.ray_o, self.ray_d, self.ray_tmax);
            if let Some(h) = &full {
                flight.emission_counted = self.emission_in_expectation(scene, settings, mi, h);
            }
            full.filter(|h| h.t < t)
        } else if t < skip_within {
            None
        } else {
            scene.intersect_in_medium(mi, self.ray_o, self.ray_d, t.min(self.ray_tmax))
        };
        flight.scattered = flight.si.is_none() && t.is_finite() && t <= self.ray_tmax;
        self.flight_weights(settings, mi, m, &mut flight);
        flight
    }

    /// Emission at the segment's end `h`, in expectation: the flight passes to it with
    /// probability T_hero(h.t) and then weighs the emission by β T / mean(r T) (the module
    /// comment of `volpath`): that product is counted now instead of its 0-or-1 sample,
    /// and not again at the hit. Whether there was emission to count.
    #[inline(always)]
    fn emission_in_expectation(
        &mut self,
        scene: &Scene,
        settings: &PathSettings,
        mi: u32,
        h: &SurfaceInteraction,
    ) -> bool {
        let m = &scene.media[mi as usize];
        let le = emission_seen(
            scene,
            Some(h),
            self.ray_d,
            self.depth,
            self.specular_chain,
            &self.last,
        );
        if le == Vec3::ZERO {
            return false;
        }
        let tr = m.transmittance(h.t);
        let pass: Vec3 = expected_pass_weight(tr.into(), tr[self.hero], self.r_u.into()).into();
        if pass.is_finite() {
            self.result += self.beta * pass * le;
            self.d_result += self.d_beta * pass * le;
            // ∂T/∂σ_t = −t T in the chosen medium.
            let d_sigma = match settings.estimand.extinction_medium() == Some(mi) {
                true => self.d_sigma - self.beta * h.t,
                false => self.d_sigma,
            };
            self.d_sigma_result += d_sigma * pass * le;
            self.d_g_result += self.d_g * pass * le;
        }
        true
    }

    /// The homogeneous flight's weights: α at a collision, and for chromatic σ_t the
    /// hero channel's f / p (`medium::collision_weight`, `pass_weight`), then mean(r) = 1.
    /// Where the extinction is differentiated, dβ/dσ_t beside them: f's ∂/∂σ_t with p
    /// detached (`volpath::Differentiated`).
    #[inline(always)]
    fn flight_weights(
        &mut self,
        settings: &PathSettings,
        mi: u32,
        m: &Medium,
        flight: &mut Flight,
    ) {
        let albedo = settings.albedo[mi as usize];
        let hero = self.hero;
        let chosen = settings.estimand.extinction_medium() == Some(mi);
        // The length passed through without a collision (where none happened).
        let passed = flight.si.as_ref().map_or(self.ray_tmax, |h| h.t);
        if m.is_grey() {
            // Grey σ_t: f and every p_c are alike, so w = T / T = 1 for passing and
            // σ_t T / (σ_t T) = 1 for a collision (exactly, in floating point too): only
            // α is left, r is unchanged, and no transmittance is needed.
            if flight.scattered {
                flight.d_beta_before = self.d_beta * albedo;
                let (a, b) = settings.estimand.vertex_factors(mi, albedo);
                self.d_beta = self.d_beta * a + self.beta * b;
                self.beta *= albedo;
                self.d_sigma *= albedo;
                self.d_g *= albedo;
                if chosen {
                    // ∂ ln(σ_t e^{−σ_t t}) = 1/σ_t − t.
                    self.d_sigma += self.beta * (1.0 / m.sigma_t.x - flight.t);
                }
            } else if chosen && passed.is_finite() {
                self.d_sigma -= self.beta * passed;
            }
            return;
        }
        let w: Vec3 = match &flight.si {
            // Passed the whole segment: f = T, p_c = T_c.
            Some(h) => {
                let tr = m.transmittance(h.t);
                pass_weight(tr.into(), tr[hero]).into()
            }
            None if flight.scattered => {
                // Collision at t: f = T σ_t α, p_c = σ_t,c T_c.
                let tr = m.transmittance(flight.t);
                let w: Vec3 =
                    collision_weight(tr.into(), m.sigma_t.into(), m.sigma_t[hero], tr[hero]).into();
                // d(β w α)/dα = dβ w α + β w in the chosen medium.
                flight.d_beta_before = self.d_beta * w * albedo;
                let (a, b) = settings.estimand.vertex_factors(mi, albedo);
                self.d_beta = self.d_beta * w * a + self.beta * w * b;
                self.d_sigma *= w * albedo;
                if chosen {
                    // ∂(σ_t T)/∂σ_t = T (1 − σ_t t), over the same (detached) p_hero.
                    let (sigma, sigma_hero) = (m.sigma_t.into(), m.sigma_t[hero]);
                    let dw: Vec3 =
                        collision_weight_d_sigma(tr.into(), sigma, flight.t, sigma_hero, tr[hero])
                            .into();
                    self.d_sigma += self.beta * dw * albedo;
                }
                self.d_g *= w * albedo;
                self.beta *= w * albedo;
                self.r_u *= w;
                // Weighted above (α with w), unlike the passes below.
                Vec3::ONE
            }
            // Left through the far end of the ray without a collision.
            None => {
                let tr = m.transmittance(self.ray_tmax);
                pass_weight(tr.into(), tr[hero]).into()
            }
        };
        if !flight.scattered {
            if chosen && passed.is_finite() {
                // ∂T/∂σ_t = −s T.
                self.d_sigma -= self.beta * passed;
            }
            self.beta *= w;
            self.d_beta *= w;
            self.d_sigma *= w;
            self.d_g *= w;
            self.r_u *= w;
        }
        // Keep mean(r) = 1: scaling β and r alike leaves β / mean(r) and every later
        // update unchanged, and keeps both bounded on long chromatic paths.
        let k = mean(self.r_u);
        self.beta /= k;
        self.d_beta /= k;
        self.d_sigma /= k;
        self.d_g /= k;
        flight.d_beta_before /= k;
        self.r_u /= k;
    }

    /// A scattering vertex in the medium at the flight's end: emitter sampling from it,
    /// then the phase function's sample for the next ray. False: the path ends
    /// (max_depth).
    #[inline(always)]
    pub(super) fn scatter_in_medium(
        &mut self,
        scene: &Scene,
        settings: &PathSettings,
        flight: &Flight,
        rng: &mut Pcg32,
    ) -> bool {
        self.null_crossings = 0;
        self.depth += 1;
        if self.depth >= scene.integrator.max_depth {
            return false;
        }
        self.valid = true;
        let mi = self.medium.expect("a medium vertex");
        let m = &scene.media[mi as usize];
        let g_chosen = settings.estimand.g_medium() == Some(mi);
        let (t, p) = (flight.t, self.ray_o + self.ray_d * flight.t);
        // ---- Emitter sampling from the medium vertex ----
        // p lies within the flight's clearance less t, and within its own, which the next
        // flight (from p) starts with. A heterogeneous medium has no use for either: its
        // shadow rays are not rouletted, and its flights are cast in full.
        let clearance = if m.heterogeneous.is_none() {
            let at_p = scene.clearance.at(p);
            self.origin_clearance = Some(at_p);
            (flight.clearance - t).max(at_p)
        } else {
            0.0
        };
        let d_in = self.ray_d;
        let mut diff = shadow_derivative(settings, &mut self.adjoint);
        let light = medium_emitter_sample(scene, mi, p, d_in, clearance, &mut diff, rng);
        if let Some(MediumLight {
            value: x,
            d_log_tr,
            d,
        }) = light
        {
            self.scatter_shadow(scene, settings, self.beta * x);
            self.result += self.beta * x;
            self.d_result += x * match settings.estimand.nee_ignores_vertex() {
                true => flight.d_beta_before,
                false => self.d_beta,
            };
            // The shadow ray's ∂ ln T and the phase value's ∂ ln p / ∂g.
            let d_log_tr = match settings.estimand.without_shadow_term() {
                true => Vec3::ZERO,
                false => d_log_tr,
            };
            self.d_sigma_result += x * (self.d_sigma + self.beta * d_log_tr);
            let score = match g_chosen {
                true => m.phase.log_derivative_g(1.0 - self.ray_d.dot(d) as f64),
                false => 0.0,
            };
            self.d_g_result += x * (self.d_g + self.beta * score);
        }
        self.specular_chain = !m.sample_emitters;
        // ---- Phase function sampling ----
        // f / p = 1 (exact sampling): with p detached, ∂f/∂g / p = ∂ ln p / ∂g.
        let (wo, pdf, w) = m.phase.sample_angle(self.ray_d, rng.next_2d());
        if g_chosen {
            self.d_g += self.beta * m.phase.log_derivative_g(w);
        }
        self.last = LastScatter { p, pdf };
        self.ray_o = p;
        self.ray_d = wo;
        self.ray_tmax = f32::INFINITY;
        true
    }

    /// The ray's end outside a medium collision: the emission seen there, then a null
    /// boundary crossed, or emitter and BSDF sampling at a surface. False: the path
    /// ends (escaped, absorbed, or a failed sample).
    #[inline(always)]
    pub(super) fn at_surface(
        &mut self,
        scene: &Scene,
        settings: &PathSettings,
        flight: Flight,
        rng: &mut Pcg32,
    ) -> bool {
        let s = &scene.integrator;
        let si = match self.medium {
            Some(_) => flight.si,
            None if s.hide_emitters && self.depth == 0 => {
                skip_emitters(scene, self.ray_o, self.ray_d, self.ray_tmax)
            }
            None => scene.intersect(self.ray_o, self.ray_d, self.ray_tmax),
        };
        if !flight.emission_counted {
            let le = emission_seen(
                scene,
                si.as_ref(),
                self.ray_d,
                self.depth,
                self.specular_chain,
                &self.last,
            );
            self.result += self.beta * le;
            self.d_result += self.d_beta * le;
            self.d_sigma_result += self.d_sigma * le;
            self.d_g_result += self.d_g * le;
            // At the camera ray's first intersection, as `aovs::seen_emission` traces it.
            if self.depth == 0 && self.null_crossings == 0 && self.medium.is_none() && si.is_some()
            {
                self.seen_emission = le;
            }
        }
        let Some(h) = si else { return false };
        let info = &scene.shapes[h.shape as usize];
        let bsdf = &scene.bsdfs[info.bsdf as usize];
        // ---- A null boundary: the ray goes on unchanged into the next medium ----
        // What the null BSDF's sample says (wo = ray_d, weight 1, not a scattering
        // vertex, no emitter sampling), without its frame changes and random numbers.
        if matches!(bsdf, Bsdf::Null) {
            self.null_crossings += 1;
            if self.null_crossings > MAX_NULL_CROSSINGS {
                return false;
            }
            self.medium = medium_after(info, h.n, self.ray_d, self.medium);
            self.ray_o = h.offset_p(self.ray_d, scene.offset_scale);
            self.ray_tmax = f32::INFINITY;
            return true;
        }
        self.scatter_at_surface(scene, settings, &h, bsdf, rng)
    }

    /// Emitter sampling from the surface `h`, then the BSDF's sample for the next ray.
    #[inline(always)]
    fn scatter_at_surface(
        &mut self,
        scene: &Scene,
        settings: &PathSettings,
        h: &SurfaceInteraction,
        bsdf: &Bsdf,
        rng: &mut Pcg32,
    ) -> bool {
        let info = &scene.shapes[h.shape as usize];
        let wi = h.sh_frame.to_local(-self.ray_d);
        // ---- Emitter sampling from the surface ----
        if bsdf.is_smooth()
            && !scene.emitters.is_empty()
            && self.depth + 1 < scene.integrator.max_depth
        {
            let u = rng.next_2d();
            let medium = self.medium;
            let mut diff = shadow_derivative(settings, &mut self.adjoint);
            let mut d_log_tr = Vec3::ZERO;
            let transmittance = |o, d, dist| {
                let medium = medium_after(info, h.n, d, medium);
                let ray = ShadowRay { o, d, dist, medium };
                let through = shadow_transmittance(scene, ray, &mut diff, rng);
                d_log_tr = through.d_log.into();
                through.tr.into()
            };
            if let Some(ls) = sample_light_at_surface(scene, h, wi, bsdf, u, transmittance) {
                let w = if ls.delta {
                    1.0
                } else {
                    mis_weight(ls.emitter_pdf, ls.bsdf_pdf)
                };
                self.scatter_shadow(scene, settings, self.beta * ls.value * w);
                self.result += self.beta * ls.value * w;
                self.d_result += self.d_beta * ls.value * w;
                if settings.estimand.without_shadow_term() {
                    d_log_tr = Vec3::ZERO;
                }
                self.d_sigma_result += (self.d_sigma + self.beta * d_log_tr) * ls.value * w;
                self.d_g_result += self.d_g * ls.value * w;
            }
        }
        // ---- BSDF sampling ----
        let s1 = rng.next_1d();
        let s2 = rng.next_2d();
        let sampled = bsdf.sample(wi, s1, s2, h.uv);
        // A failed sample is not a null one (Mitsuba tests the sampled lobe's flags).
        self.valid |= !sampled.is_some_and(|b| b.null);
        let Some(bs) = sampled else {
            return false;
        };
        let wo = h.sh_frame.to_world(bs.wo);
        self.beta *= bs.weight;
        self.d_beta *= bs.weight;
        self.d_sigma *= bs.weight;
        self.d_g *= bs.weight;
        self.eta *= bs.eta;
        if bs.null {
            self.null_crossings += 1;
            if self.null_crossings > MAX_NULL_CROSSINGS {
                return false;
            }
        } else {
            self.null_crossings = 0;
            self.depth += 1;
            self.last = LastScatter {
                p: h.p,
                pdf: bs.pdf,
            };
            self.specular_chain = bs.delta;
        }
        self.medium = medium_after(info, h.n, wo, self.medium);
        self.ray_o = h.offset_p(wo, scene.offset_scale);
        self.ray_d = wo;
        self.ray_tmax = f32::INFINITY;
        true
    }
}
