//! Triangles in SIMD lanes: a scene of few triangles tested all at once, a register's
//! width at a time (16 with AVX-512, else 8), instead of traversing a BVH over them.
//!
//! A Cornell box (a few dozen triangles) spent much of its render in the BVH's
//! traversal: each cast tests a few node boxes and a handful of triangles, one by one,
//! every test a branch the CPU cannot predict. Here every triangle is tested, a block
//! of lanes at a time (Möller–Trumbore in lanes), and the only branch left is one per
//! block: whether any lane hit. This pays while the blocks are few
//! ([`MAX_TRIANGLES`]); a large mesh keeps its BVH.

use glam::Vec3A;

use super::hit::{Crossing, Crossings, Hit};
use super::primitive::Primitives;
use super::triangle::LeafTriangle;
use crate::geometry::shape::Geometry;
use crate::simd::{Lanes, Mask, Vector3, WIDTH};

/// Up to this many triangles (eight registers' worth) a scene's triangles are tested
/// in lanes rather than by traversing a BVH; beyond about that, testing them all costs
/// more than the traversal saves (the sweep in docs/performance.md, "Triangles in
/// lanes").
pub(super) const MAX_TRIANGLES: usize = 8 * WIDTH;

/// A block of triangles: each one's vertex p0 and edges e1 = p1 − p0, e2 = p2 − p0,
/// one lane per triangle, one register per coordinate. Unused lanes hold a degenerate
/// triangle (e1 = e2 = 0), which no ray hits.
#[derive(Clone, Copy, Debug)]
struct Block {
    p0: V3,
    e1: V3,
    e2: V3,
}

/// A vector per lane: `simd`'s `Vector3` over its widest lanes. `Lanes` implements no
/// [`crate::simd::Float`] (see `simd` on the two widths), so `Vector3`'s methods do
/// not apply to it: the two products it needs are below.
type V3 = Vector3<Lanes>;

/// The triangles of a scene in blocks, in the order given (triangle `i` is lane
/// `i % WIDTH` of block `i / WIDTH`).
#[derive(Clone, Debug, Default)]
pub(super) struct TriangleLanes {
    blocks: Vec<Block>,
    count: usize,
}

/// A triangle's hit: its index, distance and barycentrics of vertices 1 and 2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct LaneHit {
    pub index: usize,
    pub t: f32,
    pub u: f32,
    pub v: f32,
}

/// a × b, each component's second product fused into its difference as glam's
/// `Vec3A::cross` does where FMA is compiled in: lanes and scalar tests then agree
/// to the bit.
#[inline(always)]
fn cross(a: &V3, b: &V3) -> V3 {
    V3 {
        x: a.z.mul_neg_add(b.y, a.y * b.z),
        y: a.x.mul_neg_add(b.z, a.z * b.x),
        z: a.y.mul_neg_add(b.x, a.x * b.y),
    }
}

/// (x₀y₀ + x₁y₁) + x₂y₂, in glam's order (as `Vector3::dot`).
#[inline(always)]
fn dot(a: &V3, b: &V3) -> Lanes {
    a.x * b.x + a.y * b.y + a.z * b.z
}

#[inline(always)]
fn splat(v: Vec3A) -> V3 {
    V3 {
        x: Lanes::splat(v.x),
        y: Lanes::splat(v.y),
        z: Lanes::splat(v.z),
    }
}

impl TriangleLanes {
    pub fn new(triangles: &[LeafTriangle]) -> Self {
        let count = triangles.len();
        let mut lanes = vec![[[0f32; WIDTH]; 9]; count.div_ceil(WIDTH)];
        for (i, t) in triangles.iter().enumerate() {
            let block = &mut lanes[i / WIDTH];
            for (k, v) in [t.p0, t.e1, t.e2].iter().enumerate() {
                for axis in 0..3 {
                    block[3 * k + axis][i % WIDTH] = v[axis];
                }
            }
        }
        let blocks = lanes
            .iter()
            .map(|b| {
                let r = |k: usize| V3 {
                    x: Lanes::load(&b[k]),
                    y: Lanes::load(&b[k + 1]),
                    z: Lanes::load(&b[k + 2]),
                };
                Block {
                    p0: r(0),
                    e1: r(3),
                    e2: r(6),
                }
            })
            .collect();
        TriangleLanes { blocks, count }
    }

    pub fn len(&self) -> usize {
        self.count
    }

    /// Each block's lanes the ray `o + t d` hits with 0 < t < `tmax`: calls
    /// `found(block, mask, t, u, v)` for each block with a hit (`mask` bit k for lane
    /// k); `found` answers the new `tmax` for the blocks after (a closest-hit search
    /// shortens the ray), or None to end the search.
    #[inline(always)]
    fn each_block_hit(
        &self,
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
        mut found: impl FnMut(usize, Mask, [f32; WIDTH], [f32; WIDTH], [f32; WIDTH]) -> Option<f32>,
    ) {
        let (o, d) = (splat(o), splat(d));
        let zero = Lanes::splat(0.0);
        let mut tmax_lanes = Lanes::splat(tmax);
        for (bi, b) in self.blocks.iter().enumerate() {
            // Möller–Trumbore with the barycentrics and t scaled by the determinant
            // until a lane hits: u = (tv · pv) / det, v = (d · qv) / det, t = (e2 · qv) /
            // det. Each test multiplied through by |det| (the numerators' signs flipped
            // with det's) leaves no division in the search.
            let pv = cross(&d, &b.e2);
            let det = dot(&b.e1, &pv);
            let abs_det = det.abs();
            let tv = V3 {
                x: o.x - b.p0.x,
                y: o.y - b.p0.y,
                z: o.z - b.p0.z,
            };
            let u = dot(&tv, &pv).times_sign_of(det);
            let qv = cross(&tv, &b.e1);
            let v = dot(&d, &qv).times_sign_of(det);
            let t = dot(&b.e2, &qv).times_sign_of(det);
            // A zero determinant (a padding lane, or a ray in the triangle's plane)
            // fails the last test.
            let mask = u.ge(zero)
                & v.ge(zero)
                & (u + v).le(abs_det)
                & t.gt(zero)
                & t.lt(tmax_lanes * abs_det);
            if mask != 0 {
                let inv = Lanes::splat(1.0) / abs_det;
                let (t, u, v) = (t * inv, u * inv, v * inv);
                match found(bi, mask, t.to_array(), u.to_array(), v.to_array()) {
                    Some(tmax) => tmax_lanes = Lanes::splat(tmax),
                    None => return,
                }
            }
        }
    }

    /// The closest hit with 0 < t < `tmax` among the triangles `keep` accepts (by
    /// index).
    #[inline(always)]
    pub fn closest(
        &self,
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
        keep: impl Fn(usize) -> bool,
    ) -> Option<LaneHit> {
        let mut best: Option<LaneHit> = None;
        let mut t_best = tmax;
        self.each_block_hit(o, d, tmax, |bi, mut mask, t, u, v| {
            while mask != 0 {
                let k = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                let index = bi * WIDTH + k;
                if t[k] < t_best && keep(index) {
                    t_best = t[k];
                    best = Some(LaneHit {
                        index,
                        t: t[k],
                        u: u[k],
                        v: v[k],
                    });
                }
            }
            Some(t_best)
        });
        best
    }

    /// Whether any triangle is hit with 0 < t < `tmax`.
    #[inline(always)]
    pub fn any_hit(&self, o: Vec3A, d: Vec3A, tmax: f32) -> bool {
        let mut hit = false;
        self.each_block_hit(o, d, tmax, |_, _, _, _, _| {
            hit = true;
            None
        });
        hit
    }

    /// Every hit with 0 < t < `tmax`, in index order, to `each(index, t)` until it
    /// answers false.
    #[inline(always)]
    pub fn each_hit(
        &self,
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
        mut each: impl FnMut(usize, f32) -> bool,
    ) {
        self.each_block_hit(o, d, tmax, |bi, mut mask, t, _, _| {
            while mask != 0 {
                let k = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                if !each(bi * WIDTH + k, t[k]) {
                    return None;
                }
            }
            Some(tmax)
        });
    }
}

/// As the scene's ray caster: triangle `i` is the caster's primitive `i`.
impl TriangleLanes {
    /// The closest hit, 0 < t < tmax, among the triangles of a shape `keep` accepts.
    #[inline(always)]
    pub fn intersect_where(
        &self,
        prims: &Primitives,
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
        keep: impl Fn(u32) -> bool,
    ) -> Option<Hit> {
        let found = self.closest(o, d, tmax, |i| keep(prims.refs[i].shape));
        found.map(|h| prims.hit(h.index, h.t, h.u, h.v))
    }

    /// Every crossing, 0 < t < tmax, to `record` (see [`super::Accel::crossings`])
    /// until it answers.
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
        let mut answer = None;
        self.each_hit(o, d, tmax, |id, t| {
            answer = record(prims.triangle_crossing(shapes, prims.refs[id].shape, id, t, d));
            answer.is_none()
        });
        answer.unwrap_or(Crossings::Found)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Pcg32;

    fn random_triangles(rng: &mut Pcg32, n: usize) -> Vec<LeafTriangle> {
        let mut p = || Vec3A::new(rng.next_1d(), rng.next_1d(), rng.next_1d()) * 2.0 - 1.0;
        (0..n)
            .map(|_| LeafTriangle {
                p0: p(),
                e1: p() * 1.5,
                e2: p() * 1.5,
            })
            .collect()
    }

    /// Closest hit, any hit and every hit agree with the triangles tested one by one
    /// (`LeafTriangle::intersect`, the BVH's leaf test), on random rays through random
    /// triangles (a count that leaves a block partly filled, so the padding lanes are
    /// tested too).
    #[test]
    fn lanes_agree_with_the_scalar_test() {
        let mut rng = Pcg32::new(7, 3);
        let tris = random_triangles(&mut rng, 21);
        let lanes = TriangleLanes::new(&tris);
        assert_eq!(lanes.len(), 21);
        let (mut hits, mut misses) = (0, 0);
        for _ in 0..20_000 {
            let o = Vec3A::new(rng.next_1d(), rng.next_1d(), rng.next_1d()) * 4.0 - 2.0;
            let d =
                (Vec3A::new(rng.next_1d(), rng.next_1d(), rng.next_1d()) * 2.0 - 1.0).normalize();
            let tmax = if rng.next_1d() < 0.5 {
                f32::INFINITY
            } else {
                rng.next_1d() * 3.0
            };
            let each: Vec<(usize, f32)> = tris
                .iter()
                .enumerate()
                .filter_map(|(i, tri)| tri.intersect(o, d, tmax).map(|h| (i, h.0)))
                .collect();
            let nearest = each.iter().copied().min_by(|a, b| a.1.total_cmp(&b.1));
            let got = lanes.closest(o, d, tmax, |_| true);
            match (nearest, got) {
                (None, None) => misses += 1,
                (Some((i, t)), Some(h)) => {
                    hits += 1;
                    // The same distance to the bit (the same arithmetic); the same
                    // triangle unless two lie at that distance.
                    assert_eq!(h.t, t);
                    assert!(h.index == i || each.iter().any(|e| e.0 == h.index && e.1 == h.t));
                }
                (a, b) => panic!("scalar {a:?}, lanes {b:?} for o {o} d {d} tmax {tmax}"),
            }
            assert_eq!(lanes.any_hit(o, d, tmax), !each.is_empty());
            let mut all = Vec::new();
            lanes.each_hit(o, d, tmax, |i, t| {
                all.push((i, t));
                true
            });
            let indices = |v: &[(usize, f32)]| v.iter().map(|e| e.0).collect::<Vec<_>>();
            assert_eq!(indices(&all), indices(&each));
        }
        // Both outcomes were tested many times.
        assert!(hits > 2000 && misses > 2000, "{hits} hits, {misses} misses");
    }

    /// A filter skips the nearest triangle for the one behind it; `each_hit` stops
    /// when told.
    #[test]
    fn filtered_and_stopped_searches() {
        let tri = |z: f32| LeafTriangle {
            p0: Vec3A::new(-1.0, -1.0, z),
            e1: Vec3A::new(3.0, 0.0, 0.0),
            e2: Vec3A::new(0.0, 3.0, 0.0),
        };
        let lanes = TriangleLanes::new(&[tri(-1.0), tri(-2.0), tri(-3.0)]);
        let (o, d) = (Vec3A::ZERO, Vec3A::NEG_Z);
        assert_eq!(
            lanes.closest(o, d, f32::INFINITY, |_| true).unwrap().index,
            0
        );
        let h = lanes.closest(o, d, f32::INFINITY, |i| i != 0).unwrap();
        assert_eq!((h.index, h.t), (1, 2.0));
        assert!(lanes.closest(o, d, 0.5, |_| true).is_none());
        let mut seen = 0;
        lanes.each_hit(o, d, f32::INFINITY, |_, _| {
            seen += 1;
            seen < 2
        });
        assert_eq!(seen, 2);
    }
}
