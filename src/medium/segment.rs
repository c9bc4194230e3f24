//! What one stretch of a medium lets through, for every medium and number type at
//! once (pbrt-v4's `SampleT_maj` serving homogeneous media as one segment): the
//! transmittance T = e^{−∫σ_t} per channel, exact (Beer–Lambert) where σ_t is constant,
//! ratio tracking's unbiased estimate where it varies (`heterogeneous`), and the
//! derivative forward mode takes in the medium's extinction parameter,
//!
//!   ∂ ln T / ∂σ_t = −ℓ  (homogeneous, over the length ℓ),
//!   ∂ ln T / ∂scale = −∫σ  (heterogeneous, σ_t = scale · σ; one lookup's estimate),   (1)
//!
//! carried as ∂ ln T so that ∂T = T ∂ ln T needs no division by T, and the product of
//! segments is a sum of theirs. Shadow rays on one path and in lanes call this one
//! definition; what differs between them is only how a heterogeneous medium's majorants
//! are walked ([`Tracked`]).

use glam::Vec3A;
use wide::f32x8;

use super::heterogeneous::{FlightEnd, HeterogeneousMedium};
use super::tracking::{MajorantSegments, MajorantWalk, OneSegment};
use super::{transmittance_at, transmittance_rgb, Medium};
use crate::sampling::Sampler;
use crate::simd::{Float, Gather, Vector3};

/// What stretches of media let through, per path: the transmittance `tr` and
/// `d_log` = ∂ ln T (1) in the differentiated medium's extinction (0 where none is).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transmitted<F> {
    pub tr: Vector3<F>,
    pub d_log: Vector3<F>,
}

impl<F: Float> Transmitted<F> {
    /// Nothing in the way.
    #[inline(always)]
    pub fn clear() -> Self {
        Transmitted {
            tr: Vector3::all(F::one()),
            d_log: Vector3::all(F::zero()),
        }
    }

    /// Nothing let through.
    #[inline(always)]
    pub fn blocked() -> Self {
        Transmitted {
            tr: Vector3::all(F::zero()),
            d_log: Vector3::all(F::zero()),
        }
    }

    /// Through this, then `next`: the transmittances multiply, their logarithms add.
    #[inline(always)]
    pub fn then(self, next: Self) -> Self {
        Transmitted {
            tr: self.tr.mul(next.tr),
            d_log: self.d_log.add(next.d_log),
        }
    }
}

/// A number type heterogeneous media are tracked over, and how: one path walks the
/// cells of the local majorants where the medium has them; lanes take one segment each
/// at the global majorant (`medium::tracking`'s module comment says why).
pub trait Tracked: Gather {
    type Walk<'a>: MajorantWalk<Self>;

    /// The majorant segments of the rays `o + t d` within [tmin, tmax].
    fn majorant_walk<'a>(
        h: &'a HeterogeneousMedium,
        o: Vector3<Self>,
        d: Vector3<Self>,
        span: (Self, Self),
    ) -> Self::Walk<'a>;

    /// `HeterogeneousMedium::depth_estimate` (∫σ, one lookup's estimate) over the
    /// stretches [tmin, tmax], in the paths of `mask` (0 elsewhere).
    fn depth_estimate(
        h: &HeterogeneousMedium,
        o: Vector3<Self>,
        d: Vector3<Self>,
        span: (Self, Self),
        mask: Self::Mask,
    ) -> Vector3<Self>;
}

impl Tracked for f32 {
    type Walk<'a> = MajorantSegments<'a>;

    #[inline(always)]
    fn majorant_walk<'a>(
        h: &'a HeterogeneousMedium,
        o: Vector3<f32>,
        d: Vector3<f32>,
        span: (f32, f32),
    ) -> MajorantSegments<'a> {
        h.majorant_segments(o.into(), d.into(), span)
    }

    #[inline(always)]
    fn depth_estimate(
        h: &HeterogeneousMedium,
        o: Vector3<f32>,
        d: Vector3<f32>,
        (tmin, tmax): (f32, f32),
        mask: bool,
    ) -> Vector3<f32> {
        let (o, d) = (Vec3A::from(o), Vec3A::from(d));
        match mask {
            true => h.depth_estimate(o + d * tmin, d, tmax - tmin).into(),
            false => Vector3::all(0.0),
        }
    }
}

impl Tracked for f32x8 {
    type Walk<'a> = OneSegment<f32x8>;

    #[inline(always)]
    fn majorant_walk(
        h: &HeterogeneousMedium,
        o: Vector3<f32x8>,
        d: Vector3<f32x8>,
        span: (f32x8, f32x8),
    ) -> OneSegment<f32x8> {
        h.global_segment(o, d, span)
    }

    /// Lane by lane: one lookup a segment.
    fn depth_estimate(
        h: &HeterogeneousMedium,
        o: Vector3<f32x8>,
        d: Vector3<f32x8>,
        (tmin, tmax): (f32x8, f32x8),
        mask: f32x8,
    ) -> Vector3<f32x8> {
        let (t0, t1) = (tmin.to_array(), tmax.to_array());
        let bits = mask.move_mask();
        Vector3::from_fn(|k| match bits >> k & 1 {
            1 => {
                let (o, d) = (o.lane(k).into(), d.lane(k).into());
                f32::depth_estimate(h, o, d, (t0[k], t1[k]), true).into()
            }
            _ => glam::Vec3::ZERO,
        })
    }
}

impl HeterogeneousMedium {
    /// ∂ ln f / ∂scale of free flights by delta tracking (σ_t = scale · σ, `volpath`'s
    /// `Differentiated`), in the paths of `mask` (0 elsewhere): 1/scale − ∫₀ᵗ σ for a
    /// real collision at t, −∫₀^end σ (1) for a flight past its segment's end, each
    /// integral one lookup's estimate (`depth_estimate`).
    #[inline(always)]
    pub fn flight_scale_score<F: Tracked>(
        &self,
        (o, d): (Vector3<F>, Vector3<F>),
        end: &FlightEnd<F>,
        t_end: F,
        mask: F::Mask,
    ) -> Vector3<F> {
        let t = F::select(end.collided, end.t, t_end);
        let depth = F::depth_estimate(self, o, d, (F::zero(), t), mask);
        let s = F::select(end.collided, F::of((1.0 / self.scale) as f64), F::zero());
        Vector3::all(s).sub(depth)
    }
}

impl Medium {
    /// What the stretches [tmin, tmax] of the rays from `o` along unit `d` in this
    /// medium let through, in the paths of `mask` (clear elsewhere), with ∂ ln T (1)
    /// where `differentiated` (its extinction is the render's parameter); a
    /// heterogeneous medium's estimate draws from `sampler`.
    #[inline(always)]
    pub fn segment_transmittance<F: Tracked, S: Sampler<F> + ?Sized>(
        &self,
        (o, d): (Vector3<F>, Vector3<F>),
        (tmin, tmax): (F, F),
        mask: F::Mask,
        differentiated: bool,
        sampler: &mut S,
    ) -> Transmitted<F> {
        let mut out = Transmitted::clear();
        if !F::any(mask) {
            return out;
        }
        match self.heterogeneous.as_deref() {
            None => {
                let len = F::select(mask, tmax - tmin, F::zero());
                // A grey σ_t (most media) takes one exponential, not three.
                out.tr = match self.is_grey() {
                    true => Vector3::all(transmittance_at(F::of(self.sigma_t.x as f64), len)),
                    false => transmittance_rgb(Vector3::splat(self.sigma_t), len),
                };
                if differentiated {
                    out.d_log = Vector3::all(len.negate());
                }
            }
            Some(h) => {
                let walk = F::majorant_walk(h, o, d, (tmin, tmax));
                out.tr = h.ratio_tracking(o, d, walk, mask, sampler);
                if differentiated {
                    let depth = F::depth_estimate(h, o, d, (tmin, tmax), mask);
                    out.d_log = Vector3::new(depth.x.negate(), depth.y.negate(), depth.z.negate());
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Pcg32;
    use glam::Vec3;
    use wide::CmpNe;

    fn medium(sigma_t: Vec3) -> Medium {
        Medium {
            albedo: Vec3::splat(0.5),
            sigma_t,
            scale: 1.0,
            phase: crate::medium::Phase::Isotropic,
            sample_emitters: true,
            id: None,
            heterogeneous: None,
        }
    }

    /// A homogeneous stretch lets through e^{−σ_t ℓ} with ∂ ln T = −ℓ, the lanes as one
    /// path (∂ ln T to the bit, T to `wide`'s exp), grey or not; lanes off the mask are
    /// clear. Power: a stretch 1% longer changes T.
    #[test]
    fn homogeneous_stretches_in_lanes_as_on_one_path() {
        let mut rng = Pcg32::new(3, 5);
        let mut rngs: [Pcg32; 8] = std::array::from_fn(|k| Pcg32::new(k as u64, 0));
        for sigma_t in [Vec3::splat(1.3), Vec3::new(0.4, 2.0, 7.5)] {
            let m = medium(sigma_t);
            let z = Vector3::all(0.0f32);
            let t0: [f32; 8] = std::array::from_fn(|k| k as f32 * 0.1);
            let t1: [f32; 8] = std::array::from_fn(|k| t0[k] + 0.3 * k as f32 + 0.05);
            let lane_index = f32x8::from(std::array::from_fn::<f32, 8, _>(|k| k as f32));
            let mask = lane_index.cmp_ne(f32x8::splat(5.0));
            let lanes = m.segment_transmittance(
                (Vector3::all(f32x8::ZERO), Vector3::all(f32x8::ZERO)),
                (f32x8::from(t0), f32x8::from(t1)),
                mask,
                true,
                &mut rngs[..],
            );
            for k in 0..8 {
                let one = m.segment_transmittance((z, z), (t0[k], t1[k]), k != 5, true, &mut rng);
                let got = |v: Vector3<f32x8>| {
                    Vec3::new(v.x.to_array()[k], v.y.to_array()[k], v.z.to_array()[k])
                };
                // `wide`'s exp is within a few ulp of libm's.
                let (a, b) = (got(lanes.tr), Vec3::from(one.tr));
                assert!(
                    (a - b).abs().max_element() <= 1e-6 * b.max_element(),
                    "lane {k}: {a} vs {b}"
                );
                assert_eq!(got(lanes.d_log), Vec3::from(one.d_log), "lane {k}");
                if k == 5 {
                    assert_eq!(Vec3::from(one.tr), Vec3::ONE);
                    continue;
                }
                let len = t1[k] - t0[k];
                let want = (-sigma_t * len).exp();
                assert!(
                    (Vec3::from(one.tr) - want).abs().max_element() <= 1e-6,
                    "lane {k}"
                );
                assert_eq!(Vec3::from(one.d_log), Vec3::splat(-len));
                let longer = m.segment_transmittance(
                    (z, z),
                    (t0[k], t0[k] + len * 1.01),
                    true,
                    false,
                    &mut rng,
                );
                assert_ne!(longer.tr, one.tr, "lane {k}");
            }
        }
    }
}
