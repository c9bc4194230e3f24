//! Participating media: Mitsuba 3's `homogeneous` medium (`src/media/homogeneous.cpp`)
//! with the `hg` or `isotropic` phase function (`src/phase/hg.cpp`).
//! Media that vary in space (`heterogeneous`, volumes from `grid`) are tracked
//! instead (`heterogeneous`); this file's sampling is the homogeneous case.
//!
//! Free-flight distances are sampled from σ_t of one colour channel (Mitsuba's
//! `Medium::sample_interaction`), never from the albedo: `t = −ln(1 − u) / σ_t[c]`,
//! with pdf `σ_t[c] e^{−σ_t[c] t}` for a collision at `t` and `e^{−σ_t[c] s}` for passing
//! a whole segment of length `s`. Transmittance along a segment is `e^{−σ_t s}` per
//! channel (Beer–Lambert).

pub mod differential;
pub mod grid;
pub mod heterogeneous;
pub mod lookup_bounds;
pub mod majorant;
pub mod phase;
pub mod segment;
pub mod tracking;

use glam::Vec3;

use crate::simd::{Float, Vector3};

pub use heterogeneous::HeterogeneousMedium;
pub use phase::Phase;
pub use segment::{Tracked, Transmitted};

/// A participating medium as the scene holds it (Mitsuba's `Medium`): the homogeneous
/// case in full, or, where `heterogeneous` is set, the medium that varies in space with
/// its majorant and global albedo factor here.
#[derive(Clone, Debug)]
pub struct Medium {
    /// Single-scattering albedo σ_s / σ_t, per channel, in [0, 1].
    pub albedo: Vec3,
    /// Extinction σ_t (already multiplied by `scale`), per channel, ≥ 0.
    pub sigma_t: Vec3,
    /// The XML `scale` (σ_t above holds it; a heterogeneous medium's is its own).
    pub scale: f32,
    pub phase: Phase,
    /// Next-event estimation at scattering vertices in this medium (Mitsuba's
    /// `sample_emitters`, default true).
    pub sample_emitters: bool,
    /// The XML `id`, to name the medium (e.g. `--gradient albedo --medium ID`).
    pub id: Option<String>,
    /// Set for a medium that varies in space (`heterogeneous`, or a volume albedo):
    /// the volpath then tracks it (`heterogeneous`), and `sigma_t` above holds its
    /// majorant (an upper bound), `albedo` a global factor on its albedo volume (1 as
    /// loaded; the albedo gradient is with respect to it). None: the homogeneous
    /// medium, rendered by the code paths for it.
    pub heterogeneous: Option<Box<HeterogeneousMedium>>,
}

impl Medium {
    /// Scattering coefficient σ_s = albedo · σ_t.
    #[inline]
    pub fn sigma_s(&self) -> Vec3 {
        self.albedo * self.sigma_t
    }

    /// Whether σ_t is the same in every channel (then every channel's distance pdf is
    /// the hero's).
    #[inline]
    pub fn is_grey(&self) -> bool {
        self.sigma_t.x == self.sigma_t.y && self.sigma_t.y == self.sigma_t.z
    }

    /// Sets the XML `scale`: σ_t scaled with it (a heterogeneous medium's majorants
    /// too).
    pub fn set_scale(&mut self, scale: f32) {
        match &mut self.heterogeneous {
            Some(h) => {
                h.set_scale(scale);
                self.sigma_t = Vec3::splat(h.majorant);
            }
            None => self.sigma_t = self.sigma_t / self.scale * scale,
        }
        self.scale = scale;
    }

    /// A free-flight distance sampled with the extinction of `channel` (∞ where that
    /// extinction is 0: the ray never collides).
    #[inline]
    pub fn sample_distance(&self, channel: usize, u: f32) -> f32 {
        sample_distance(self.sigma_t[channel], u)
    }

    /// Beer–Lambert transmittance over a length `t` (t may be ∞: 0 where σ_t > 0,
    /// 1 where σ_t = 0).
    #[inline]
    pub fn transmittance(&self, t: f32) -> Vec3 {
        transmittance(self.sigma_t, t)
    }
}

/// A free-flight distance at extinction σ from uniform `u` (inverting the CDF
/// 1 − e^{−σ t}): t = −ln(1 − u) / σ, ∞ where σ = 0 (the ray never collides).
///
/// u < 1, so t is finite. The sampler's u are multiples of 2^-23, for which 1 − u is
/// exact in f32: ln(1 − u) is then as accurate as ln_1p(−u), and libm's logf is several
/// times faster than its log1pf.
#[inline(always)]
pub fn sample_distance<F: Float>(sigma: F, u: F) -> F {
    let t = (F::one() - u).ln().negate() / sigma;
    F::select(sigma.gt(F::zero()), t, F::of(f64::INFINITY))
}

/// e^{−σ t} (Beer–Lambert), with `0 · ∞ = 0`: no extinction, no attenuation, at any t.
#[inline(always)]
pub fn transmittance_at<F: Float>(sigma: F, t: F) -> F {
    F::select(sigma.gt(F::zero()), (sigma.negate() * t).exp(), F::one())
}

/// `e^{−σ t}` per channel ([`transmittance_at`]). A grey σ_t (most media) takes one
/// exponential, not three: `expf` was 8% of a furnace profile.
#[inline]
pub fn transmittance(sigma_t: Vec3, t: f32) -> Vec3 {
    if sigma_t.x == sigma_t.y && sigma_t.y == sigma_t.z {
        Vec3::splat(transmittance_at(sigma_t.x, t))
    } else {
        transmittance_rgb(sigma_t.into(), t).into()
    }
}

/// `e^{−σ t}` per channel, for a path or lanes of paths.
#[inline(always)]
pub fn transmittance_rgb<F: Float>(sigma_t: Vector3<F>, t: F) -> Vector3<F> {
    Vector3::new(
        transmittance_at(sigma_t.x, t),
        transmittance_at(sigma_t.y, t),
        transmittance_at(sigma_t.z, t),
    )
}

/// The hero channel a path draws its distances with (volpath's module comment): each
/// of the three with probability 1/3, from the draw `u` in [0, 1).
#[inline(always)]
pub fn hero_channel(u: f32) -> usize {
    ((u * 3.0) as usize).min(2)
}

/// The hero channel's free-flight weights (volpath's module comment): a flight sampled
/// with σ_t of the hero channel h, transmittance T, weighs f / p_h per channel.
/// A collision at t: f = T σ_t (α apart), p_h = σ_t,h T_h.
#[inline(always)]
pub fn collision_weight<F: Float>(
    tr: Vector3<F>,
    sigma_t: Vector3<F>,
    sigma_hero: F,
    tr_hero: F,
) -> Vector3<F> {
    tr.mul(sigma_t).div(sigma_hero * tr_hero)
}

/// ∂/∂σ_t (per channel) of [`collision_weight`]'s f = T σ_t over the same, detached
/// p_h: ∂(σ_t e^{−σ_t t})/∂σ_t = T (1 − σ_t t), so T (1 − σ_t t) / (σ_t,h T_h)
/// (volpath's `Differentiated`). Finite where a channel's σ_t is 0, unlike
/// [`collision_weight`] times the score 1/σ_t − t.
#[inline(always)]
pub fn collision_weight_d_sigma<F: Float>(
    tr: Vector3<F>,
    sigma_t: Vector3<F>,
    t: F,
    sigma_hero: F,
    tr_hero: F,
) -> Vector3<F> {
    tr.mul(Vector3::all(F::one()).sub(sigma_t.scale(t)))
        .div(sigma_hero * tr_hero)
}

/// Passing a whole segment: f = T, p_h = T_h (the other half of [`collision_weight`]).
#[inline(always)]
pub fn pass_weight<F: Float>(tr: Vector3<F>, tr_hero: F) -> Vector3<F> {
    tr.div(tr_hero)
}

/// The weight of an emitter at a segment's end counted in expectation (volpath's module
/// comment): the flight passes to it with probability T_h and then weighs β T / mean(r T),
/// so the path counts β T (T_h / mean(r T)) L_e at once.
#[inline(always)]
pub fn expected_pass_weight<F: Float>(tr: Vector3<F>, tr_hero: F, r: Vector3<F>) -> Vector3<F> {
    tr.scale(tr_hero / r.mul(tr).mean())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn free_flight_mean_is_one_over_sigma_t() {
        let m = Medium {
            albedo: Vec3::splat(0.5),
            sigma_t: Vec3::new(2.0, 5.0, 0.0),
            scale: 1.0,
            phase: Phase::Isotropic,
            sample_emitters: true,
            id: None,
            heterogeneous: None,
        };
        let n = 200_000;
        for (c, want) in [(0, 0.5f64), (1, 0.2)] {
            let mean = (0..n)
                .map(|i| m.sample_distance(c, (i as f32 + 0.5) / n as f32) as f64)
                .sum::<f64>()
                / n as f64;
            assert!((mean - want).abs() < 2e-3 * want, "channel {c}: {mean}");
        }
        assert_eq!(m.sample_distance(2, 0.3), f32::INFINITY);
        assert_eq!(m.transmittance(f32::INFINITY), Vec3::new(0.0, 0.0, 1.0));
    }
}
