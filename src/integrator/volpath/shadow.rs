//! Shadow rays' transmittance in volpath: through `null` (and `thindielectric`)
//! boundaries, the media between them, each segment exact (homogeneous) or by ratio
//! tracking (heterogeneous).

use glam::{Vec3, Vec3A};

use super::{medium_after, medium_beyond};
use crate::geometry::accel::{Crossing, CrossingList, Crossings};
use crate::geometry::offset_point;
use crate::medium::transmittance;
use crate::sampling::Pcg32;
use crate::scene::Scene;

/// Null-boundary crossings a shadow ray may make before it is treated as blocked
/// (guards against a degenerate scene trapping the ray).
const MAX_SHADOW_CROSSINGS: u32 = 256;

/// Transmittance from `o` along unit `d` over `dist`, starting in `medium`: the product
/// of `e^{−σ_t s}` over the segments, through `null` surfaces (switching medium by the
/// side crossed) and `thindielectric` ones (times their transmission); 0 if any other
/// surface blocks the way.
///
/// Where the accelerator can, it finds every crossing in one traversal
/// ([`Scene::crossings`]); else one ray is
/// cast per crossing, as Mitsuba does.
pub(super) fn shadow_transmittance(
    scene: &Scene,
    o: Vec3A,
    d: Vec3A,
    dist: f32,
    medium: Option<u32>,
    rng: &mut Pcg32,
) -> Vec3 {
    let mut hits = CrossingList::new();
    match scene.crossings(o, d, dist, &mut hits) {
        Crossings::Blocked => Vec3::ZERO,
        Crossings::Found => through_crossings(scene, o, d, dist, medium, &mut hits, rng),
        Crossings::Unsupported => shadow_transmittance_stepwise(scene, o, d, dist, medium, rng),
    }
}

/// The transmittance of a shadow ray over `dist` whose pass-through crossings
/// are `hits` (in any order): the segments between them in turn, each in the medium
/// the previous crossing entered. A surface found twice at one distance (on an edge
/// shared by two triangles) changes nothing: the second crossing enters the medium the
/// first did, after a segment of length 0.
pub(super) fn through_crossings(
    scene: &Scene,
    o: Vec3A,
    d: Vec3A,
    dist: f32,
    mut medium: Option<u32>,
    hits: &mut [Crossing],
    rng: &mut Pcg32,
) -> Vec3 {
    hits.sort_unstable_by(|a, b| a.t.total_cmp(&b.t));
    let mut tr = Vec3::ONE;
    let mut start = 0.0f32;
    for h in hits.iter() {
        if let Some(m) = medium {
            tr *= segment_transmittance(scene, m, o + d * start, d, h.t - start, rng);
        }
        start = h.t;
        medium = medium_beyond(&scene.shapes[h.shape as usize], h.along_normal, medium);
    }
    if let Some(m) = medium {
        tr *= segment_transmittance(scene, m, o + d * start, d, dist - start, rng);
    }
    tr
}

/// The transmittance of a segment from `o` along `d` of length `len` in medium `m`:
/// Beer–Lambert in a homogeneous medium, ratio tracking (an unbiased estimate) in a
/// heterogeneous one.
#[inline]
pub(super) fn segment_transmittance(
    scene: &Scene,
    m: u32,
    o: Vec3A,
    d: Vec3A,
    len: f32,
    rng: &mut Pcg32,
) -> Vec3 {
    let med = &scene.media[m as usize];
    match &med.heterogeneous {
        None => transmittance(med.sigma_t, len),
        Some(h) => h.transmittance(o, d, len, rng),
    }
}

/// [`shadow_transmittance`] by one closest-hit cast per crossing.
pub(super) fn shadow_transmittance_stepwise(
    scene: &Scene,
    mut o: Vec3A,
    d: Vec3A,
    mut dist: f32,
    mut medium: Option<u32>,
    rng: &mut Pcg32,
) -> Vec3 {
    let mut tr = Vec3::ONE;
    for _ in 0..MAX_SHADOW_CROSSINGS {
        if dist <= 0.0 {
            return tr;
        }
        let hit = scene.intersect(o, d, dist);
        let seg = hit.map_or(dist, |h| h.t);
        if let Some(m) = medium {
            tr *= segment_transmittance(scene, m, o, d, seg, rng);
        }
        let Some(h) = hit else { return tr };
        let info = &scene.shapes[h.shape as usize];
        // Through a null or thin-dielectric surface, by what it lets through; any
        // other surface blocks.
        tr *= scene.bsdfs[info.bsdf as usize].null_transmission(h.sh_frame.n.dot(d), h.uv);
        if tr == Vec3::ZERO {
            return Vec3::ZERO;
        }
        medium = medium_after(info, h.n, d, medium);
        let o2 = offset_point(h.p, h.n, d, scene.offset_scale);
        dist -= (o2 - o).length();
        o = o2;
    }
    Vec3::ZERO
}
