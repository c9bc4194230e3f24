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
//! A `homogeneous` medium whose albedo is a grid also lands here, with a constant
//! unbounded σ_t: then σ̄ = σ_t for grey extinction and no null collision happens.

use glam::{Vec3, Vec3A};

use super::grid::Volume;
use crate::sampling::Pcg32;

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
}

/// What a free flight found: a real collision, or none before `tmax`.
pub struct Collision {
    pub t: f32,
    /// The albedo there (before the render's global factor on it).
    pub albedo: Vec3,
}

impl HeterogeneousMedium {
    /// The ray's stretch [t0, t1] ⊂ [0, tmax] in which extinction can be non-zero.
    #[inline]
    pub fn span(&self, o: Vec3A, d: Vec3A, tmax: f32) -> Option<(f32, f32)> {
        if !self.bounded {
            return Some((0.0, tmax));
        }
        let [lo, hi] = self.sigma_t.bbox;
        let inv = d.recip();
        let a = (Vec3A::from(lo) - o) * inv;
        let b = (Vec3A::from(hi) - o) * inv;
        // NaN (0 · ∞ on a slab's plane) is dropped by min/max.
        let t0 = a.min(b).max_element().max(0.0);
        let t1 = a.max(b).min_element().min(tmax);
        (t0 <= t1).then_some((t0, t1))
    }

    /// σ_t at `p` (with `scale`).
    #[inline]
    pub fn sigma_t_at(&self, p: Vec3A) -> Vec3 {
        self.sigma_t.eval(p) * self.scale
    }

    /// Delta tracking from `o` along unit `d` up to `tmax`: the first real collision,
    /// if any, and the path weight the flight contributes (product of the null
    /// collisions' σ_n / mean(σ_n), times σ_t / mean(σ_t) at the real one; all ones for
    /// grey σ_t). The albedo is left to the caller.
    pub fn sample_flight(
        &self,
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
        rng: &mut Pcg32,
    ) -> (Option<Collision>, Vec3) {
        let mut w = Vec3::ONE;
        let Some((t0, t1)) = self.span(o, d, tmax) else {
            return (None, w);
        };
        if self.majorant <= 0.0 {
            return (None, w);
        }
        let inv_major = 1.0 / self.majorant;
        let mut t = t0;
        loop {
            t -= (1.0 - rng.next_1d()).ln() * inv_major;
            if t >= t1 {
                return (None, w);
            }
            let p = o + d * t;
            let sigma_t = self.sigma_t_at(p);
            let p_real = mean(sigma_t) * inv_major;
            if rng.next_1d() < p_real {
                w *= sigma_t / mean(sigma_t);
                let albedo = self.albedo.eval(p);
                return (Some(Collision { t, albedo }), w);
            }
            let sigma_n = Vec3::splat(self.majorant) - sigma_t;
            let m = mean(sigma_n);
            if m <= 0.0 {
                return (None, Vec3::ZERO);
            }
            w *= sigma_n / m;
        }
    }

    /// Ratio tracking: an unbiased estimate of `exp(−∫₀^dist σ_t)` from `o` along `d`.
    pub fn transmittance(&self, o: Vec3A, d: Vec3A, dist: f32, rng: &mut Pcg32) -> Vec3 {
        let mut tr = Vec3::ONE;
        let Some((t0, t1)) = self.span(o, d, dist) else {
            return tr;
        };
        if self.majorant <= 0.0 {
            return tr;
        }
        let inv_major = 1.0 / self.majorant;
        let mut t = t0;
        loop {
            t -= (1.0 - rng.next_1d()).ln() * inv_major;
            if t >= t1 {
                return tr;
            }
            let sigma_t = self.sigma_t_at(o + d * t);
            tr *= (Vec3::splat(self.majorant) - sigma_t) * inv_major;
            // Russian roulette once little is left (unbiased: survivors weigh 1/q).
            let m = tr.max_element();
            if m < 0.1 {
                if m <= 0.0 || rng.next_1d() >= 0.5 {
                    return Vec3::ZERO;
                }
                tr *= 2.0;
            }
        }
    }
}

#[inline]
fn mean(v: Vec3) -> f32 {
    (v.x + v.y + v.z) * (1.0 / 3.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::medium::grid::{Source, Volume};
    use glam::Affine3A;

    fn medium(v: Vec3) -> HeterogeneousMedium {
        let sigma_t = Volume::new(Source::Const(v), Affine3A::IDENTITY);
        HeterogeneousMedium {
            majorant: 2.0 * sigma_t.max,
            sigma_t,
            albedo: Volume::new(Source::Const(Vec3::splat(0.5)), Affine3A::IDENTITY),
            scale: 1.0,
            bounded: true,
        }
    }

    #[test]
    fn ratio_and_delta_tracking_give_beer_lambert() {
        // Chromatic σ_t in the unit box, ray through it along x from outside.
        let m = medium(Vec3::new(1.0, 2.0, 0.5));
        let o = Vec3A::new(-1.0, 0.5, 0.5);
        let d = Vec3A::X;
        let want = (-Vec3::new(1.0, 2.0, 0.5)).exp();
        let mut rng = Pcg32::new(7, 1);
        let n = 200_000;
        let mut tr = Vec3::ZERO;
        let mut pass = Vec3::ZERO;
        for _ in 0..n {
            tr += m.transmittance(o, d, 3.0, &mut rng);
            let (c, w) = m.sample_flight(o, d, 3.0, &mut rng);
            if c.is_none() {
                pass += w;
            }
        }
        for (name, got) in [("ratio", tr / n as f32), ("delta", pass / n as f32)] {
            let err = (got - want).abs().max_element();
            assert!(err < 6e-3, "{name}: {got} vs {want}");
        }
    }
}
