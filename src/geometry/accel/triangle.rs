//! The triangle of the accelerator's leaves and its ray test.

use glam::Vec3A;

use crate::geometry::mesh::TriangleMesh;

/// A triangle as the intersection test reads it: `p0` and the edges `e1 = p1 − p0`,
/// `e2 = p2 − p0`, precomputed and stored in the BVH's leaf order, so that a leaf's
/// triangles are one contiguous read instead of an index lookup and three vertex loads
/// each (a ray in a 100k-triangle mesh is bound by memory latency, not arithmetic).
#[derive(Clone, Copy, Debug)]
pub(super) struct LeafTriangle {
    pub p0: Vec3A,
    pub e1: Vec3A,
    pub e2: Vec3A,
}

impl LeafTriangle {
    /// Triangle `ti` of `m` as the hit tests read it.
    #[inline]
    pub fn of(m: &TriangleMesh, ti: u32) -> LeafTriangle {
        let [p0, p1, p2] = m.vertices(ti);
        LeafTriangle {
            p0,
            e1: p1 - p0,
            e2: p2 - p0,
        }
    }

    /// Möller–Trumbore: (t, u, v), u and v the barycentrics of vertices 1 and 2.
    #[inline(always)]
    pub fn intersect(&self, o: Vec3A, d: Vec3A, tmax: f32) -> Option<(f32, f32, f32)> {
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
