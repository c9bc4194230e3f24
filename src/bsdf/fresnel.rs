//! Mitsuba's `fresnel.h`: the Fresnel equations at smooth dielectric and conductor
//! interfaces, the diffuse Fresnel reflectance, and reflection and refraction about a
//! (micro)facet normal, shared by every BSDF with a specular interface.

use glam::Vec3A;

use crate::simd::Float;

/// Unpolarized Fresnel reflectance. Returns (R, cos θ_t, η_it, η_ti), with cos θ_t signed
/// opposite to cos θ_i, exactly as Mitsuba's `fresnel(cos_theta_i, eta)`: with
/// a_s = (cos θ_i − η_it cos θ_t) / (cos θ_i + η_it cos θ_t) and
/// a_p = (cos θ_t − η_it cos θ_i) / (cos θ_t + η_it cos θ_i), R = (a_s² + a_p²) / 2.
/// One definition for a path and for lanes of paths (every branch a select).
#[inline(always)]
pub fn fresnel<F: Float>(cos_theta_i: F, eta: F) -> (F, F, F, F) {
    let (zero, one) = (F::zero(), F::one());
    let outside = cos_theta_i.ge(zero);
    let eta_it = F::select(outside, eta, one / eta);
    let eta_ti = F::select(outside, one / eta, eta);
    let cos_t_sqr = one - (one - cos_theta_i * cos_theta_i) * eta_ti * eta_ti;
    let ci = cos_theta_i.abs();
    let ct = cos_t_sqr.max(zero).sqrt();
    let a_s = (ci - eta_it * ct) / (ci + eta_it * ct);
    let a_p = (ct - eta_it * ci) / (ct + eta_it * ci);
    let r = F::of(0.5) * (a_s * a_s + a_p * a_p);
    // At grazing incidence (ci = 0) the quotients are 0/0: R = 1. No interface, no
    // reflection. Total internal reflection gives cos_t_sqr < 0: R = 1.
    let r = F::select(ci.eq(zero), one, r);
    let r = F::select(eta.eq(one), zero, r);
    let r = F::select(cos_t_sqr.le(zero), one, r);
    let cos_theta_t = F::select(outside, ct.negate(), ct);
    (r, cos_theta_t, eta_it, eta_ti)
}

/// Unpolarized Fresnel reflectance at a conductor with index η + iκ, for cos θ_i > 0
/// (the exact formula, e.g. pbrt 3rd ed. §8.2.1, as Mitsuba's `fresnel_conductor`):
///   a² + b² = √((η² − κ² − sin²θ)² + 4η²κ²),  a = √((a² + b² + η² − κ² − sin²θ) / 2)
///   R_s = (a² + b² + cos²θ − 2a cosθ) / (a² + b² + cos²θ + 2a cosθ)
///   R_p = R_s (cos²θ (a² + b²) + sin⁴θ − 2a cosθ sin²θ) / (… + 2a cosθ sin²θ)
pub fn fresnel_conductor(cos_theta_i: f32, eta: f32, k: f32) -> f32 {
    let (c, eta, k) = (cos_theta_i.clamp(0.0, 1.0) as f64, eta as f64, k as f64);
    let c2 = c * c;
    let s2 = 1.0 - c2;
    let t1 = eta * eta - k * k - s2;
    let a2pb2 = (t1 * t1 + 4.0 * eta * eta * k * k).max(0.0).sqrt();
    let a = (0.5 * (a2pb2 + t1)).max(0.0).sqrt();
    let term1 = a2pb2 + c2;
    let term2 = 2.0 * c * a;
    let r_s = (term1 - term2) / (term1 + term2);
    let term3 = a2pb2 * c2 + s2 * s2;
    let term4 = term2 * s2;
    let r_p = r_s * (term3 - term4) / (term3 + term4);
    (0.5 * (r_s + r_p)) as f32
}

/// Diffuse Fresnel reflectance: the fraction of light arriving uniformly from a
/// hemisphere that a smooth interface of relative index `eta` reflects. Mitsuba's fits:
/// Egan and Hilgeman (1973) for η < 1, d'Eon and Irving (2011) otherwise.
pub fn fresnel_diffuse_reflectance(eta: f32) -> f32 {
    let inv = 1.0 / eta;
    if eta < 1.0 {
        0.0636 * inv + eta * (eta * -1.4399 + 0.7099) + 0.6681
    } else {
        // Horner in 1/η.
        let c = [0.919317, -3.4793, 6.75335, -7.80989, 4.98554, -1.36881];
        c.iter().rev().fold(0.0f32, |acc, &k| acc * inv + k)
    }
}

/// Reflection of `wi` about the microfacet normal `m`: 2 (wi·m) m − wi.
#[inline]
pub fn reflect(wi: Vec3A, m: Vec3A) -> Vec3A {
    m * (2.0 * wi.dot(m)) - wi
}

/// Refraction of `wi` through the microfacet `m`, with cos θ_t and η_ti from `fresnel`.
#[inline]
pub fn refract(wi: Vec3A, m: Vec3A, cos_theta_t: f32, eta_ti: f32) -> Vec3A {
    m * (wi.dot(m) * eta_ti + cos_theta_t) - wi * eta_ti
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_normal_incidence_and_tir() {
        let (r, ct, _, _) = fresnel(1.0, 1.5);
        assert!((r - 0.04).abs() < 1e-6 && (ct + 1.0).abs() < 1e-6);
        // From inside glass at grazing angles: total internal reflection.
        let (r, _, _, _) = fresnel(-0.2, 1.5);
        assert_eq!(r, 1.0);
    }

    /// η = 0, κ = 1 reflects everything at every angle; a dielectric-like conductor
    /// (κ = 0) at normal incidence gives ((η − 1)/(η + 1))²; at grazing incidence 1.
    #[test]
    fn fresnel_conductor_known_values() {
        for c in [1.0, 0.7, 0.3, 0.05] {
            assert!(
                (fresnel_conductor(c, 0.0, 1.0) - 1.0).abs() < 1e-6,
                "cos {c}"
            );
        }
        let r0 = ((1.5f32 - 1.0) / 2.5).powi(2);
        assert!((fresnel_conductor(1.0, 1.5, 0.0) - r0).abs() < 1e-6);
        assert!((fresnel_conductor(1e-6, 0.2, 3.0) - 1.0).abs() < 1e-4);
        // Gold-like (η 0.2, κ 3.6) at normal incidence: ((η−1)² + κ²)/((η+1)² + κ²).
        let want = ((0.2f32 - 1.0).powi(2) + 3.6 * 3.6) / ((1.2f32).powi(2) + 3.6 * 3.6);
        assert!((fresnel_conductor(1.0, 0.2, 3.6) - want).abs() < 1e-6);
    }

    /// The fits against the integral they approximate:
    /// F_dr(η) = ∫ F(cos θ, η) 2 cos θ sin θ dθ over the hemisphere.
    #[test]
    fn diffuse_fresnel_matches_its_integral() {
        for eta in [1.0 / 1.9, 1.0 / 1.5, 1.33, 1.5, 1.9] {
            let n = 20_000;
            let integral: f64 = (0..n)
                .map(|i| {
                    let mu = (i as f64 + 0.5) / n as f64;
                    fresnel(mu as f32, eta).0 as f64 * 2.0 * mu / n as f64
                })
                .sum();
            let fit = fresnel_diffuse_reflectance(eta) as f64;
            assert!(
                (fit - integral).abs() < 0.01,
                "eta {eta}: fit {fit}, integral {integral}"
            );
        }
    }
}
