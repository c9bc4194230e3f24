//! The caster of obvhs's compressed wide BVH (CWBVH), traversed with this module's
//! node test ([`node_hits`]) and leaf test ([`LeafTriangle`], read from the copy in
//! leaf order). It holds triangles only, or, where analytic shapes are many
//! ([`super::build::SEPARATE_ANALYTIC`]), them too ("mixed").

use glam::Vec3A;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::Ray as BvhRay;

use super::hit::{Crossing, Crossings, Hit};
use super::node::{node_hits, traversal_ray};
use super::primitive::Primitives;
use crate::geometry::shape::Geometry;

pub(super) struct Bvh {
    pub cwbvh: CwBvh,
    /// Whether it holds analytic shapes too (else triangles only).
    pub mixed: bool,
}

impl Bvh {
    /// Closest-hit traversal (obvhs's `ray_traverse` with [`node_hits`] as its node
    /// test): `leaf(tmax, primitive)` tests a primitive against the ray as far as `tmax`
    /// and answers its hit distance (∞ for none); a closer one shortens the ray, and a
    /// distance ≤ 0 ends the traversal.
    #[inline(always)]
    fn traverse(&self, ray: BvhRay, mut leaf: impl FnMut(f32, usize) -> f32) {
        use glam::UVec2;
        let mut ray = ray;
        let mut state = self.cwbvh.new_traversal(ray.direction);
        let mut node;
        'done: {
            obvhs::traverse!(
                self.cwbvh,
                node,
                state,
                node_hits(node, &ray, state.oct_inv4),
                {
                    let t = leaf(ray.tmax, state.primitive_id as usize);
                    if t < ray.tmax {
                        ray.tmax = t;
                        if t <= 0.0 {
                            break 'done;
                        }
                    }
                }
            );
        }
    }

    /// The hit of the ray with primitive `i`: a triangle, unless the BVH is mixed.
    #[inline(always)]
    fn leaf_intersect(
        &self,
        prims: &Primitives,
        shapes: &[Geometry],
        i: usize,
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
    ) -> Option<(f32, f32, f32)> {
        if !self.mixed {
            return prims.triangles[i].intersect(o, d, tmax);
        }
        // A BVH that holds analytic shapes (more than SEPARATE_ANALYTIC, rare) tests
        // them out of line: inlined, they made every BVH's leaf test too large to be
        // inlined into its traversal (a call per triangle, 1-3% on the meshes).
        #[inline(never)]
        fn mixed(
            prims: &Primitives,
            shapes: &[Geometry],
            i: usize,
            ray: (Vec3A, Vec3A, f32),
        ) -> Option<(f32, f32, f32)> {
            prims.intersect(shapes, i, ray.0, ray.1, ray.2)
        }
        mixed(prims, shapes, i, (o, d, tmax))
    }

    /// The closest hit, 0 < t < tmax, among the primitives of a shape `keep` accepts.
    #[inline(always)]
    pub fn intersect_where(
        &self,
        prims: &Primitives,
        shapes: &[Geometry],
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
        keep: impl Fn(u32) -> bool,
    ) -> Option<Hit> {
        let (ray, back) = traversal_ray(o, d, tmax);
        let mut best_prim = None;
        self.traverse(ray, |ray_tmax, id| {
            if !keep(prims.refs[id].shape) {
                return f32::INFINITY;
            }
            match self.leaf_intersect(prims, shapes, id, o, d, ray_tmax - back) {
                Some((t, u, v)) => {
                    best_prim = Some((id, t, u, v));
                    t + back
                }
                None => f32::INFINITY,
            }
        });
        best_prim.map(|(id, t, u, v)| prims.hit(id, t, u, v))
    }

    /// Whether any primitive meets the ray, 0 < t < tmax.
    #[inline(always)]
    pub fn occluded(
        &self,
        prims: &Primitives,
        shapes: &[Geometry],
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
    ) -> bool {
        let (ray, back) = traversal_ray(o, d, tmax);
        let mut blocked = false;
        self.traverse(ray, |ray_tmax, id| {
            match self.leaf_intersect(prims, shapes, id, o, d, ray_tmax - back) {
                // Any hit answers: a distance of 0 ends the traversal.
                Some(_) => {
                    blocked = true;
                    0.0
                }
                None => f32::INFINITY,
            }
        });
        blocked
    }

    /// Every triangle crossing, 0 < t < tmax, to `record` (see
    /// [`super::Accel::crossings`]) until it answers; unsupported where the BVH is mixed.
    /// (A mixed BVH has nothing beside it, no analytic shape nor cube, that could have
    /// answered first: it holds them all.)
    #[inline(always)]
    pub fn crossings(
        &self,
        prims: &Primitives,
        shapes: &[Geometry],
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
        record: &mut impl FnMut(Crossing) -> Option<Crossings>,
    ) -> Crossings {
        if self.mixed {
            return Crossings::Unsupported;
        }
        let mut answer = None;
        let mut each = |id: usize, t: f32| {
            answer = record(prims.triangle_crossing(shapes, prims.refs[id].shape, id, t, d));
            answer.is_none()
        };
        let (ray, _) = traversal_ray(o, d, tmax);
        self.traverse(ray, |_, id| {
            match prims.triangles[id].intersect(o, d, tmax) {
                // Not a closer hit for the traversal: the ray's extent stays; a distance
                // of 0 culls every remaining node, and the traversal ends.
                Some((t, _, _)) if !each(id, t) => 0.0,
                _ => f32::INFINITY,
            }
        });
        answer.unwrap_or(Crossings::Found)
    }
}
