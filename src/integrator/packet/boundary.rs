//! A smooth dielectric boundary of a medium shape in lanes: `bsdf::Dielectric::sample`.

use glam::Vec3;
use wide::{CmpEq, CmpLe};

use super::lanes::{L, V3};
use super::medium_normals;
use super::scene::PacketScene;
use crate::bsdf::fresnel::fresnel;
use crate::sampling::{Pcg32, Sampler};

/// A dielectric boundary's sample: the outward normal, the new direction, its pdf (0:
/// none), the weight and the relative index the path's η takes.
pub struct BoundarySample {
    pub n: V3,
    pub wo: V3,
    pub pdf: L,
    pub weight: V3,
    pub eta: L,
}

/// `bsdf::Dielectric::sample` in lanes at the boundaries of medium shapes `shape` the
/// lanes of `mask` are on at `o`, light arriving along `d`: reflection with Fresnel's
/// probability R (`bsdf::fresnel`), weight ρ_s; else refraction, weight τ_s η_ti² (the
/// solid angle's compression, radiance transport). The draws are the scalar path's for
/// a BSDF sample (a 1-D one choosing the lobe, a 2-D one unused here).
pub fn boundary_sample(
    ps: &PacketScene,
    shape: L,
    mask: L,
    (o, d): (V3, V3),
    rngs: &mut [Pcg32],
) -> BoundarySample {
    let n = medium_normals(ps, shape, o, mask);
    let (mut eta, mut refl, mut trans) = (L::ONE, V3::splat(Vec3::ONE), V3::splat(Vec3::ONE));
    for (i, m) in ps.media_shapes.iter().enumerate() {
        let Some(b) = m.dielectric else { continue };
        let here = mask & shape.cmp_eq(L::splat(i as f32));
        if here.any() {
            eta = here.blend(L::splat(b.eta), eta);
            refl = refl.select(here, V3::splat(b.reflectance));
            trans = trans.select(here, V3::splat(b.transmittance));
        }
    }
    let u = rngs.draw_1d(mask);
    let _ = rngs.draw_2d(mask);
    // Fresnel (`bsdf::fresnel`): cos θ_i of wi = −d about the outward normal.
    let one = L::ONE;
    let cos_i = -d.dot(n);
    let (r, cos_t, eta_it, eta_ti) = fresnel(cos_i, eta);
    let reflect = u.cmp_le(r);
    // Reflection: 2 (wi·n) n − wi; refraction: −η_ti (wi − (wi·n) n) + cos θ_t n.
    let wi = V3::splat(Vec3::ZERO).sub(d);
    let wo_r = n.scale(L::splat(2.0) * cos_i).sub(wi);
    let wo_t = wi.sub(n.scale(cos_i)).scale(-eta_ti).add(n.scale(cos_t));
    BoundarySample {
        n,
        wo: wo_t.select(reflect, wo_r),
        pdf: reflect.blend(r, one - r),
        weight: trans.scale(eta_ti * eta_ti).select(reflect, refl),
        eta: reflect.blend(one, eta_it),
    }
}
