//! Directions in lanes: Henyey–Greenstein sampling and evaluation (`medium::phase`'s
//! forms, by the distance from the peak), Lambert's cosine-weighted sampling, the cone
//! of a sphere light, and the frame around a direction they are drawn in.

use glam::Vec3;
use wide::{CmpGe, CmpGt, CmpLe};

use crate::geometry::RAY_EPSILON;

use super::lanes::{L, V3};

const INV_FOUR_PI: f32 = 1.0 / (4.0 * std::f32::consts::PI);

/// `geometry::Frame::new(n)`: Duff et al.'s branchless orthonormal basis, `local` taken
/// to the world.
#[inline(always)]
fn to_world(n: V3, lx: L, ly: L, lz: L) -> V3 {
    let one = L::ONE;
    let sign = one.copysign(n.z);
    let a = -one / (sign + n.z);
    let b = n.x * n.y * a;
    let s = V3 {
        x: one + sign * n.x * n.x * a,
        y: sign * b,
        z: -sign * n.x,
    };
    let t = V3 {
        x: b,
        y: sign + n.y * n.y * a,
        z: -n.y,
    };
    s.scale(lx).add(t.scale(ly)).add(n.scale(lz))
}

/// The direction at cos θ = `cos_theta` from `n` and azimuth 2π `u`.
#[inline(always)]
fn around(n: V3, cos_theta: L, sin_theta: L, u: L) -> V3 {
    let (sin_phi, cos_phi) = (L::splat(2.0 * std::f32::consts::PI) * u).sin_cos();
    to_world(n, sin_theta * cos_phi, sin_theta * sin_phi, cos_theta)
}

/// The direction after a Henyey–Greenstein scattering of light travelling along `d`
/// (unit), from uniform `u1`, `u2`. With a = |g|, q = 1 + a − 2au and s = (1 − a²)/q,
/// the distance from the peak is
///   w = (1 − a) u (s + 1 − a) / q,
/// cos θ = 1 − w for g ≥ 0 and w − 1 for g < 0 (the peak backwards); g = 0 gives
/// w = 2u, the isotropic law. Sampling is exact: the weight is 1.
#[inline(always)]
pub fn sample_hg(d: V3, g: L, u1: L, u2: L) -> V3 {
    let one = L::ONE;
    let two = L::splat(2.0);
    let a = g.abs();
    let q = one + a - two * a * u1;
    let s = (one - a * a) / q;
    let w = ((one - a) * u1 * (s + one - a) / q).max(L::ZERO).min(two);
    let w = g.cmp_ge(L::ZERO).blend(w, two - w);
    let sin_theta = (w * (two - w)).max(L::ZERO).sqrt();
    around(d, one - w, sin_theta, u2)
}

/// p_HG(cos θ) = (1 − g²) / (4π (1 + g² − 2g cos θ)^{3/2}), with 1 + g² − 2g cos θ
/// written (1 − |g|)² + 2|g| w, w = 1 ∓ cos θ, free of cancellation at the peak.
#[inline(always)]
pub fn eval_hg(g: L, cos_theta: L) -> L {
    let one = L::ONE;
    let a = g.abs();
    let w = g.cmp_ge(L::ZERO).blend(one - cos_theta, one + cos_theta);
    let denom = (one - a) * (one - a) + L::splat(2.0) * a * w;
    (one - g * g) * L::splat(INV_FOUR_PI) / (denom * denom.sqrt())
}

/// A cosine-weighted direction about the unit normal `n` (pdf cos θ / π), by the
/// polar map: cos θ = √(1 − u1), azimuth 2π u2.
#[inline(always)]
pub fn sample_cosine(n: V3, u1: L, u2: L) -> V3 {
    let cos_theta = (L::ONE - u1).max(L::ZERO).sqrt();
    around(n, cos_theta, u1.sqrt(), u2)
}

/// A direction toward a sphere from [`sample_sphere_cone`].
pub struct ConeLanes {
    /// Unit direction from the reference point.
    pub d: V3,
    /// Distance to where it meets the sphere.
    pub dist: L,
    /// Solid-angle pdf.
    pub pdf: L,
    /// The lanes whose point sees the sphere from outside and whose sample is valid
    /// (the light's side faces it, the pdf is finite).
    pub ok: L,
    /// The lanes whose point is inside the sphere (deeper than the ray epsilon): the
    /// scalar code samples its area there.
    pub inside: L,
}

/// `geometry::Sphere::sample_cone` in lanes: a direction uniform in the cone of the cap
/// of the sphere (`center`, `radius`) visible from `p`, pdf 1 / (2π (1 − cos θ_max)),
/// and the distance to the nearer root,
///   t = (|c|² − r²) / (|c| cos θ + √(r² − |c|² sin² θ)),   c = center − p,
/// the product of the roots over the larger one, so that nothing cancels. Small cones
/// (sin² θ_max below Mitsuba's 1.5° threshold) take sin² θ = sin² θ_max u1 instead of
/// 1 − cos² θ.
#[inline(always)]
pub fn sample_sphere_cone(center: Vec3, radius: f32, p: V3, u1: L, u2: L) -> ConeLanes {
    let one = L::ONE;
    let c = V3::splat(center).sub(p);
    let dc2 = c.dot(c);
    let r2 = L::splat(radius * radius);
    // Points on the surface count as outside (they see a hemisphere), as in Mitsuba.
    let r_adj = radius * (1.0 - RAY_EPSILON);
    let inside = dc2.cmp_le(L::splat(r_adj * r_adj));
    let sin2_max = r2 / dc2;
    let cos_max = (one - sin2_max).max(L::ZERO).sqrt();
    let wide_cone = sin2_max.cmp_gt(L::splat(0.000_685_23));
    let cos_wide = (cos_max - one) * u1 + one;
    let sin2_small = sin2_max * u1;
    let cos_t = wide_cone.blend(cos_wide, (one - sin2_small).max(L::ZERO).sqrt());
    let sin2 = wide_cone.blend((one - cos_wide * cos_wide).max(L::ZERO), sin2_small);
    let dc_len = dc2.sqrt();
    let d = around(c.div(dc_len), cos_t, sin2.sqrt(), u2);
    let half_chord = (r2 - dc2 * sin2).max(L::ZERO).sqrt();
    let dist = (dc2 - r2) / (dc_len * cos_t + half_chord);
    // The outward normal where it meets the sphere must face back along d.
    let toward_center = c.sub(d.scale(dist));
    let pdf = one / (L::splat(2.0 * std::f32::consts::PI) * (one - cos_max));
    let ok =
        !inside & dist.cmp_gt(L::ZERO) & toward_center.dot(d).cmp_gt(L::ZERO) & pdf.is_finite();
    ConeLanes {
        d,
        dist,
        pdf,
        ok,
        inside,
    }
}
