//! Shadow rays' transmittance in volpath: through `null` (and `thindielectric`)
//! boundaries, the media between them, each segment exact (homogeneous) or by ratio
//! tracking (heterogeneous).

use glam::Vec3A;

use super::{medium_after, medium_beyond, AdjointParams};
use crate::geometry::accel::{Crossing, CrossingList, Crossings};
use crate::medium::Transmitted;
use crate::sampling::Pcg32;
use crate::scene::Scene;
use crate::simd::Vector3;

/// Null-boundary crossings a shadow ray may make before it is treated as blocked
/// (guards against a degenerate scene trapping the ray).
const MAX_SHADOW_CROSSINGS: u32 = 256;

/// A shadow ray: from `o` along unit `d` over `dist`, starting in `medium`.
#[derive(Clone, Copy, Debug)]
pub(super) struct ShadowRay {
    pub o: Vec3A,
    pub d: Vec3A,
    pub dist: f32,
    pub medium: Option<u32>,
}

/// What a shadow ray's transmittance is differentiated in: forward mode's extinction of
/// one medium (`extinction`), or reverse mode's voxels (`adjoint`: that medium is tracked
/// by `medium::differential`, and where `record` is given each tentative collision in
/// it is pushed there as (point, −scale / σ_n), the factor of ∂ ln T in the voxels
/// about that point, for the caller to scatter once the ray's contribution is known).
pub(super) struct ShadowDerivative<'r> {
    pub extinction: Option<u32>,
    pub adjoint: Option<AdjointParams>,
    pub record: Option<&'r mut Vec<(Vec3A, f32)>>,
}

#[cfg(test)]
impl ShadowDerivative<'_> {
    /// Forward mode in `extinction`'s extinction (or nothing).
    pub fn forward(extinction: Option<u32>) -> ShadowDerivative<'static> {
        ShadowDerivative {
            extinction,
            adjoint: None,
            record: None,
        }
    }
}

/// Transmittance along `ray`: the product of `e^{−σ_t s}` over the segments, through
/// `null` surfaces (switching medium by the side crossed) and `thindielectric` ones
/// (times their transmission); 0 if any other surface blocks the way; differentiated as
/// `diff` says.
///
/// Where the accelerator can, it finds every crossing in one traversal
/// ([`Scene::crossings`]); else one ray is
/// cast per crossing, as Mitsuba does.
pub(super) fn shadow_transmittance(
    scene: &Scene,
    ray: ShadowRay,
    diff: &mut ShadowDerivative,
    rng: &mut Pcg32,
) -> Transmitted<f32> {
    let mut hits = CrossingList::new();
    match scene.crossings(ray.o, ray.d, ray.dist, &mut hits) {
        Crossings::Blocked => Transmitted::blocked(),
        Crossings::Found => through_crossings(scene, ray, diff, &mut hits, rng),
        Crossings::Unsupported => shadow_transmittance_stepwise(scene, ray, diff, rng),
    }
}

/// The transmittance along `ray` whose pass-through crossings
/// are `hits` (in any order): the segments between them in turn, each in the medium
/// the previous crossing entered. A surface found twice at one distance (on an edge
/// shared by two triangles) changes nothing: the second crossing enters the medium the
/// first did, after a segment of length 0.
pub(super) fn through_crossings(
    scene: &Scene,
    ray: ShadowRay,
    diff: &mut ShadowDerivative,
    hits: &mut [Crossing],
    rng: &mut Pcg32,
) -> Transmitted<f32> {
    let ShadowRay {
        o,
        d,
        dist,
        mut medium,
    } = ray;
    hits.sort_unstable_by(|a, b| a.t.total_cmp(&b.t));
    let mut tr = Transmitted::clear();
    let mut start = 0.0f32;
    for h in hits.iter() {
        if let Some(m) = medium {
            let seg = (o + d * start, d, h.t - start);
            tr = tr.then(segment_transmittance(scene, m, seg, diff, rng));
        }
        start = h.t;
        medium = medium_beyond(&scene.shapes[h.shape as usize], h.along_normal, medium);
    }
    if let Some(m) = medium {
        let seg = (o + d * start, d, dist - start);
        tr = tr.then(segment_transmittance(scene, m, seg, diff, rng));
    }
    tr
}

/// The transmittance of a segment `(o, d, len)` in medium `m`
/// (`Medium::segment_transmittance`), or where `m`'s voxels are differentiated in
/// reverse mode, `medium::differential`'s ratio tracking, which records where it looked.
#[inline]
pub(super) fn segment_transmittance(
    scene: &Scene,
    m: u32,
    (o, d, len): (Vec3A, Vec3A, f32),
    diff: &mut ShadowDerivative,
    rng: &mut Pcg32,
) -> Transmitted<f32> {
    let med = &scene.media[m as usize];
    if let (Some(h), Some(a)) = (med.heterogeneous.as_deref(), diff.adjoint) {
        if a.medium == m {
            let record = &mut diff.record;
            let tr = a.tracking.ratio_tracking(h, o, d, len, rng, |p, sigma_n| {
                if let Some(r) = record.as_deref_mut() {
                    r.push((p, -h.scale / sigma_n));
                }
            });
            return Transmitted {
                tr: tr.into(),
                d_log: Vector3::all(0.0),
            };
        }
    }
    let chosen = diff.extinction == Some(m);
    med.segment_transmittance((o.into(), d.into()), (0.0, len), true, chosen, rng)
}

/// [`shadow_transmittance`] by one closest-hit cast per crossing.
pub(super) fn shadow_transmittance_stepwise(
    scene: &Scene,
    ray: ShadowRay,
    diff: &mut ShadowDerivative,
    rng: &mut Pcg32,
) -> Transmitted<f32> {
    let ShadowRay {
        mut o,
        d,
        mut dist,
        mut medium,
    } = ray;
    let mut tr = Transmitted::clear();
    for _ in 0..MAX_SHADOW_CROSSINGS {
        if dist <= 0.0 {
            return tr;
        }
        let hit = scene.intersect(o, d, dist);
        let seg = hit.map_or(dist, |h| h.t);
        if let Some(m) = medium {
            tr = tr.then(segment_transmittance(scene, m, (o, d, seg), diff, rng));
        }
        let Some(h) = hit else { return tr };
        let info = &scene.shapes[h.shape as usize];
        // Through a null or thin-dielectric surface, by what it lets through; any
        // other surface blocks.
        let passed = scene.bsdfs[info.bsdf as usize].null_transmission(h.sh_frame.n.dot(d), h.uv);
        tr.tr = tr.tr.mul(passed.into());
        if tr.tr == Vector3::all(0.0) {
            return Transmitted::blocked();
        }
        medium = medium_after(info, h.n, d, medium);
        let o2 = h.offset_p(d, scene.offset_scale);
        dist -= (o2 - o).length();
        o = o2;
    }
    Transmitted::blocked()
}
