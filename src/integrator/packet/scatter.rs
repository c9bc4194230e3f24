//! Directions in lanes, each by the one kernel the scalar path also calls:
//! Henyey–Greenstein sampling and evaluation (`medium::phase`), Lambert's cosine law
//! (`sampling::warp`), and the cone of a sphere light (`geometry::shape`). What is left
//! here is the packet's own bookkeeping: which lanes' samples are valid.

use glam::Vec3;
use wide::CmpGt;

use super::lanes::{L, V3};
use crate::geometry::shape::sample_sphere_cone;
use crate::geometry::to_world;
use crate::medium::phase::{direction_at, hg_sample_angle};
use crate::sampling::warp::cosine_hemisphere;

/// The direction after a Henyey–Greenstein scattering of light travelling along `d`
/// (unit), from uniform `u1`, `u2` (`Phase::sample`'s, in f32: the packet takes only
/// moderate |g|). Sampling is exact: the weight is 1. With the sample's 1 − cos θ (for
/// the derivative in g).
#[inline(always)]
pub fn sample_hg(d: V3, g: L, u1: L, u2: L) -> (V3, L) {
    let w = hg_sample_angle(g, u1);
    (direction_at(d, w, u2), w)
}

/// A cosine-weighted direction about the unit normal `n` (pdf cos θ / π), by Malley's
/// method on the concentric disk, as the scalar BSDF samples it.
#[inline(always)]
pub fn sample_cosine(n: V3, u1: L, u2: L) -> V3 {
    to_world(n, cosine_hemisphere(u1, u2))
}

/// A direction toward a sphere from [`sample_cone`].
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

/// `geometry::shape::sample_sphere_cone` in lanes, with the lanes whose sample is valid.
#[inline(always)]
pub fn sample_cone(center: Vec3, radius: f32, p: V3, u1: L, u2: L) -> ConeLanes {
    let c = sample_sphere_cone(V3::splat(center), radius, p, u1, u2);
    // The outward normal where it meets the sphere must face back along d.
    let toward_center = V3::splat(center).sub(p).sub(c.d.scale(c.dist));
    let ok = !c.inside
        & c.dist.cmp_gt(L::ZERO)
        & toward_center.dot(c.d).cmp_gt(L::ZERO)
        & c.pdf.is_finite();
    ConeLanes {
        d: c.d,
        dist: c.dist,
        pdf: c.pdf,
        ok,
        inside: c.inside,
    }
}
