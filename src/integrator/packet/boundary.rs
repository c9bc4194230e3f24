//! A smooth dielectric boundary of a medium shape in lanes: `bsdf::Dielectric::sample`.

use glam::Vec3;
use wide::CmpEq;

use super::lanes::{L, V3};
use super::medium_normals;
use super::scene::PacketScene;
use crate::bsdf::dielectric::sample_smooth;
use crate::geometry::{coordinate_system, to_world};
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
/// lanes of `mask` are on at `o`, light arriving along `d`: its kernel
/// (`dielectric::sample_smooth`) in the frame around the outward normal (the boundary is
/// isotropic: any frame about it gives the same directions). The draws are the scalar
/// path's for a BSDF sample (a 1-D one choosing the lobe, a 2-D one unused here).
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
            refl = refl.select(here, V3::splat(b.specular_reflectance));
            trans = trans.select(here, V3::splat(b.specular_transmittance));
        }
    }
    let u = rngs.draw_1d(mask);
    let _ = rngs.draw_2d(mask);
    let (s, t) = coordinate_system(n);
    let wi = V3::splat(Vec3::ZERO).sub(d);
    let local = V3::new(wi.dot(s), wi.dot(t), wi.dot(n));
    let b = sample_smooth(eta, (refl, trans), local, u);
    BoundarySample {
        n,
        wo: to_world(n, b.wo),
        pdf: b.pdf,
        weight: b.weight,
        eta: b.eta,
    }
}
