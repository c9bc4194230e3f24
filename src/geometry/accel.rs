//! One compressed wide BVH (obvhs CWBVH) over every primitive of the scene: each
//! triangle of each mesh, and each analytic shape as a single primitive.

use std::time::Duration;

use glam::Vec3A;
use obvhs::aabb::Aabb;
use obvhs::cwbvh::builder::build_cwbvh;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::{Ray as BvhRay, RayHit};
use obvhs::BvhBuildParams;

use super::shape::Geometry;
use super::Bounds;

/// Which primitive of which shape; `index` is [`ANALYTIC`] for a sphere, rectangle or
/// disk (one primitive per shape).
#[derive(Clone, Copy, Debug)]
struct PrimRef {
    shape: u32,
    index: u32,
}

const ANALYTIC: u32 = u32::MAX;

/// A triangle as the intersection test reads it: `p0` and the edges `e1 = p1 − p0`,
/// `e2 = p2 − p0`, precomputed and stored in the BVH's leaf order, so that a leaf's
/// triangles are one contiguous read instead of an index lookup and three vertex loads
/// each (a ray in a 100k-triangle mesh is bound by memory latency, not arithmetic).
#[derive(Clone, Copy, Debug)]
struct LeafTriangle {
    p0: Vec3A,
    e1: Vec3A,
    e2: Vec3A,
}

impl LeafTriangle {
    /// Möller–Trumbore: (t, u, v), u and v the barycentrics of vertices 1 and 2.
    #[inline(always)]
    fn intersect(&self, o: Vec3A, d: Vec3A, tmax: f32) -> Option<(f32, f32, f32)> {
        let pv = d.cross(self.e2);
        let det = self.e1.dot(pv);
        if det == 0.0 {
            return None;
        }
        let inv = 1.0 / det;
        let tv = o - self.p0;
        let u = tv.dot(pv) * inv;
        if !(0.0..=1.0).contains(&u) {
            return None;
        }
        let qv = tv.cross(self.e1);
        let v = d.dot(qv) * inv;
        if v < 0.0 || u + v > 1.0 {
            return None;
        }
        let t = self.e2.dot(qv) * inv;
        (t > 0.0 && t < tmax).then_some((t, u, v))
    }
}

/// The closest hit of a ray: which shape and primitive, at which distance, and the
/// triangle barycentrics (zero for analytic shapes).
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    pub t: f32,
    pub shape: u32,
    pub prim: u32,
    pub u: f32,
    pub v: f32,
}

/// obvhs's CWBVH node test clamps a box's entry distance to an absolute 1e-4
/// (`cwbvh::node::EPSILON`): a box the ray leaves within 1e-4 of its origin is culled.
/// That loses hits near the origin: every boundary of a scene scaled down, and in a
/// dense medium (σ_t 1e4: a mean free path is 1e-4) the mesh boundary next to a
/// scattering vertex, so the path walks out of the medium unseen.
const NODE_TMIN: f32 = 1e-4;

/// The ray handed to the traversal: started `back` behind `o`, with `back` above the
/// node test's clamp even after rounding `o − back·d` to f32, so every box the true
/// ray meets at t ≥ 0 is visited. Primitives are still intersected with the true ray,
/// and their distances reported to the traversal as `t + back`.
#[inline]
fn traversal_ray(o: Vec3A, d: Vec3A, tmax: f32) -> (BvhRay, f32) {
    let back = 2.0 * NODE_TMIN + o.abs().max_element() * 1e-6;
    (BvhRay::new(o - d * back, d, 0.0, tmax + back), back)
}

/// Up to this many primitives, testing each beats traversing the BVH: the furnace (one
/// sphere) renders ~30% faster; the medium cube (14 primitives) ~10% slower, so the
/// limit stays well below that.
const BRUTE_FORCE_PRIMS: usize = 4;

pub struct Accel {
    bvh: CwBvh,
    /// Primitive `i` of the traversal (`bvh.primitive_indices` already applied).
    prims: Vec<PrimRef>,
    /// Its triangle, when it is one (zeros for analytic shapes).
    triangles: Vec<LeafTriangle>,
    pub bounds: Bounds,
}

impl Accel {
    pub fn build(shapes: &[&Geometry]) -> Accel {
        let mut prims = Vec::new();
        let mut aabbs = Vec::new();
        let mut bounds = Bounds::EMPTY;
        for (si, g) in shapes.iter().enumerate() {
            match g {
                Geometry::Mesh(m) => {
                    for ti in 0..m.triangles.len() as u32 {
                        let mut b = Bounds::EMPTY;
                        for p in m.vertices(ti) {
                            b.expand(p);
                        }
                        prims.push(PrimRef {
                            shape: si as u32,
                            index: ti,
                        });
                        aabbs.push(Aabb {
                            min: b.min,
                            max: b.max,
                        });
                        bounds = bounds.union(&b);
                    }
                }
                Geometry::Sphere(s) => {
                    let b = s.bounds();
                    prims.push(PrimRef {
                        shape: si as u32,
                        index: ANALYTIC,
                    });
                    aabbs.push(Aabb {
                        min: b.min,
                        max: b.max,
                    });
                    bounds = bounds.union(&b);
                }
                Geometry::Planar(p) => {
                    let b = p.bounds();
                    prims.push(PrimRef {
                        shape: si as u32,
                        index: ANALYTIC,
                    });
                    aabbs.push(Aabb {
                        min: b.min,
                        max: b.max,
                    });
                    bounds = bounds.union(&b);
                }
            }
        }
        let bvh = if aabbs.is_empty() {
            CwBvh::default()
        } else {
            build_cwbvh(
                &aabbs,
                // The slowest build (more reinsertion): ~10% faster renders of the
                // Bunny than `medium_build`, for 0.25 s more on a 100k-triangle mesh.
                // Pre-splitting needs the triangles, not boxes.
                BvhBuildParams {
                    pre_split: false,
                    ..BvhBuildParams::very_slow_build()
                },
                &mut Duration::default(),
            )
        };
        // Lay primitives out in traversal order (small scenes are tested in input
        // order, without the BVH).
        if prims.len() > BRUTE_FORCE_PRIMS {
            prims = bvh
                .primitive_indices
                .iter()
                .map(|&i| prims[i as usize])
                .collect();
        }
        let triangles = prims
            .iter()
            .map(|p| match shapes[p.shape as usize] {
                Geometry::Mesh(m) if p.index != ANALYTIC => {
                    let [p0, p1, p2] = m.vertices(p.index);
                    LeafTriangle {
                        p0,
                        e1: p1 - p0,
                        e2: p2 - p0,
                    }
                }
                _ => LeafTriangle {
                    p0: Vec3A::ZERO,
                    e1: Vec3A::ZERO,
                    e2: Vec3A::ZERO,
                },
            })
            .collect();
        Accel {
            bvh,
            prims,
            triangles,
            bounds,
        }
    }

    /// The hit of the ray with traversal primitive `i`, if closer than `tmax`.
    #[inline(always)]
    fn prim_intersect(
        &self,
        shapes: &[Geometry],
        i: usize,
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
    ) -> Option<(f32, f32, f32)> {
        let p = self.prims[i];
        if p.index != ANALYTIC {
            return self.triangles[i].intersect(o, d, tmax);
        }
        match &shapes[p.shape as usize] {
            Geometry::Sphere(s) => s.intersect(o, d, tmax).map(|t| (t, 0.0, 0.0)),
            Geometry::Planar(pl) => pl.intersect(o, d, tmax).map(|t| (t, 0.0, 0.0)),
            Geometry::Mesh(_) => None,
        }
    }

    /// Closest hit along `o + t d`, 0 < t < tmax.
    #[inline]
    pub fn intersect(&self, shapes: &[Geometry], o: Vec3A, d: Vec3A, tmax: f32) -> Option<Hit> {
        if self.prims.is_empty() {
            return None;
        }
        if self.prims.len() <= BRUTE_FORCE_PRIMS {
            let mut best: Option<Hit> = None;
            let mut t_best = tmax;
            for i in 0..self.prims.len() {
                if let Some((t, u, v)) = self.prim_intersect(shapes, i, o, d, t_best) {
                    t_best = t;
                    best = Some(self.hit(i, t, u, v));
                }
            }
            return best;
        }
        let (ray, back) = traversal_ray(o, d, tmax);
        let mut best: Option<Hit> = None;
        let mut rh = RayHit::none();
        self.bvh.ray_traverse(ray, &mut rh, |r, id| {
            match self.prim_intersect(shapes, id, o, d, r.tmax - back) {
                Some((t, u, v)) => {
                    best = Some(self.hit(id, t, u, v));
                    t + back
                }
                None => f32::INFINITY,
            }
        });
        best
    }

    #[inline(always)]
    fn hit(&self, i: usize, t: f32, u: f32, v: f32) -> Hit {
        let p = self.prims[i];
        Hit {
            t,
            shape: p.shape,
            prim: if p.index == ANALYTIC { 0 } else { p.index },
            u,
            v,
        }
    }

    /// Whether anything blocks `o + t d` for 0 < t < tmax.
    #[inline]
    pub fn occluded(&self, shapes: &[Geometry], o: Vec3A, d: Vec3A, tmax: f32) -> bool {
        if self.prims.is_empty() {
            return false;
        }
        if self.prims.len() <= BRUTE_FORCE_PRIMS {
            return (0..self.prims.len())
                .any(|i| self.prim_intersect(shapes, i, o, d, tmax).is_some());
        }
        let (ray, back) = traversal_ray(o, d, tmax);
        !self.bvh.ray_traverse_miss(ray, |r, id| {
            self.prim_intersect(shapes, id, o, d, r.tmax - back)
                .map_or(f32::INFINITY, |h| h.0 + back)
        })
    }
}
