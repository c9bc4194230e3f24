//! Phase functions: `isotropic`, Henyey–Greenstein `hg` and `rayleigh` (Mitsuba 3
//! `src/phase/`).
//!
//! Directions follow propagation: `d_in` is the direction the light travelled before
//! the scattering event, `d_out` after it, and cos θ = d_in · d_out. Mitsuba evaluates
//! `eval_hg(dot(wo, wi))` with `wi = −d_in` and `1 + g² + 2g·cos`, which is the
//! textbook form below: g > 0 scatters forward.
//!
//!   p_HG(cos θ) = (1 − g²) / (4π (1 + g² − 2g cos θ)^{3/2})
//!
//! Rayleigh scattering (unpolarized; Mitsuba 3 `src/phase/rayleigh.cpp`, Chandrasekhar
//! 1960, *Radiative Transfer*, §17):
//!
//!   p_R(cos θ) = 3/(16π) (1 + cos² θ),
//!
//! symmetric in cos θ, so the direction convention does not matter for it.
//!
//! Sampling is exact (the phase value equals its pdf), so the sample weight is 1.

use std::f32::consts::PI;

use glam::{Vec2, Vec3A};

use crate::geometry::around;
use crate::simd::{Float, Vector3};

/// p_HG(cos θ). 1 + g² − 2g cos = (1 − |g|)² + 2|g| w, with w = 1 ∓ cos θ the distance
/// from the peak (cos θ = ±1 for g ≷ 0): both terms are ≥ 0, so there is no
/// cancellation in the peak, which near |g| = 1 is only ~(1 − |g|)² wide in w. The
/// scalar path evaluates it in f64, the lanes in f32.
#[inline(always)]
pub fn hg_eval<F: Float>(g: F, cos_theta: F) -> F {
    let one = F::one();
    hg_peak(
        g,
        F::select(g.ge(F::zero()), one - cos_theta, one + cos_theta),
    )
}

/// p_HG at distance `w` = 1 ∓ cos θ from the peak.
#[inline(always)]
fn hg_peak<F: Float>(g: F, w: F) -> F {
    let one = F::one();
    let a = g.abs();
    let denom = (one - a) * (one - a) + F::of(2.0) * a * w;
    (one - g * g) / (F::of(4.0 * std::f64::consts::PI) * denom * denom.sqrt())
}

/// Inverse CDF of p_HG, as the distance from the peak
/// w = 1 ∓ cos θ. The textbook cos θ = (1 + g² − s²)/(2g), s = (1 − g²)/(1 + g − 2gu),
/// cancels near the peak: at g = 0.999 its f32 error (~1e-7) is a fifth of the peak's
/// width. With a = |g| and s = (1 − a²)/(1 + a − 2au), the same value is
///   w = (1 − a) u (s + 1 − a) / (1 + a − 2au),
/// whose terms are all ≥ 0 (g < 0 is g > 0 mirrored: the peak at cos θ = −1), and which
/// needs no isotropic special case: at g = 0 it is w = 2u.
#[inline(always)]
fn hg_sample_peak_distance<F: Float>(g: F, u: F) -> F {
    let one = F::one();
    let two = F::of(2.0);
    let a = g.abs();
    let q = one + a - two * a * u;
    let s = (one - a * a) / q;
    ((one - a) * u * (s + one - a) / q).max(F::zero()).min(two)
}

/// A Henyey–Greenstein scattering angle from uniform `u`: w = 1 − cos θ measured from
/// the direction the light travelled (so that sin θ = √(w (2 − w)) keeps its precision
/// near θ = 0, which cos θ would lose), and the pdf p_HG, the sample's value (sampling
/// is exact: the weight is 1).
#[inline(always)]
pub fn hg_sample<F: Float>(g: F, u: F) -> (F, F) {
    let peak = hg_sample_peak_distance(g, u);
    (hg_angle(g, peak), hg_peak(g, peak))
}

/// [`hg_sample`]'s angle alone, where the pdf is not wanted (the lanes' phase sample).
#[inline(always)]
pub fn hg_sample_angle<F: Float>(g: F, u: F) -> F {
    hg_angle(g, hg_sample_peak_distance(g, u))
}

/// w = 1 − cos θ from the distance to the peak (at cos θ = ±1 for g ≷ 0).
#[inline(always)]
fn hg_angle<F: Float>(g: F, peak: F) -> F {
    F::select(g.ge(F::zero()), peak, F::of(2.0) - peak)
}

/// The direction at 1 − cos θ = `w` from the unit `d` and azimuth 2π `u`:
/// sin θ = √(w (2 − w)), in `d`'s frame (`geometry::coordinate_system`).
#[inline(always)]
pub fn direction_at<F: Float>(d: Vector3<F>, w: F, u: F) -> Vector3<F> {
    let sin_theta = (w * (F::of(2.0) - w)).max(F::zero()).sqrt();
    around(d, F::one() - w, sin_theta, u)
}

/// ∂ ln p_HG / ∂g at 1 − cos θ = `w` (the score of g, for its derivative with sampling
/// detached): ln p_HG = ln(1 − g²) − (3/2) ln D with D = 1 + g² − 2g cos θ, so
///   ∂ ln p_HG / ∂g = −2g / (1 − g²) − 3 (g − cos θ) / D,
/// D in [`hg_peak`]'s cancellation-free form and g − cos θ = g − 1 + w. The scalar
/// path evaluates it in f64, the lanes in f32.
#[inline(always)]
pub fn hg_log_derivative_g<F: Float>(g: F, w: F) -> F {
    let (one, two) = (F::one(), F::of(2.0));
    let a = g.abs();
    let peak = F::select(g.ge(F::zero()), w, two - w);
    let denom = (one - a) * (one - a) + two * a * peak;
    F::of(-2.0) * g / (one - g * g) - F::of(3.0) * (g - one + w) / denom
}

/// p_R(cos θ) = 3/(16π) (1 + cos² θ).
#[inline]
fn rayleigh(cos_theta: f64) -> f64 {
    3.0 / (16.0 * std::f64::consts::PI) * (1.0 + cos_theta * cos_theta)
}

/// Inverse CDF of p_R in μ = cos θ. The marginal density of μ is (3/8)(1 + μ²), whose
/// CDF (3/8)(μ + μ³/3) + ½ = u gives the depressed cubic μ³ + 3μ − 2z = 0 with
/// z = 2(2u − 1). It has one real root (discriminant z² + 1 > 0), by Cardano's formula
///   μ = ∛(z + √(z² + 1)) + ∛(z − √(z² + 1)),
/// the same expression as Mitsuba's `sample`.
#[inline]
fn rayleigh_sample_cos(u: f64) -> f64 {
    let z = 2.0 * (2.0 * u - 1.0);
    let r = (z * z + 1.0).sqrt();
    ((z + r).cbrt() + (z - r).cbrt()).clamp(-1.0, 1.0)
}

#[derive(Clone, Debug, PartialEq)]
pub enum Phase {
    Isotropic,
    /// Henyey–Greenstein with asymmetry `g` ∈ (−1, 1), Mitsuba's sign convention.
    HenyeyGreenstein {
        g: f32,
    },
    /// Rayleigh's (1 + cos² θ) law, no parameters.
    Rayleigh,
}

impl Phase {
    /// Phase function value (= pdf, per steradian) for cos θ = d_in · d_out.
    #[inline]
    pub fn eval(&self, cos_theta: f32) -> f32 {
        match *self {
            Phase::Isotropic => 1.0 / (4.0 * PI),
            Phase::HenyeyGreenstein { g } => hg_eval(g as f64, cos_theta as f64) as f32,
            Phase::Rayleigh => rayleigh(cos_theta as f64) as f32,
        }
    }

    /// ∂ ln p / ∂g at 1 − cos θ = `w` ([`hg_log_derivative_g`]); 0 for a phase function
    /// without g.
    #[inline]
    pub fn log_derivative_g(&self, w: f64) -> f32 {
        match *self {
            Phase::HenyeyGreenstein { g } => hg_log_derivative_g(g as f64, w) as f32,
            Phase::Isotropic | Phase::Rayleigh => 0.0,
        }
    }

    /// Samples d_out for light travelling along `d_in`; returns (d_out, pdf).
    #[inline]
    pub fn sample(&self, d_in: Vec3A, u: Vec2) -> (Vec3A, f32) {
        let (d_out, pdf, _) = self.sample_angle(d_in, u);
        (d_out, pdf)
    }

    /// [`Phase::sample`] with the sample's 1 − cos θ, in f64 (for the g derivative).
    #[inline]
    pub fn sample_angle(&self, d_in: Vec3A, u: Vec2) -> (Vec3A, f32, f64) {
        let (w, pdf) = match *self {
            Phase::HenyeyGreenstein { g } => {
                let (w, pdf) = hg_sample(g as f64, u.x as f64);
                (w, pdf as f32)
            }
            Phase::Isotropic => (2.0 * u.x as f64, 1.0 / (4.0 * PI)),
            Phase::Rayleigh => {
                let mu = rayleigh_sample_cos(u.x as f64);
                (1.0 - mu, rayleigh(mu) as f32)
            }
        };
        // sin θ from w in f64, then the frame in f32.
        let sin_theta = (w * (2.0 - w)).max(0.0).sqrt() as f32;
        let d_out = around(d_in.into(), (1.0 - w) as f32, sin_theta, u.y).into();
        (d_out, pdf, w)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ∫ p dω = 1 and ∫ p cos θ dω = g, by quadrature. The peak (at cos θ = ±1, of
    /// width ~ (1 − |g|)² in w = 1 ∓ cos θ) is resolved by the midpoint rule on a log grid
    /// in w: ∫ f dw = ∫ f w d(ln w). In double precision: an f32 cos θ cannot resolve w
    /// below ~6e-8, which at g = ±0.999 is a tenth of the peak's width.
    #[test]
    fn hg_normalised_with_mean_cosine_g() {
        for g in [-0.999, -0.7, -0.3, 0.0, 0.0005, 0.5, 0.9, 0.999] {
            let sign = if g >= 0.0 { 1.0 } else { -1.0 };
            let (lo, hi) = (1e-14f64.ln(), 2f64.ln());
            let n = 200_000;
            let h = (hi - lo) / n as f64;
            let (mut norm, mut mean) = (0.0f64, 0.0f64);
            for i in 0..n {
                let w = (lo + (i as f64 + 0.5) * h).exp();
                let c = sign * (1.0 - w);
                let v = hg_eval(g, c) * 2.0 * std::f64::consts::PI * w * h;
                norm += v;
                mean += v * c;
            }
            assert!((norm - 1.0).abs() < 1e-6, "g={g}: ∫p = {norm}");
            assert!((mean - g).abs() < 1e-6, "g={g}: mean cos = {mean}");
        }
        // The f32 entry point agrees with the f64 form.
        let p = Phase::HenyeyGreenstein { g: 0.7 };
        assert!((p.eval(0.3) as f64 - hg_eval(0.7f32 as f64, 0.3f32 as f64)).abs() < 1e-7);
    }

    /// Sampled cosines have the HG mean g, and the returned pdf is the phase value.
    #[test]
    fn hg_sampling_matches_eval() {
        let d_in = Vec3A::new(0.3, -0.4, 0.866).normalize();
        for g in [-0.8f32, 0.0, 0.3, 0.95] {
            let p = Phase::HenyeyGreenstein { g };
            let n = 256;
            let mut mean = 0.0f64;
            for i in 0..n {
                for j in 0..n {
                    let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                    let (d, pdf) = p.sample(d_in, u);
                    assert!((d.length() - 1.0).abs() < 1e-4);
                    let c = d.dot(d_in);
                    assert!((pdf - p.eval(c)).abs() <= 2e-3 * pdf.max(1.0), "g={g}");
                    mean += c as f64;
                }
            }
            mean /= (n * n) as f64;
            assert!((mean - g as f64).abs() < 2e-3, "g={g}: mean cos {mean}");
        }
    }

    /// The g score against a central difference of ln p_HG in f64, over g and angles
    /// (including near the peak of g = ±0.95); a sign flip or a missing term fails.
    #[test]
    fn hg_g_score_is_the_log_derivative() {
        for g in [-0.95, -0.5, 0.0, 0.3, 0.8, 0.95] {
            for w in [1e-4, 0.01, 0.2, 1.0, 1.7, 2.0 - 1e-4] {
                let cos = 1.0 - w;
                let h = 1e-6;
                let fd = (hg_eval(g + h, cos).ln() - hg_eval(g - h, cos).ln()) / (2.0 * h);
                let score = hg_log_derivative_g(g, w);
                assert!(
                    (score - fd).abs() <= 1e-5 * fd.abs().max(1.0),
                    "g={g} w={w}: {score} vs {fd}"
                );
            }
        }
    }

    /// Rayleigh: ∫ p dω = 1 (midpoint rule in cos θ), and sampled cosines follow the
    /// marginal (3/8)(1 + μ²): chi-square over 40 equal-width μ bins, the returned pdf
    /// being p_R of the returned direction.
    #[test]
    fn rayleigh_normalised_and_sampled_exactly() {
        use crate::sampling::Pcg32;
        use statrs::distribution::{ChiSquared, ContinuousCDF};
        let n = 100_000;
        let norm: f64 = (0..n)
            .map(|i| {
                rayleigh(-1.0 + 2.0 * (i as f64 + 0.5) / n as f64)
                    * 2.0
                    * 2.0
                    * std::f64::consts::PI
                    / n as f64
            })
            .sum();
        assert!((norm - 1.0).abs() < 1e-9, "∫p = {norm}");
        // Symmetric: forward and backward scattering alike; twice the side value.
        let p = Phase::Rayleigh;
        assert_eq!(p.eval(0.6), p.eval(-0.6));
        assert!((p.eval(1.0) / p.eval(0.0) - 2.0).abs() < 1e-6);

        let d_in = Vec3A::new(0.3, -0.4, 0.866).normalize();
        let bins = 40;
        let mut counts = vec![0usize; bins];
        let mut rng = Pcg32::new(23, 1);
        let samples = 200_000;
        for _ in 0..samples {
            let (d, pdf) = p.sample(d_in, rng.next_2d());
            assert!((d.length() - 1.0).abs() < 1e-4);
            let c = d.dot(d_in).clamp(-1.0, 1.0);
            assert!(
                (pdf - p.eval(c)).abs() <= 1e-4 * pdf,
                "pdf {pdf} vs {}",
                p.eval(c)
            );
            counts[(((c + 1.0) / 2.0 * bins as f32) as usize).min(bins - 1)] += 1;
        }
        // P(bin) from the marginal's CDF F(μ) = (3/8)(μ + μ³/3) + ½.
        let cdf = |m: f64| 0.375 * (m + m * m * m / 3.0) + 0.5;
        let chi2: f64 = (0..bins)
            .map(|b| {
                let (lo, hi) = (
                    -1.0 + 2.0 * b as f64 / bins as f64,
                    -1.0 + 2.0 * (b + 1) as f64 / bins as f64,
                );
                let e = (cdf(hi) - cdf(lo)) * samples as f64;
                (counts[b] as f64 - e).powi(2) / e
            })
            .sum();
        let limit = ChiSquared::new((bins - 1) as f64)
            .unwrap()
            .inverse_cdf(1.0 - 1e-6);
        assert!(chi2 < limit, "chi-square {chi2:.1} (limit {limit:.1})");
        // The inverse CDF at the ends and the middle.
        assert!((rayleigh_sample_cos(0.0) + 1.0).abs() < 1e-12);
        assert!((rayleigh_sample_cos(1.0) - 1.0).abs() < 1e-12);
        assert!(rayleigh_sample_cos(0.5).abs() < 1e-12);
    }

    /// The distance from the peak of a sampled direction, measured without the f32
    /// cancellation of 1 − d·d_in: 1 ∓ cos = sin² / (1 ± cos) on the peak's side.
    fn measured_peak_distance(g: f32, d_in: Vec3A, d: Vec3A) -> f64 {
        let (d_in, d) = (d_in.as_dvec3(), d.as_dvec3().normalize());
        let c = d.dot(d_in);
        let sin2 = d.cross(d_in).length_squared();
        let toward = if g >= 0.0 { c } else { -c };
        if toward > 0.0 {
            sin2 / (1.0 + toward)
        } else {
            1.0 - toward
        }
    }

    /// HG sampling is exact up to |g| = 0.999: the sampled directions' distances from
    /// the peak follow the pdf (chi-square over a log grid reaching far inside the
    /// peak, bin probabilities by numerical integration of p_HG), and the returned pdf
    /// is p_HG of the direction returned. The textbook inversion in f32 fails this at
    /// g = ±0.999 (its cos θ cancels in the peak).
    #[test]
    fn hg_sampling_exact_near_the_peak() {
        use crate::sampling::Pcg32;
        use statrs::distribution::{ChiSquared, ContinuousCDF};
        let d_in = Vec3A::new(0.3, -0.4, 0.866).normalize();
        let n = 400_000usize;
        for (k, g) in [-0.999f32, -0.9, -0.5, 0.0, 0.0005, 0.5, 0.9, 0.999]
            .into_iter()
            .enumerate()
        {
            let p = Phase::HenyeyGreenstein { g };
            // Bin edges in w: 0, then 10^-12 … 2 logarithmically.
            let mut edges = vec![0.0f64];
            edges.extend((0..=60).map(|i| 1e-12f64 * (2e12f64).powf(i as f64 / 60.0)));
            // P(bin) = ∫ 2π p_HG dw over the bin: midpoint rule in ln w (and in w on the
            // first bin), 2000 steps per bin.
            let gd = g as f64;
            let prob: Vec<f64> = edges
                .windows(2)
                .map(|e| {
                    let m = 2000;
                    if e[0] == 0.0 {
                        let h = e[1] / m as f64;
                        (0..m)
                            .map(|i| hg_peak(gd, (i as f64 + 0.5) * h) * h)
                            .sum::<f64>()
                            * 2.0
                            * std::f64::consts::PI
                    } else {
                        let (lo, hi) = (e[0].ln(), e[1].ln());
                        let h = (hi - lo) / m as f64;
                        (0..m)
                            .map(|i| {
                                let w = (lo + (i as f64 + 0.5) * h).exp();
                                hg_peak(gd, w) * w * h
                            })
                            .sum::<f64>()
                            * 2.0
                            * std::f64::consts::PI
                    }
                })
                .collect();
            let total: f64 = prob.iter().sum();
            assert!((total - 1.0).abs() < 1e-6, "g={g}: ∫p = {total}");

            let mut counts = vec![0usize; prob.len()];
            let mut rng = Pcg32::new(17, k as u64);
            for _ in 0..n {
                let (d, pdf) = p.sample(d_in, rng.next_2d());
                let w = measured_peak_distance(g, d_in, d);
                let b = edges.partition_point(|e| *e <= w).clamp(1, prob.len()) - 1;
                counts[b] += 1;
                // Away from the f32 resolution of a direction, the pdf returned is p_HG
                // of the direction returned.
                if w > 1e-5 {
                    let want = hg_peak(gd, w);
                    assert!(
                        (pdf as f64 - want).abs() <= 1e-3 * want,
                        "g={g}: pdf {pdf} vs p_HG {want} at w {w:e}"
                    );
                }
            }
            // Chi-square over bins merged until each expects ≥ 20 samples.
            let (mut chi2, mut dof) = (0.0, 0usize);
            let (mut e_acc, mut o_acc) = (0.0, 0usize);
            for (pb, c) in prob.iter().zip(&counts) {
                e_acc += pb * n as f64;
                o_acc += c;
                if e_acc >= 20.0 {
                    chi2 += (o_acc as f64 - e_acc).powi(2) / e_acc;
                    dof += 1;
                    (e_acc, o_acc) = (0.0, 0);
                }
            }
            if e_acc > 0.0 || o_acc > 0 {
                chi2 += (o_acc as f64 - e_acc).powi(2) / e_acc.max(1.0);
                dof += 1;
            }
            let limit = ChiSquared::new((dof - 1) as f64)
                .unwrap()
                .inverse_cdf(1.0 - 1e-6);
            assert!(
                chi2 < limit,
                "g={g}: chi-square {chi2:.1} over {dof} bins (limit {limit:.1})"
            );
        }
    }
}
