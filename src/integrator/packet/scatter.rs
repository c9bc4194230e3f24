//! Directions in lanes: Henyey–Greenstein sampling and evaluation (`medium::phase`'s
//! forms, by the distance from the peak), Lambert's cosine-weighted sampling, and the
//! frame around a direction they are drawn in.

use wide::CmpGe;

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
