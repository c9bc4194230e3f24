//! The caster of a scene of few primitives ([`BRUTE_FORCE_PRIMS`]): each one tested in
//! turn, in input order, without a BVH. The list may hold analytic shapes and triangles
//! together.

use glam::Vec3A;

use super::hit::{Crossing, Crossings, Hit};
use super::primitive::{analytic_crossing, analytic_hits, Primitives, ANALYTIC};
use crate::geometry::shape::Geometry;

/// Up to this many primitives, testing each beats traversing the BVH: the furnace (one
/// sphere) renders ~30% faster; the medium cube (14 primitives) ~10% slower, so the
/// limit stays well below that.
pub(super) const BRUTE_FORCE_PRIMS: usize = 4;

/// The closest hit, 0 < t < tmax, among the primitives of a shape `keep` accepts.
#[inline(always)]
pub(super) fn intersect_where(
    prims: &Primitives,
    shapes: &[Geometry],
    o: Vec3A,
    d: Vec3A,
    tmax: f32,
    keep: impl Fn(u32) -> bool,
) -> Option<Hit> {
    let mut best = None;
    let mut t_best = tmax;
    for i in 0..prims.len() {
        if !keep(prims.refs[i].shape) {
            continue;
        }
        if let Some((t, u, v)) = prims.intersect(shapes, i, o, d, t_best) {
            t_best = t;
            best = Some(prims.hit(i, t, u, v));
        }
    }
    best
}

/// Whether any primitive meets the ray, 0 < t < tmax.
#[inline(always)]
pub(super) fn occluded(
    prims: &Primitives,
    shapes: &[Geometry],
    o: Vec3A,
    d: Vec3A,
    tmax: f32,
) -> bool {
    (0..prims.len()).any(|i| prims.intersect(shapes, i, o, d, tmax).is_some())
}

/// Every crossing, 0 < t < tmax, to `record` (see [`super::Accel::crossings`]) until it
/// answers.
#[inline(always)]
pub(super) fn crossings(
    prims: &Primitives,
    shapes: &[Geometry],
    o: Vec3A,
    d: Vec3A,
    tmax: f32,
    record: &mut impl FnMut(Crossing) -> Option<Crossings>,
) -> Crossings {
    for (i, p) in prims.refs.iter().enumerate() {
        let answer = if p.index == ANALYTIC {
            analytic_hits(shapes, p.shape, o, d, tmax)
                .into_iter()
                .flatten()
                .find_map(|t| record(analytic_crossing(shapes, p.shape, o, d, t)))
        } else {
            prims.triangles[i]
                .intersect(o, d, tmax)
                .and_then(|(t, _, _)| record(prims.triangle_crossing(shapes, p.shape, i, t, d)))
        };
        if let Some(answer) = answer {
            return answer;
        }
    }
    Crossings::Found
}
