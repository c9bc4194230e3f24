//! Mitsuba 3's `heterogeneous` medium (`src/media/heterogeneous.cpp`): extinction and
//! albedo given by volumes, σ_t(x) = scale · sigma_t(x), σ_s(x) = albedo(x) σ_t(x).
//! The extinction exists only within the sigma_t volume's bounding box (Mitsuba's
//! `intersect_aabb` bounds every free flight to it); outside, the medium is vacuum.
//!
//! Free flights by delta tracking (Woodcock; Mitsuba's `volpath` with
//! `has_spectral_extinction`): tentative collisions at rate σ̄ = scale · max(sigma_t)
//! (one majorant for all channels); at each, a real collision with probability
//! P = mean_c(σ_t,c / σ̄), else a null one. The weights that keep the estimator
//! unbiased per channel (Novák et al. 2018, "Monte Carlo methods for volumetric light
//! transport simulation", Sec. 5.2, with a spectral mixture of the three channels'
//! probabilities) are σ_n / mean(σ_n) for a null collision and σ_t / mean(σ_t) (times
//! the albedo) for a real one, σ_n = σ̄ − σ_t. For a grey σ_t both are 1 (and α).
//!
//! Transmittance along shadow rays by ratio tracking (Novák et al. 2014, "Residual
//! ratio tracking for estimating attenuation in participating media", Eq. 5): the
//! product of σ_n / σ̄ over tentative collisions, whose expectation is
//! `exp(−∫ σ_t)` per channel (Mitsuba's volpath estimates it the same way).
//!
//! Both are written once over the number type (one path, or lanes of paths) and draw
//! their tentative collisions by one loop over the ray's majorant segments
//! (`medium::tracking`, pbrt-v4's `SampleT_maj`): where σ_t is a clamped grid the
//! segments are the cells of its local majorants (`medium::majorant`), each at its own
//! σ̄, with the weights above taken against that σ̄; elsewhere one segment over the
//! span at the global σ̄ (as the lanes walk every grid). Any majorant gives the same
//! expectation.
//!
//! A `homogeneous` medium whose albedo is a grid also lands here, with a constant
//! unbounded σ_t: then σ̄ = σ_t for grey extinction and no null collision happens.

use glam::{Vec3, Vec3A};

use super::grid::Volume;
use super::lookup_bounds::LookupBounds;
use super::majorant::{self, MajorantGrid};
use super::tracking::{sample_t_maj, MajorantSegment, MajorantSegments, MajorantWalk, OneSegment};
#[cfg(test)]
use crate::sampling::Pcg32;
use crate::sampling::Sampler;
use crate::simd::{Float, Gather, Vector3};

/// Grids of more values than this get lookup bounds: the bounds save reads that miss the
/// cache, and cost a little more than they save on a grid that stays in it.
const BOUNDED_LOOKUPS_FROM: usize = 1 << 20;

#[derive(Clone, Debug)]
pub struct HeterogeneousMedium {
    /// Extinction before `scale`.
    pub sigma_t: Volume,
    pub albedo: Volume,
    pub scale: f32,
    /// σ̄ = scale · max(sigma_t) (Mitsuba's `m_max_density`).
    pub majorant: f32,
    /// Whether the extinction ends at sigma_t's box (`heterogeneous`), or fills all
    /// space (a `homogeneous` medium with a volume albedo).
    pub bounded: bool,
    /// Local majorants, where sigma_t is a clamped grid (else `majorant` everywhere).
    pub majorants: Option<MajorantGrid>,
    /// Bounds on sigma_t's lookups where it is a one-channel clamped grid, with which
    /// delta tracking decides most tentative collisions unread (`lookup_bounds`).
    pub bounds: Option<LookupBounds>,
}

/// Where free flights by delta tracking ended, per path: at a real collision
/// (`collided`, at `t`, the albedo volume's value there) or past their segments (`t`
/// is then 0 and the albedo 1), and the weight each contributes
/// (`HeterogeneousMedium::delta_tracking`).
pub struct FlightEnd<F: Float> {
    pub collided: F::Mask,
    pub t: F,
    pub weight: Vector3<F>,
    pub albedo: Vector3<F>,
}

/// What a free flight found: a real collision, or none before `tmax`.
#[cfg(test)]
pub struct Collision {
    pub t: f32,
    /// The albedo there (before the render's global factor on it).
    pub albedo: Vec3,
}

impl HeterogeneousMedium {
    /// The ray's stretch [t0, t1] ⊂ [0, tmax] in which extinction can be non-zero.
    #[inline]
    pub fn span(&self, o: Vec3A, d: Vec3A, tmax: f32) -> Option<(f32, f32)> {
        let (t0, t1, some) = self.span_at(o.into(), d.into(), (0.0, tmax));
        some.then_some((t0, t1))
    }

    /// [`HeterogeneousMedium::span`] over any number type: the stretches [t0, t1] ⊂
    /// [tmin, tmax] of the rays from `o` along `d`, and the paths where one is not
    /// empty.
    #[inline(always)]
    pub fn span_at<F: Gather>(
        &self,
        o: Vector3<F>,
        d: Vector3<F>,
        (tmin, tmax): (F, F),
    ) -> (F, F, F::Mask) {
        if !self.bounded {
            return (tmin, tmax, tmin.le(tmax));
        }
        let [lo, hi] = self.sigma_t.bbox;
        let bbox = [Vec3A::from(lo), Vec3A::from(hi)];
        F::box_span(bbox, F::point(o), F::point(d), (tmin, tmax))
    }

    /// The rays' one majorant segment each: the span within [tmin, tmax] at the global
    /// σ̄ (none where σ̄ = 0), the walk the lanes track along.
    #[inline(always)]
    pub fn global_segment<F: Gather>(
        &self,
        o: Vector3<F>,
        d: Vector3<F>,
        (tmin, tmax): (F, F),
    ) -> OneSegment<F> {
        let (t_min, t_max, some) = self.span_at(o, d, (tmin, tmax));
        let sigma_maj = F::of(self.majorant as f64);
        OneSegment {
            segment: MajorantSegment {
                t_min,
                t_max,
                sigma_maj,
            },
            some: some & sigma_maj.gt(F::zero()),
        }
    }

    /// An unbiased estimate of ∫ σ (σ_t before `scale`) over the segment from `o` along
    /// unit `d` of length `len`: the span's length times σ at one uniform point of it,
    /// the point chosen by a hash of the segment, apart from the random numbers of the
    /// tracking along it (their product stays unbiased: the two are independent). For
    /// the derivative in `scale` (∂ ln T / ∂ scale = −∫ σ). 0 where it is not finite
    /// (an unbounded segment: its transmittance is 0).
    pub fn depth_estimate(&self, o: Vec3A, d: Vec3A, len: f32) -> Vec3 {
        let Some((t0, t1)) = self.span(o, d, len) else {
            return Vec3::ZERO;
        };
        let u = segment_hash(o, d, len);
        let depth = self.sigma_t.eval(o + d * (t0 + u * (t1 - t0))) * (t1 - t0);
        if depth.is_finite() {
            depth
        } else {
            Vec3::ZERO
        }
    }

    /// The medium of extinction `sigma_t` × `scale` and albedo `albedo`, with its
    /// majorants (`set_scale`).
    pub fn new(sigma_t: Volume, albedo: Volume, scale: f32, bounded: bool) -> HeterogeneousMedium {
        let mut m = HeterogeneousMedium {
            bounds: match sigma_t.values() > BOUNDED_LOOKUPS_FROM {
                true => LookupBounds::new(&sigma_t),
                false => None,
            },
            sigma_t,
            albedo,
            scale,
            majorant: 0.0,
            bounded,
            majorants: None,
        };
        m.set_scale(scale);
        m
    }

    /// The same medium with other extinction and albedo volumes (its majorants and
    /// lookup bounds made for them, as the loader makes them).
    pub fn with_volumes(&self, sigma_t: Volume, albedo: Volume) -> HeterogeneousMedium {
        HeterogeneousMedium::new(sigma_t, albedo, self.scale, self.bounded)
    }

    /// The medium at density `scale`: σ̄ and, for a bounded medium, the local
    /// majorants made for it (a pass over the grid: cheap beside a render), as the
    /// loader makes them (it calls `new`), so that a fit's medium is the one
    /// `-D scale=…` loads.
    pub fn set_scale(&mut self, scale: f32) {
        self.scale = scale;
        self.majorant = self.sigma_t.max * scale;
        self.majorants = match self.bounded {
            true => MajorantGrid::new(&self.sigma_t, scale),
            false => None,
        };
    }

    /// σ_t at `p` (with `scale`).
    #[inline]
    pub fn sigma_t_at(&self, p: Vec3A) -> Vec3 {
        self.sigma_t.eval(p) * self.scale
    }

    /// Delta tracking from `o` along unit `d` up to `tmax` on one path, for tests: the
    /// first real collision, if any, and the path weight the flight contributes.
    #[cfg(test)]
    pub fn sample_flight(
        &self,
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
        rng: &mut Pcg32,
    ) -> (Option<Collision>, Vec3) {
        let segments = self.majorant_segments(o, d, (0.0, tmax));
        let f = self.delta_tracking(o.into(), d.into(), segments, true, rng);
        let collision = f.collided.then(|| Collision {
            t: f.t,
            albedo: f.albedo.into(),
        });
        (collision, f.weight.into())
    }

    /// Delta tracking along `segments` of the rays from `o` along unit `d`, for the
    /// paths of `mask`: where each flight ends, its first real collision if any, and the
    /// path weight it contributes (product of the null collisions' σ_n / mean(σ_n),
    /// times σ_t / mean(σ_t) at the real one; all ones for grey σ_t). The render's
    /// albedo factor is left to the caller.
    #[inline(always)]
    pub fn delta_tracking<F: Gather, S: Sampler<F> + ?Sized>(
        &self,
        o: Vector3<F>,
        d: Vector3<F>,
        segments: impl MajorantWalk<F>,
        mask: F::Mask,
        sampler: &mut S,
    ) -> FlightEnd<F> {
        let (o, d) = (F::point(o), F::point(d));
        let mut weight = Vector3::all(F::one());
        let mut at = F::zero();
        let mut collided = mask & !mask;
        let scale = F::of(self.scale as f64);
        // Grey σ_t: both weights are 1 (exactly, where rounding would make them 1 ± ulp).
        let grey = self.sigma_t.is_grey();
        sample_t_maj(
            segments,
            mask,
            sampler,
            #[inline(always)]
            |t, major, active, sampler| {
                let q: [F; 3] = self.sigma_t.local_point(F::along(o, d, t));
                // Real with probability P = mean(σ_t) / σ̄, else null; the grid read only
                // where its bounds leave the answer open.
                let u = sampler.draw_1d(active);
                let none = active & !active;
                let (sure_real, sure_null) = self
                    .decided_by_bounds_at(q, u, major, active)
                    .unwrap_or((none, none));
                let look = active & !(sure_real | sure_null);
                let sigma_t = match F::any(look) {
                    true => self.sigma_t.eval_local(q, look).scale(scale),
                    false => Vector3::all(F::zero()),
                };
                let real = sure_real | (look & u.lt(real_probability(sigma_t, major)));
                if F::any(real) {
                    if !grey {
                        weight = weight.select(look & real, weight.mul(real_weight(sigma_t)));
                    }
                    at = F::select(real, t, at);
                    collided = collided | real;
                }
                // No null collision can happen where σ_n is 0 in every channel (σ_t at the
                // majorant): the flight passes with weight 0 there. (A null the bounds
                // decide has σ_t below σ̄.)
                let null = active & !real & look;
                let (null_w, stuck) = null_weight(sigma_t, major);
                let stuck = null & stuck;
                weight = weight.select(stuck, Vector3::all(F::zero()));
                if !grey {
                    weight = weight.select(null & !stuck, weight.mul(null_w));
                }
                real | stuck
            },
        );
        // The albedo at the collisions, looked up once the loop is done (fewer values
        // live across its draws).
        let ones = Vector3::all(F::one());
        let albedo = match F::any(collided) {
            true => ones.select(
                collided,
                self.albedo.eval_at(F::vector(F::along(o, d, at)), collided),
            ),
            false => ones,
        };
        FlightEnd {
            collided,
            t: at,
            weight,
            albedo,
        }
    }

    /// Whether the lookup bounds alone decide delta tracking's tentative collisions at
    /// points `q` of sigma_t's unit cube (`Volume::local_point`) with draws `u` at
    /// majorants `major`: of the paths of `mask`, those the bounds make real
    /// (u < P(lo)) and those they make null (u ≥ P(hi)), the others' grid to be read;
    /// None where the medium has no bounds. P rises with σ_t, so each answer is the one
    /// the lookup would give.
    #[inline(always)]
    pub fn decided_by_bounds_at<F: Gather>(
        &self,
        q: [F; 3],
        u: F,
        major: F,
        mask: F::Mask,
    ) -> Option<(F::Mask, F::Mask)> {
        let lo_hi = self.bounds.as_ref()?.at_lanes(q, mask);
        let (real, null) = bounds_decision(lo_hi, u, F::of(self.scale as f64), major);
        Some((mask & real, mask & null))
    }

    /// Ratio tracking: an unbiased estimate of `exp(−∫₀^dist σ_t)` from `o` along `d`,
    /// on one path, for tests (renders call `Medium::segment_transmittance`).
    #[cfg(test)]
    pub fn transmittance(&self, o: Vec3A, d: Vec3A, dist: f32, rng: &mut Pcg32) -> Vec3 {
        let segments = self.majorant_segments(o, d, (0.0, dist));
        self.ratio_tracking(o.into(), d.into(), segments, true, rng)
            .into()
    }

    /// Ratio tracking along `segments` of the rays from `o` along unit `d`, for the
    /// paths of `mask` (1 elsewhere): [`HeterogeneousMedium::transmittance`] over any
    /// number type, with its Russian roulette.
    #[inline(always)]
    pub fn ratio_tracking<F: Gather, S: Sampler<F> + ?Sized>(
        &self,
        o: Vector3<F>,
        d: Vector3<F>,
        segments: impl MajorantWalk<F>,
        mask: F::Mask,
        sampler: &mut S,
    ) -> Vector3<F> {
        let (o, d) = (F::point(o), F::point(d));
        let mut tr = Vector3::all(F::one());
        let scale = F::of(self.scale as f64);
        let survival = F::of(RATIO_SURVIVAL as f64);
        sample_t_maj(
            segments,
            mask,
            sampler,
            #[inline(always)]
            |t, major, active, sampler| {
                let q: [F; 3] = self.sigma_t.local_point(F::along(o, d, t));
                // Where the bounds say the cell is empty σ_t is 0 and the factor exactly 1:
                // no read.
                let look = match &self.bounds {
                    Some(b) => active & b.at_lanes(q, active)[1].gt(F::zero()),
                    None => active,
                };
                let sigma_t = match F::any(look) {
                    true => self.sigma_t.eval_local(q, look).scale(scale),
                    false => Vector3::all(F::zero()),
                };
                tr = tr.select(active, ratio_weight(sigma_t, major).mul(tr));
                // Russian roulette once little is left (unbiased: survivors weigh 1/q); a
                // draw only where something is left.
                let (play, end) = ratio_roulette(tr.max_element());
                let (play, end) = (active & play, active & end);
                let mut ended = end;
                if F::any(play) {
                    let u = sampler.draw_1d(play);
                    let lost = play & u.ge(survival);
                    ended = ended | lost;
                    tr = tr.select(play & !lost, tr.scale(F::one() / survival));
                }
                tr = tr.select(ended, Vector3::all(F::zero()));
                ended
            },
        );
        tr
    }

    /// The majorant segments of `o + t d` within the span in [tmin, tmax] (pbrt-v4's
    /// `SampleRay`): the cells of the local majorants where there are some, else the
    /// span at the global one; none where the ray misses the medium or σ̄ = 0.
    pub fn majorant_segments(
        &self,
        o: Vec3A,
        d: Vec3A,
        (tmin, tmax): (f32, f32),
    ) -> MajorantSegments<'_> {
        let (t0, t1, some) = self.span_at(o.into(), d.into(), (tmin, tmax));
        let span = (some && self.majorant > 0.0).then_some((t0, t1));
        match (span, &self.majorants) {
            (Some(span), Some(grid)) => {
                let (ol, dl) = majorant::to_local(&self.sigma_t, o, d);
                MajorantSegments::Cells(grid.segments(ol, dl, span))
            }
            (span, _) => MajorantSegments::One(span.map(|(t_min, t_max)| MajorantSegment {
                t_min,
                t_max,
                sigma_maj: self.majorant,
            })),
        }
    }
}

/// A uniform number in [0, 1) from the bits of a segment (splitmix64's finaliser over
/// them): a draw that does not disturb the path's own random stream.
fn segment_hash(o: Vec3A, d: Vec3A, len: f32) -> f32 {
    let mut h = 0x9e37_79b9_7f4a_7c15u64;
    for x in [o.x, o.y, o.z, d.x, d.y, d.z, len] {
        h ^= x.to_bits() as u64;
        h = h.wrapping_mul(0xbf58_476d_1ce4_e5b9);
        h ^= h >> 31;
        h = h.wrapping_mul(0x94d0_49bb_1331_11eb);
        h ^= h >> 29;
    }
    (h >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
}

/// The probability that a tentative collision at σ_t is real: P = mean(σ_t) / σ̄
/// (the spectral mixture of the channels' σ_t,c / σ̄).
#[inline(always)]
pub fn real_probability<F: Float>(sigma_t: Vector3<F>, major: F) -> F {
    sigma_t.mean() / major
}

/// Delta tracking's answer from the lookup bounds [lo, hi] (before `scale`) at a
/// tentative collision with draw `u`: (surely real: u < P(lo), surely null: u ≥ P(hi)),
/// P rising with σ_t (`lookup_bounds`).
#[inline(always)]
pub fn bounds_decision<F: Float>([lo, hi]: [F; 2], u: F, scale: F, major: F) -> (F::Mask, F::Mask) {
    let p = |v: F| real_probability(Vector3::all(v * scale), major);
    (u.lt(p(lo)), u.ge(p(hi)))
}

/// A real collision's weight per channel, σ_t / mean(σ_t) (the albedo apart).
#[inline(always)]
pub fn real_weight<F: Float>(sigma_t: Vector3<F>) -> Vector3<F> {
    sigma_t.div(sigma_t.mean())
}

/// A null collision's weight per channel, σ_n / mean(σ_n) with σ_n = σ̄ − σ_t, and
/// where no null collision can happen (σ_n = 0 in every channel: σ_t at the majorant):
/// the flight then passes with weight 0.
#[inline(always)]
pub fn null_weight<F: Float>(sigma_t: Vector3<F>, major: F) -> (Vector3<F>, F::Mask) {
    let sigma_n = Vector3::all(major).sub(sigma_t);
    let m = sigma_n.mean();
    (sigma_n.div(m), m.le(F::zero()))
}

/// Ratio tracking's factor at a tentative collision: σ_n / σ̄ per channel.
#[inline(always)]
pub fn ratio_weight<F: Float>(sigma_t: Vector3<F>, major: F) -> Vector3<F> {
    Vector3::all(major).sub(sigma_t).div(major)
}

/// Below this largest channel, ratio tracking plays Russian roulette.
pub const RATIO_ROULETTE_BELOW: f32 = 0.1;
/// The probability a rouletted ratio-tracking estimate goes on (it then weighs 1/q).
pub const RATIO_SURVIVAL: f32 = 0.5;

/// Ratio tracking's Russian roulette once its estimate's largest channel `m` is below
/// [`RATIO_ROULETTE_BELOW`]: where something is left a draw decides (`play`), where
/// nothing is the estimate ends at 0 (`end`); elsewhere it goes on with no draw.
#[inline(always)]
pub fn ratio_roulette<F: Float>(m: F) -> (F::Mask, F::Mask) {
    let low = m.lt(F::of(RATIO_ROULETTE_BELOW as f64));
    let left = m.gt(F::zero());
    (low & left, low & !left)
}

#[cfg(test)]
mod tests;
