//! The primitives a ray caster tests one at a time (pbrt's primitives, Mitsuba's shape
//! and primitive index): which shape each is, its triangle in the caster's order, and
//! the tests of analytic shapes, which every caster and the shapes beside it share.

use glam::Vec3A;

use super::hit::{Crossing, Hit};
use super::triangle::LeafTriangle;
use crate::geometry::shape::Geometry;

/// Which primitive of which shape; `index` is [`ANALYTIC`] for a sphere, rectangle or
/// disk (one primitive per shape).
#[derive(Clone, Copy, Debug)]
pub(super) struct PrimRef {
    pub shape: u32,
    pub index: u32,
}

pub(super) const ANALYTIC: u32 = u32::MAX;

/// The caster's primitives (in the BVH's leaf order where one was built, else in input
/// order) and the triangles the hit tests read.
pub(super) struct Primitives {
    /// Primitive `i` of the caster.
    pub refs: Vec<PrimRef>,
    /// Primitive `i`'s triangle, when it is one (zeros for analytic shapes); then the
    /// triangles of the cubes tested as boxes (from each one's `first_leaf`). The
    /// first `unstored` leaves are left out (read with [`Primitives::triangle`]).
    pub triangles: Vec<LeafTriangle>,
    /// Leaves whose triangle is not in `triangles` but worked out from the mesh when
    /// asked: Embree's (it tests its own copy; the few reads left are for a surface
    /// without Embree's normal), all of them, else none.
    pub unstored: usize,
}

impl Primitives {
    pub fn len(&self) -> usize {
        self.refs.len()
    }

    /// Leaf `leaf`'s triangle: the stored copy, or the same values worked out from the
    /// mesh for an unstored one.
    #[inline(always)]
    pub fn triangle(&self, shapes: &[Geometry], leaf: usize) -> LeafTriangle {
        if leaf >= self.unstored {
            return self.triangles[leaf - self.unstored];
        }
        let p = self.refs[leaf];
        match &shapes[p.shape as usize] {
            Geometry::Mesh(m) => LeafTriangle::of(m, p.index),
            // What is stored for an analytic shape (unstored leaves are all triangles).
            _ => LeafTriangle {
                p0: Vec3A::ZERO,
                e1: Vec3A::ZERO,
                e2: Vec3A::ZERO,
            },
        }
    }

    /// The hit of the ray with primitive `i`, if closer than `tmax`.
    #[inline(always)]
    pub fn intersect(
        &self,
        shapes: &[Geometry],
        i: usize,
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
    ) -> Option<(f32, f32, f32)> {
        let p = self.refs[i];
        if p.index != ANALYTIC {
            return self.triangles[i].intersect(o, d, tmax);
        }
        analytic_intersect(shapes, p.shape, o, d, tmax).map(|t| (t, 0.0, 0.0))
    }

    /// Primitive `i`'s hit at `t` (barycentrics `u`, `v` for a triangle).
    #[inline(always)]
    pub fn hit(&self, i: usize, t: f32, u: f32, v: f32) -> Hit {
        let p = self.refs[i];
        Hit {
            t,
            shape: p.shape,
            prim: if p.index == ANALYTIC { 0 } else { p.index },
            u,
            v,
            leaf: if p.index == ANALYTIC {
                u32::MAX
            } else {
                i as u32
            },
            ng: [0.0; 3],
        }
    }

    /// The crossing of direction `d` at `t` through the triangle at `leaf` of mesh
    /// `shape`: along its geometric normal (p1 − p0) × (p2 − p0), after `flip_normals`,
    /// or against it.
    #[inline(always)]
    pub fn triangle_crossing(
        &self,
        shapes: &[Geometry],
        shape: u32,
        leaf: usize,
        t: f32,
        d: Vec3A,
    ) -> Crossing {
        let tri = self.triangle(shapes, leaf);
        let along = d.dot(tri.e1.cross(tri.e2)) > 0.0;
        let flip = matches!(&shapes[shape as usize], Geometry::Mesh(m) if m.flip_normals);
        Crossing {
            t,
            shape,
            along_normal: along != flip,
        }
    }
}

/// The hit of the ray with analytic shape `shape`, if closer than `tmax`.
#[inline(always)]
pub(super) fn analytic_intersect(
    shapes: &[Geometry],
    shape: u32,
    o: Vec3A,
    d: Vec3A,
    tmax: f32,
) -> Option<f32> {
    let [first, second] = analytic_hits(shapes, shape, o, d, tmax);
    first.or(second)
}

/// Every hit of the ray with an analytic shape, 0 < t < tmax, nearest first.
#[inline]
pub(super) fn analytic_hits(
    shapes: &[Geometry],
    shape: u32,
    o: Vec3A,
    d: Vec3A,
    tmax: f32,
) -> [Option<f32>; 2] {
    match &shapes[shape as usize] {
        Geometry::Sphere(s) => s.hits_within(o, d, tmax),
        Geometry::Planar(pl) => [pl.intersect(o, d, tmax), None],
        Geometry::Mesh(_) => [None, None],
    }
}

/// The crossing of the ray with analytic shape `shape` at `t`.
#[inline(always)]
pub(super) fn analytic_crossing(
    shapes: &[Geometry],
    shape: u32,
    o: Vec3A,
    d: Vec3A,
    t: f32,
) -> Crossing {
    // Only the sign of d · n is wanted: a sphere's normal needs no normalising.
    let along_normal = match &shapes[shape as usize] {
        Geometry::Sphere(s) => (d.dot(o + d * t - s.center) > 0.0) != s.flip_normals,
        Geometry::Planar(pl) => d.dot(pl.normal) > 0.0,
        Geometry::Mesh(_) => false,
    };
    Crossing {
        t,
        shape,
        along_normal,
    }
}
