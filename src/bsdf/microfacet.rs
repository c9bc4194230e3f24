//! Mitsuba 3's microfacet distributions (`include/mitsuba/render/microfacet.h`): Beckmann
//! and GGX, anisotropic roughness (α_u, α_v), Smith's separable shadowing-masking, and
//! sampling of the visible normals (Heitz & d'Eon 2014) with the same warps as Mitsuba,
//! so that the rough BSDFs built on it estimate the same integrals. Directions are in
//! the local frame (z = normal).
//!
//! Also the two integrals that `roughplastic` tabulates when it loads
//! (`eval_transmittance`, `eval_reflectance`), computed by Gauss–Legendre quadrature over
//! the visible-normal sample space as Mitsuba does.

use std::f64::consts::PI;

use glam::{Vec2, Vec3A};
use statrs::function::erf::{erf, erf_inv};

use super::fresnel::{fresnel, reflect, refract};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MicrofacetType {
    Beckmann,
    Ggx,
}

impl MicrofacetType {
    pub fn parse(name: &str) -> Option<Self> {
        match name.to_ascii_lowercase().as_str() {
            "beckmann" => Some(Self::Beckmann),
            "ggx" => Some(Self::Ggx),
            _ => None,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Microfacet {
    pub kind: MicrofacetType,
    pub alpha_u: f32,
    pub alpha_v: f32,
}

impl Microfacet {
    /// Roughness below 10⁻⁴ is clamped to it, as in Mitsuba (use the smooth model for 0).
    pub fn new(kind: MicrofacetType, alpha_u: f32, alpha_v: f32) -> Self {
        Microfacet {
            kind,
            alpha_u: alpha_u.max(1e-4),
            alpha_v: alpha_v.max(1e-4),
        }
    }

    /// The distribution of normals D(m), per unit projected area:
    ///   Beckmann: exp(−((m_x/α_u)² + (m_y/α_v)²)/cos²θ) / (π α_u α_v cos⁴θ)
    ///   GGX:      1 / (π α_u α_v ((m_x/α_u)² + (m_y/α_v)² + m_z²)²)
    pub fn eval(&self, m: Vec3A) -> f32 {
        let (au, av) = (self.alpha_u, self.alpha_v);
        let cos2 = m.z * m.z;
        let d = match self.kind {
            MicrofacetType::Beckmann => {
                let e = (m.x / au).powi(2) + (m.y / av).powi(2);
                (-e / cos2).exp() / (std::f32::consts::PI * au * av * cos2 * cos2)
            }
            MicrofacetType::Ggx => {
                let t = (m.x / au).powi(2) + (m.y / av).powi(2) + cos2;
                1.0 / (std::f32::consts::PI * au * av * t * t)
            }
        };
        if d * m.z > 1e-20 {
            d
        } else {
            0.0
        }
    }

    /// Smith's G1 for direction `v` and microfacet `m`: zero when `v` sees the facet
    /// from the other side than the macro-surface. Beckmann uses Walter et al.'s
    /// rational fit (as Mitsuba), GGX its exact 2 / (1 + √(1 + α² tan²θ)).
    pub fn smith_g1(&self, v: Vec3A, m: Vec3A) -> f32 {
        if v.dot(m) * v.z <= 0.0 {
            return 0.0;
        }
        let xy_alpha_2 = (self.alpha_u * v.x).powi(2) + (self.alpha_v * v.y).powi(2);
        if xy_alpha_2 == 0.0 {
            return 1.0;
        }
        let tan_theta_alpha_2 = xy_alpha_2 / (v.z * v.z);
        match self.kind {
            MicrofacetType::Beckmann => {
                let a = 1.0 / tan_theta_alpha_2.sqrt();
                if a >= 1.6 {
                    1.0
                } else {
                    let a2 = a * a;
                    (3.535 * a + 2.181 * a2) / (1.0 + 2.276 * a + 2.577 * a2)
                }
            }
            MicrofacetType::Ggx => 2.0 / (1.0 + (1.0 + tan_theta_alpha_2).sqrt()),
        }
    }

    /// G(wi, wo, m) = G1(wi, m) G1(wo, m).
    pub fn g(&self, wi: Vec3A, wo: Vec3A, m: Vec3A) -> f32 {
        self.smith_g1(wi, m) * self.smith_g1(wo, m)
    }

    /// Density of the visible normals: D(m) G1(wi, m) |wi·m| / cos θ_i.
    pub fn pdf(&self, wi: Vec3A, m: Vec3A) -> f32 {
        self.eval(m) * self.smith_g1(wi, m) * wi.dot(m).abs() / wi.z
    }

    /// Samples a visible normal for `wi` (upper hemisphere): stretch to unit roughness,
    /// sample the slope of the 1-roughness distribution seen at θ_i, rotate and unstretch.
    /// Returns the normal and its density (`pdf`).
    pub fn sample(&self, wi: Vec3A, u: Vec2) -> (Vec3A, f32) {
        let wi_p = Vec3A::new(self.alpha_u * wi.x, self.alpha_v * wi.y, wi.z).normalize();
        let sin2 = wi_p.x * wi_p.x + wi_p.y * wi_p.y;
        let (sin_phi, cos_phi) = if sin2 > 0.0 {
            let inv = 1.0 / sin2.sqrt();
            (
                (wi_p.y * inv).clamp(-1.0, 1.0),
                (wi_p.x * inv).clamp(-1.0, 1.0),
            )
        } else {
            (0.0, 1.0)
        };
        let s = self.sample_visible_11(wi_p.z, u);
        let slope = Vec2::new(
            (cos_phi * s.x - sin_phi * s.y) * self.alpha_u,
            (sin_phi * s.x + cos_phi * s.y) * self.alpha_v,
        );
        let m = Vec3A::new(-slope.x, -slope.y, 1.0).normalize();
        (m, self.pdf(wi, m))
    }

    /// A slope (x̃, ỹ) of the unit-roughness distribution, distributed as its visible
    /// normals seen from an angle with cosine `cos_theta_i` in the xz-plane.
    fn sample_visible_11(&self, cos_theta_i: f32, u: Vec2) -> Vec2 {
        match self.kind {
            MicrofacetType::Beckmann => {
                // Numerical inversion of the visible-slope CDF (Jakob's variant, which
                // has no discontinuities): three Newton steps in the erf domain.
                let c = cos_theta_i as f64;
                let tan_theta_i = (1.0 - c * c).max(0.0).sqrt() / c;
                let cot_theta_i = 1.0 / tan_theta_i;
                let maxval = erf(cot_theta_i);
                let ux = (u.x as f64).clamp(1e-6, 1.0 - 1e-6);
                let uy = (u.y as f64).clamp(1e-6, 1.0 - 1e-6);
                let inv_sqrt_pi = 1.0 / PI.sqrt();
                let mut x = maxval - (maxval + 1.0) * erf((-ux.ln()).sqrt());
                let ux = ux
                    * (1.0
                        + maxval
                        + inv_sqrt_pi * tan_theta_i * (-cot_theta_i * cot_theta_i).exp());
                // erf⁻¹ is defined on (−1, 1); a Newton step may overshoot the ends.
                let lim = 1.0 - 1e-15;
                for _ in 0..3 {
                    x = x.clamp(-lim, lim);
                    let slope = erf_inv(x);
                    let value = 1.0 + x + inv_sqrt_pi * tan_theta_i * (-slope * slope).exp() - ux;
                    let derivative = 1.0 - slope * tan_theta_i;
                    x -= value / derivative;
                }
                let x = x.clamp(-lim, lim);
                Vec2::new(erf_inv(x) as f32, erf_inv(2.0 * uy - 1.0) as f32)
            }
            MicrofacetType::Ggx => {
                // Heitz 2017: a concentric-disk point, squashed toward the visible half.
                let (x, y0) = crate::sampling::warp::square_to_uniform_disk_concentric(u);
                let s = 0.5 * (1.0 + cos_theta_i);
                let y = (1.0 - x * x).max(0.0).sqrt() * (1.0 - s) + y0 * s;
                let z = (1.0 - x * x - y * y).max(0.0).sqrt();
                let sin_theta_i = (1.0 - cos_theta_i * cos_theta_i).max(0.0).sqrt();
                let norm = 1.0 / (sin_theta_i * y + cos_theta_i * z);
                Vec2::new((cos_theta_i * y - sin_theta_i * z) * norm, x * norm)
            }
        }
    }
}

/// Gauss–Legendre nodes and weights on [−1, 1] (Newton's method on Pₙ).
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let mut dp = 1.0;
            for _ in 0..100 {
                // Pₙ(x) and Pₙ'(x) by the three-term recurrence.
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                    p0 = p1;
                    p1 = p2;
                }
                dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
                let dx = p1 / dp;
                x -= dx;
                if dx.abs() < 1e-15 {
                    break;
                }
            }
            (x, 2.0 / ((1.0 - x * x) * dp * dp))
        })
        .collect()
}

/// Σ over a res × res Gauss–Legendre grid on the unit square of the visible normals
/// for `wi`, of `f(m)` (the grid weights sum to 1).
fn integrate_visible(distr: &Microfacet, wi: Vec3A, res: usize, f: impl Fn(Vec3A) -> f32) -> f32 {
    let gl = gauss_legendre(res);
    let mut sum = 0.0f64;
    for &(ny, wy) in &gl {
        for &(nx, wx) in &gl {
            let u = Vec2::new((0.5 * nx + 0.5) as f32, (0.5 * ny + 0.5) as f32);
            let (m, _) = distr.sample(wi, u);
            let v = f(m);
            if v.is_finite() {
                sum += v as f64 * wx * wy * 0.25;
            }
        }
    }
    sum as f32
}

/// Fraction of light from `wi` that a rough dielectric interface of relative index
/// `eta` transmits in one crossing (the rough Fresnel transmittance).
pub fn eval_transmittance(distr: &Microfacet, wi: Vec3A, eta: f32) -> f32 {
    let res = if eta > 1.0 { 32 } else { 128 };
    integrate_visible(distr, wi, res, |m| {
        let (f, cos_theta_t, _, eta_ti) = fresnel(wi.dot(m), eta);
        let wo = refract(wi, m, cos_theta_t, eta_ti);
        if wo.z * wi.z >= 0.0 {
            0.0
        } else {
            distr.smith_g1(wo, m) * (1.0 - f)
        }
    })
}

/// Fraction of light from `wi` that a rough dielectric interface reflects (one bounce).
pub fn eval_reflectance(distr: &Microfacet, wi: Vec3A, eta: f32) -> f32 {
    let res = if eta > 1.0 { 32 } else { 128 };
    integrate_visible(distr, wi, res, |m| {
        let wo = reflect(wi, m);
        if wo.z <= 0.0 || wi.z <= 0.0 {
            0.0
        } else {
            distr.smith_g1(wo, m) * fresnel(wi.dot(m), eta).0
        }
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    #[test]
    fn gauss_legendre_integrates_polynomials_exactly() {
        let gl = gauss_legendre(8);
        let sum_w: f64 = gl.iter().map(|p| p.1).sum();
        assert!((sum_w - 2.0).abs() < 1e-13);
        // ∫ x¹⁴ over [−1, 1] = 2/15 (degree 2n − 2 is exact).
        let i: f64 = gl.iter().map(|&(x, w)| w * x.powi(14)).sum();
        assert!((i - 2.0 / 15.0).abs() < 1e-13, "{i}");
    }

    /// The projected area of the microfacets is that of the macro-surface:
    /// ∫ D(m) cos θ_m dm = 1 (midpoint rule in spherical coordinates).
    #[test]
    fn distributions_are_normalized() {
        for kind in [MicrofacetType::Beckmann, MicrofacetType::Ggx] {
            for (au, av) in [(0.3, 0.3), (0.5, 0.2)] {
                let d = Microfacet::new(kind, au, av);
                let sum = integrate_over_directions(PI / 2.0, |m| (d.eval(m) * m.z) as f64);
                // GGX has a long tail that the grid resolves less well.
                assert!((sum - 1.0).abs() < 5e-3, "{kind:?} {au} {av}: {sum}");
            }
        }
    }

    /// ∫ f(ω) dω over the directions with θ < `theta_max` (π/2: the upper hemisphere,
    /// π: the sphere), by the midpoint rule in (θ, φ) on a 2000 × 400 grid.
    pub(crate) fn integrate_over_directions(theta_max: f64, f: impl Fn(Vec3A) -> f64) -> f64 {
        let (nt, np) = (2000, 400);
        let mut sum = 0.0f64;
        for i in 0..nt {
            let t = (i as f64 + 0.5) / nt as f64 * theta_max;
            for j in 0..np {
                let p = (j as f64 + 0.5) / np as f64 * 2.0 * PI;
                let m = Vec3A::new(
                    (t.sin() * p.cos()) as f32,
                    (t.sin() * p.sin()) as f32,
                    t.cos() as f32,
                );
                sum += f(m) * t.sin();
            }
        }
        sum * (theta_max / nt as f64) * (2.0 * PI / np as f64)
    }

    fn hemisphere_integral(f: impl Fn(Vec3A) -> f64) -> f64 {
        integrate_over_directions(PI / 2.0, f)
    }

    /// The visible-normal sampler draws from its stated density: moments of the sampled
    /// normals (mean of m_x, m_y, m_z, m_x m_y over a stratified grid of samples) equal
    /// the same moments of `pdf` by quadrature.
    #[test]
    fn visible_normal_sampling_matches_its_pdf() {
        for kind in [MicrofacetType::Beckmann, MicrofacetType::Ggx] {
            let d = Microfacet::new(kind, 0.4, 0.25);
            for wi in [
                Vec3A::new(0.5, -0.3, 0.6).normalize(),
                Vec3A::new(0.1, 0.0, 0.99).normalize(),
            ] {
                let n = 300;
                let mut sampled = [0.0f64; 4];
                for i in 0..n {
                    for j in 0..n {
                        let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                        let (m, pdf) = d.sample(wi, u);
                        assert!(
                            m.is_finite() && m.z > 0.0 && pdf > 0.0,
                            "{kind:?} {m} {pdf}"
                        );
                        for (s, g) in sampled.iter_mut().zip([m.x, m.y, m.z, m.x * m.y]) {
                            *s += g as f64 / (n * n) as f64;
                        }
                    }
                }
                let moments = [
                    hemisphere_integral(|m| (m.x * d.pdf(wi, m)) as f64),
                    hemisphere_integral(|m| (m.y * d.pdf(wi, m)) as f64),
                    hemisphere_integral(|m| (m.z * d.pdf(wi, m)) as f64),
                    hemisphere_integral(|m| (m.x * m.y * d.pdf(wi, m)) as f64),
                ];
                for (k, (s, q)) in sampled.iter().zip(moments).enumerate() {
                    // Beckmann's G1 is a fit, so its pdf is ~1% off the exact VNDF.
                    assert!(
                        (s - q).abs() < 1e-2,
                        "{kind:?} wi {wi} moment {k}: sampled {s}, pdf {q}"
                    );
                }
            }
        }
    }

    /// The visible normals integrate to one: ∫ D G1(wi) (wi·m)⁺ / cos θ_i dm = 1 (checked
    /// by quadrature over the sampler's square, whose Jacobian is 1/pdf).
    #[test]
    fn smith_g1_normalizes_the_visible_normals() {
        for kind in [MicrofacetType::Beckmann, MicrofacetType::Ggx] {
            let d = Microfacet::new(kind, 0.3, 0.3);
            for cos_i in [0.95f32, 0.6, 0.25] {
                let wi = Vec3A::new((1.0 - cos_i * cos_i).sqrt(), 0.0, cos_i);
                let sum = hemisphere_integral(|m| {
                    (d.eval(m) * d.smith_g1(wi, m) * wi.dot(m).max(0.0) / wi.z) as f64
                });
                // Beckmann's G1 is a fit (within about 1%), GGX's is exact.
                let tol = if kind == MicrofacetType::Ggx {
                    5e-3
                } else {
                    1.5e-2
                };
                assert!((sum - 1.0).abs() < tol, "{kind:?} cos {cos_i}: {sum}");
            }
        }
    }
}
