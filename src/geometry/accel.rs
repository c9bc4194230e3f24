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

#[derive(Clone, Copy, Debug)]
struct PrimRef {
    shape: u32,
    index: u32,
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
    prims: Vec<PrimRef>,
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
                        index: 0,
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
                        index: 0,
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
                BvhBuildParams::medium_build(),
                &mut Duration::default(),
            )
        };
        Accel { bvh, prims, bounds }
    }

    #[inline]
    fn prim_intersect(
        shapes: &[Geometry],
        p: PrimRef,
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
    ) -> Option<(f32, f32, f32)> {
        match &shapes[p.shape as usize] {
            Geometry::Mesh(m) => m.intersect(p.index, o, d, tmax),
            Geometry::Sphere(s) => s.intersect(o, d, tmax).map(|t| (t, 0.0, 0.0)),
            Geometry::Planar(pl) => pl.intersect(o, d, tmax).map(|t| (t, 0.0, 0.0)),
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
            for p in &self.prims {
                if let Some((t, u, v)) = Self::prim_intersect(shapes, *p, o, d, t_best) {
                    t_best = t;
                    best = Some(Hit {
                        t,
                        shape: p.shape,
                        prim: p.index,
                        u,
                        v,
                    });
                }
            }
            return best;
        }
        let (ray, back) = traversal_ray(o, d, tmax);
        let mut best: Option<Hit> = None;
        let mut rh = RayHit::none();
        self.bvh.ray_traverse(ray, &mut rh, |r, id| {
            let p = self.prims[self.bvh.primitive_indices[id] as usize];
            match Self::prim_intersect(shapes, p, o, d, r.tmax - back) {
                Some((t, u, v)) => {
                    best = Some(Hit {
                        t,
                        shape: p.shape,
                        prim: p.index,
                        u,
                        v,
                    });
                    t + back
                }
                None => f32::INFINITY,
            }
        });
        best
    }

    /// Whether anything blocks `o + t d` for 0 < t < tmax.
    #[inline]
    pub fn occluded(&self, shapes: &[Geometry], o: Vec3A, d: Vec3A, tmax: f32) -> bool {
        if self.prims.is_empty() {
            return false;
        }
        if self.prims.len() <= BRUTE_FORCE_PRIMS {
            return self
                .prims
                .iter()
                .any(|p| Self::prim_intersect(shapes, *p, o, d, tmax).is_some());
        }
        let (ray, back) = traversal_ray(o, d, tmax);
        !self.bvh.ray_traverse_miss(ray, |r, id| {
            let p = self.prims[self.bvh.primitive_indices[id] as usize];
            Self::prim_intersect(shapes, p, o, d, r.tmax - back)
                .map_or(f32::INFINITY, |h| h.0 + back)
        })
    }
}
