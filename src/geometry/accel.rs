//! One compressed wide BVH (obvhs CWBVH) over every triangle of the scene, with the
//! analytic shapes tested one by one beside it when there are few of them, else in it
//! as one primitive each. Mitsuba `cube`s, when few, are tested beside it as boxes
//! ([`Cuboid`]) instead of as 12 triangles in it.

use std::time::Duration;

use arrayvec::ArrayVec;
use glam::Vec3A;
use obvhs::aabb::Aabb;
use obvhs::cwbvh::builder::build_cwbvh;
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::Ray as BvhRay;
use obvhs::BvhBuildParams;

use super::cuboid::{Cuboid, CuboidHit};
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
#[derive(Clone, Copy, Debug, Default)]
pub struct Hit {
    pub t: f32,
    pub shape: u32,
    pub prim: u32,
    pub u: f32,
    pub v: f32,
    /// The triangle's place in the accelerator's own copy ([`Accel::triangle_surface`]),
    /// `u32::MAX` for analytic shapes.
    pub leaf: u32,
}

impl Hit {
    /// A hit of analytic shape `shape` at distance `t` (no triangle, no barycentrics).
    #[inline]
    pub fn analytic(shape: u32, t: f32) -> Hit {
        Hit {
            t,
            shape,
            prim: 0,
            u: 0.0,
            v: 0.0,
            leaf: u32::MAX,
        }
    }
}

/// How a surface treats a shadow ray (see [`Accel::crossings`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShadowPass {
    /// Stops it (every BSDF but the two below).
    Blocks,
    /// Lets it through unchanged (`null`).
    Passes,
    /// Lets part of it through, by the angle (`thindielectric`).
    Partial,
}

/// The answer of [`Accel::crossings`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Crossings {
    Blocked,
    /// Every pass-through hit, in `out`.
    Found,
    /// The caller must cast one ray per crossing.
    Unsupported,
}

/// A surface a shadow ray crosses: where, which shape, and whether the ray crosses
/// along the surface's geometric normal (`d · n > 0`, `n` after `flip_normals`), all
/// it needs to know which medium lies beyond (Mitsuba's `target_medium`). The side is
/// read where the hit test has the surface at hand: no normal is looked up after.
#[derive(Clone, Copy, Debug)]
pub struct Crossing {
    pub t: f32,
    pub shape: u32,
    pub along_normal: bool,
}

/// Crossings one shadow traversal collects before it gives up (see
/// [`Accel::crossings`]).
pub const MAX_CROSSINGS: usize = 16;

/// Where [`Accel::crossings`] puts them. Its storage is not initialised: zeroing an
/// array of 16 for every search cost the medium cube 5% of its render time (about two
/// searches a sample, most of them finding one or two crossings).
pub type CrossingList = ArrayVec<Crossing, MAX_CROSSINGS>;

/// A cuboid's hit as the BVH would give it: the mesh triangle and its barycentrics.
#[inline(always)]
pub(super) fn cuboid_hit(c: &Cuboid, h: CuboidHit) -> Hit {
    Hit {
        t: h.t,
        shape: c.shape,
        prim: h.prim,
        u: h.u,
        v: h.v,
        leaf: h.leaf,
    }
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
#[inline(always)]
fn traversal_ray(o: Vec3A, d: Vec3A, tmax: f32) -> (BvhRay, f32) {
    let back = 2.0 * NODE_TMIN + o.abs().max_element() * 1e-6;
    (BvhRay::new(o - d * back, d, 0.0, tmax + back), back)
}

/// Which children of a CWBVH node the ray meets, as obvhs's `intersect_ray` answers
/// (the hit mask `traverse!` reads). The same slab test on the node's quantized child
/// boxes, but all eight children in one AVX2 register: each axis's eight bytes widen to
/// floats in two instructions (obvhs builds them one by one, four at a time in SSE,
/// which it notes is the most expensive part of its test). Where AVX2 is not compiled
/// in, obvhs's own test.
#[inline(always)]
fn node_hits(node: &CwBvhNode, ray: &BvhRay, oct_inv4: u32) -> u32 {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
    {
        use std::arch::x86_64::*;
        // Child box planes are p + extent · q for the byte q: along axis k the ray is at
        // t = (p + e q − o) / d = q · (e / d) + (p − o) / d.
        let scale = node.compute_extent() * ray.inv_direction;
        let offset = (Vec3A::from(node.p) - ray.origin) * ray.inv_direction;
        // SAFETY: AVX2 is enabled at compile time (the cfg above); the loads
        // read the 8 bytes of an [u8; 8].
        let mask = unsafe {
            let widen = |q: &[u8; 8]| {
                _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_loadl_epi64(
                    q.as_ptr() as *const __m128i
                )))
            };
            // (near, far) planes' distances on one axis: a negative direction meets
            // the max plane first.
            let axis = |lo: &[u8; 8], hi: &[u8; 8], negative: bool, scale: f32, offset: f32| {
                let (near, far) = if negative { (hi, lo) } else { (lo, hi) };
                let (s, o) = (_mm256_set1_ps(scale), _mm256_set1_ps(offset));
                // FMA (obvhs multiplies, then adds: 3-5% slower renders of the Bunny
                // and Lucy). It rounds once where obvhs rounds twice, so a box the ray
                // grazes to within that rounding may be answered otherwise; either
                // answer is right, as quantized child boxes are padded by far more.
                (
                    _mm256_fmadd_ps(widen(near), s, o),
                    _mm256_fmadd_ps(widen(far), s, o),
                )
            };
            let d = ray.direction;
            let (x0, x1) = axis(
                &node.child_min_x,
                &node.child_max_x,
                d.x < 0.0,
                scale.x,
                offset.x,
            );
            let (y0, y1) = axis(
                &node.child_min_y,
                &node.child_max_y,
                d.y < 0.0,
                scale.y,
                offset.y,
            );
            let (z0, z1) = axis(
                &node.child_min_z,
                &node.child_max_z,
                d.z < 0.0,
                scale.z,
                offset.z,
            );
            // In obvhs's order, so a NaN (0 · ∞ on an axis the ray runs along) falls out
            // the same way: max/min answer their second operand when one is NaN.
            let t_near = _mm256_max_ps(x0, _mm256_max_ps(y0, z0));
            let t_far = _mm256_min_ps(x1, _mm256_min_ps(y1, z1));
            let t_near = _mm256_max_ps(t_near, _mm256_set1_ps(NODE_TMIN));
            let t_far = _mm256_min_ps(t_far, _mm256_set1_ps(ray.tmax));
            _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(t_near, t_far)) as u32
        };
        // Per child met: its bits (1 for an inner node, the unary primitive count for a
        // leaf) shifted to its place in the hit mask (see obvhs's CwBvhNode).
        let (child_bits8, bit_index8) = node.get_child_and_index_bits(oct_inv4);
        let mut hit_mask = 0u32;
        let mut m = mask;
        while m != 0 {
            let shift = 8 * m.trailing_zeros();
            m &= m - 1;
            let bits = ((child_bits8 >> shift) & 0xff) as u32;
            let index = ((bit_index8 >> shift) & 0xff) as u32;
            hit_mask |= bits << index;
        }
        hit_mask
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
    {
        node.intersect_ray(ray, oct_inv4)
    }
}

/// Up to this many primitives, testing each beats traversing the BVH: the furnace (one
/// sphere) renders ~30% faster; the medium cube (14 primitives) ~10% slower, so the
/// limit stays well below that.
const BRUTE_FORCE_PRIMS: usize = 4;

/// Up to this many analytic shapes are tested one by one beside the BVH, which then
/// holds triangles only: its leaf test reads one contiguous triangle, without first
/// looking up what kind of primitive it is (a cache miss per candidate on a large mesh).
/// More of them go into the BVH with the triangles.
const SEPARATE_ANALYTIC: usize = 16;

pub struct Accel {
    bvh: CwBvh,
    /// Primitive `i` of the traversal (`bvh.primitive_indices` already applied).
    prims: Vec<PrimRef>,
    /// Its triangle, when it is one (zeros for analytic shapes).
    triangles: Vec<LeafTriangle>,
    /// Analytic shapes tested beside the BVH (when there are few; see
    /// [`SEPARATE_ANALYTIC`]): their shape indices.
    analytic: Vec<u32>,
    /// Mitsuba cubes tested beside the BVH as boxes (when, with the analytic shapes,
    /// there are few); their triangles follow the BVH's in `triangles`.
    cuboids: Vec<Cuboid>,
    /// Whether the BVH holds analytic shapes too (else triangles only).
    mixed: bool,
    pub bounds: Bounds,
}

impl Accel {
    pub fn build(shapes: &[&Geometry]) -> Accel {
        let n_analytic = shapes
            .iter()
            .filter(|g| !matches!(g, Geometry::Mesh(_)))
            .count();
        // A slab test beats the BVH over a cube's 12 triangles, but every ray pays it
        // for every cube: many cubes stay in the BVH.
        let mut cuboids: Vec<Cuboid> = shapes
            .iter()
            .enumerate()
            .filter_map(|(si, g)| match g {
                Geometry::Mesh(m) => Cuboid::new(si as u32, m, m.cube_to_world.as_ref()?),
                _ => None,
            })
            .collect();
        if cuboids.len() + n_analytic > SEPARATE_ANALYTIC {
            cuboids.clear();
        }
        let is_cuboid = |si: usize| cuboids.iter().any(|c| c.shape == si as u32);
        let n_triangles: usize = shapes
            .iter()
            .enumerate()
            .map(|(si, g)| match g {
                Geometry::Mesh(m) if !is_cuboid(si) => m.triangles.len(),
                _ => 0,
            })
            .sum();
        // Few primitives in all are tested one by one (see BRUTE_FORCE_PRIMS), in the
        // BVH's primitive list; else few analytic shapes are kept out of the BVH.
        let mixed = n_analytic + n_triangles <= BRUTE_FORCE_PRIMS || n_analytic > SEPARATE_ANALYTIC;
        let mut analytic = Vec::new();
        let mut prims = Vec::new();
        let mut aabbs = Vec::new();
        let mut bounds = Bounds::EMPTY;
        for (si, g) in shapes.iter().enumerate() {
            match g {
                Geometry::Mesh(_) if is_cuboid(si) => bounds = bounds.union(&g.bounds()),
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
                Geometry::Sphere(_) | Geometry::Planar(_) => {
                    let b = g.bounds();
                    bounds = bounds.union(&b);
                    if !mixed {
                        analytic.push(si as u32);
                        continue;
                    }
                    prims.push(PrimRef {
                        shape: si as u32,
                        index: ANALYTIC,
                    });
                    aabbs.push(Aabb {
                        min: b.min,
                        max: b.max,
                    });
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
        let leaf_triangle = |m: &crate::geometry::mesh::TriangleMesh, ti: u32| {
            let [p0, p1, p2] = m.vertices(ti);
            LeafTriangle {
                p0,
                e1: p1 - p0,
                e2: p2 - p0,
            }
        };
        let mut triangles: Vec<LeafTriangle> = prims
            .iter()
            .map(|p| match shapes[p.shape as usize] {
                Geometry::Mesh(m) if p.index != ANALYTIC => leaf_triangle(m, p.index),
                _ => LeafTriangle {
                    p0: Vec3A::ZERO,
                    e1: Vec3A::ZERO,
                    e2: Vec3A::ZERO,
                },
            })
            .collect();
        for c in &mut cuboids {
            c.first_leaf = triangles.len() as u32;
            if let Geometry::Mesh(m) = shapes[c.shape as usize] {
                triangles.extend((0..m.triangles.len() as u32).map(|ti| leaf_triangle(m, ti)));
            }
        }
        Accel {
            bvh,
            prims,
            triangles,
            analytic,
            cuboids,
            mixed,
            bounds,
        }
    }

    /// The cube `shape` as the accelerator tests it, if it is tested as a box.
    pub fn cuboid(&self, shape: u32) -> Option<&Cuboid> {
        self.cuboids.iter().find(|c| c.shape == shape)
    }

    /// Closest-hit traversal of the BVH (obvhs's `ray_traverse` with [`node_hits`] as
    /// its node test): `leaf(tmax, primitive)` tests a primitive against the ray as far as
    /// `tmax` and answers its hit distance (∞ for none); a closer one shortens the
    /// ray, and a distance ≤ 0 ends the traversal.
    #[inline(always)]
    fn traverse(&self, ray: BvhRay, mut leaf: impl FnMut(f32, usize) -> f32) {
        use glam::UVec2;
        let mut ray = ray;
        let mut state = self.bvh.new_traversal(ray.direction);
        let mut node;
        'done: {
            obvhs::traverse!(
                self.bvh,
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

    /// Whether a ray cast traverses the BVH (else it tests a few primitives one by one).
    pub fn traverses_bvh(&self) -> bool {
        self.prims.len() > BRUTE_FORCE_PRIMS
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
        Self::analytic_intersect(shapes, p.shape, o, d, tmax).map(|t| (t, 0.0, 0.0))
    }

    /// The hit of the ray with BVH primitive `i`: a triangle, unless the BVH is mixed.
    #[inline(always)]
    fn leaf_intersect(
        &self,
        shapes: &[Geometry],
        i: usize,
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
    ) -> Option<(f32, f32, f32)> {
        if !self.mixed {
            return self.triangles[i].intersect(o, d, tmax);
        }
        // A BVH that holds analytic shapes (more than SEPARATE_ANALYTIC, rare) tests
        // them out of line: inlined, they made every BVH's leaf test too large to be
        // inlined into its traversal (a call per triangle, 1-3% on the meshes).
        #[inline(never)]
        fn mixed(
            accel: &Accel,
            shapes: &[Geometry],
            i: usize,
            ray: (Vec3A, Vec3A, f32),
        ) -> Option<(f32, f32, f32)> {
            accel.prim_intersect(shapes, i, ray.0, ray.1, ray.2)
        }
        mixed(self, shapes, i, (o, d, tmax))
    }

    /// The hit of the ray with analytic shape `shape`, if closer than `tmax`.
    #[inline(always)]
    fn analytic_intersect(
        shapes: &[Geometry],
        shape: u32,
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
    ) -> Option<f32> {
        let [first, second] = Self::analytic_hits(shapes, shape, o, d, tmax);
        first.or(second)
    }

    /// Every hit of the ray with an analytic shape, 0 < t < tmax, nearest first.
    #[inline]
    fn analytic_hits(
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

    /// Closest hit along `o + t d`, 0 < t < tmax.
    #[inline(always)]
    pub fn intersect(&self, shapes: &[Geometry], o: Vec3A, d: Vec3A, tmax: f32) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let mut t_best = tmax;
        // The analytic shapes first: a hit among them shortens the BVH's ray.
        for &shape in &self.analytic {
            if let Some(t) = Self::analytic_intersect(shapes, shape, o, d, t_best) {
                t_best = t;
                best = Some(Hit::analytic(shape, t));
            }
        }
        for c in &self.cuboids {
            if let Some(h) = c.intersect(o, d, t_best) {
                t_best = h.t;
                best = Some(cuboid_hit(c, h));
            }
        }
        if self.prims.is_empty() {
            return best;
        }
        if self.prims.len() <= BRUTE_FORCE_PRIMS {
            for i in 0..self.prims.len() {
                if let Some((t, u, v)) = self.prim_intersect(shapes, i, o, d, t_best) {
                    t_best = t;
                    best = Some(self.hit(i, t, u, v));
                }
            }
            return best;
        }
        let (ray, back) = traversal_ray(o, d, t_best);
        let mut best_prim = None;
        self.traverse(ray, |ray_tmax, id| {
            match self.leaf_intersect(shapes, id, o, d, ray_tmax - back) {
                Some((t, u, v)) => {
                    best_prim = Some((id, t, u, v));
                    t + back
                }
                None => f32::INFINITY,
            }
        });
        match best_prim {
            Some((id, t, u, v)) => Some(self.hit(id, t, u, v)),
            None => best,
        }
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
            leaf: if p.index == ANALYTIC {
                u32::MAX
            } else {
                i as u32
            },
        }
    }

    /// The point at barycentrics (u, v) of a hit triangle and its unit geometric normal
    /// (p1 − p0) × (p2 − p0), from the copy the hit test has just read: no lookups in
    /// the mesh (where a surface needs no shading frame, see `Scene::intersect`).
    #[inline]
    pub fn triangle_surface(&self, leaf: u32, u: f32, v: f32) -> (Vec3A, Vec3A) {
        let t = &self.triangles[leaf as usize];
        (
            t.p0 + t.e1 * u + t.e2 * v,
            t.e1.cross(t.e2).normalize_or_zero(),
        )
    }

    /// Every surface a shadow ray crosses on `o + t d`, 0 < t < tmax, found in one
    /// traversal instead of one closest-hit cast per crossing (a ray out of a mesh
    /// boundary crosses it about twice on the Bunny, a ray out of a sphere once, and
    /// each cast of the old way ended in a second one to find nothing beyond). `pass[shape]`
    /// says how each shape treats the ray. The crossings go into `out` in the order
    /// found (not sorted), each with the side it crosses to.
    ///
    /// A blocking surface ends the search at once: whatever else lies on the ray,
    /// nothing gets through. A BVH that holds analytic shapes, a thin-dielectric
    /// surface the ray passes through and more than [`MAX_CROSSINGS`] crossings answer
    /// [`Crossings::Unsupported`], and the caller casts one ray per crossing.
    pub fn crossings(
        &self,
        shapes: &[Geometry],
        pass: &[ShadowPass],
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
        out: &mut CrossingList,
    ) -> Crossings {
        out.clear();
        if self.mixed && self.traverses_bvh() {
            return Crossings::Unsupported;
        }
        // Records a crossing; Some(answer) when the search is over.
        let mut record = |c: Crossing| match pass[c.shape as usize] {
            ShadowPass::Passes if !out.is_full() => {
                out.push(c);
                None
            }
            ShadowPass::Blocks => Some(Crossings::Blocked),
            _ => Some(Crossings::Unsupported),
        };
        for &shape in &self.analytic {
            let hits = Self::analytic_hits(shapes, shape, o, d, tmax);
            for t in hits.into_iter().flatten() {
                let c = Self::analytic_crossing(shapes, shape, o, d, t);
                if let Some(answer) = record(c) {
                    return answer;
                }
            }
        }
        for c in &self.cuboids {
            let shape = c.shape;
            if let Some(exit_along) = c.exit_along_normal {
                // Entry first, then exit: the box's side is the whole face's.
                let [entry, exit] = c.span_within(o, d, tmax);
                for (t, along_normal) in [(entry, !exit_along), (exit, exit_along)] {
                    let Some(t) = t else { continue };
                    if let Some(answer) = record(Crossing {
                        t,
                        shape,
                        along_normal,
                    }) {
                        return answer;
                    }
                }
            } else {
                for h in c.hits_within(o, d, tmax).into_iter().flatten() {
                    let crossing = self.triangle_crossing(shapes, shape, h.leaf as usize, h.t, d);
                    if let Some(answer) = record(crossing) {
                        return answer;
                    }
                }
            }
        }
        if !self.traverses_bvh() {
            for (i, p) in self.prims.iter().enumerate() {
                let answer = if p.index == ANALYTIC {
                    Self::analytic_hits(shapes, p.shape, o, d, tmax)
                        .into_iter()
                        .flatten()
                        .find_map(|t| record(Self::analytic_crossing(shapes, p.shape, o, d, t)))
                } else {
                    self.triangles[i]
                        .intersect(o, d, tmax)
                        .and_then(|(t, _, _)| {
                            record(self.triangle_crossing(shapes, p.shape, i, t, d))
                        })
                };
                if let Some(answer) = answer {
                    return answer;
                }
            }
            return Crossings::Found;
        }
        let (ray, _) = traversal_ray(o, d, tmax);
        let mut answer = None;
        self.traverse(ray, |_, id| {
            let Some((t, _, _)) = self.triangles[id].intersect(o, d, tmax) else {
                return f32::INFINITY;
            };
            match record(self.triangle_crossing(shapes, self.prims[id].shape, id, t, d)) {
                // Not a closer hit for the traversal: the ray's extent stays.
                None => f32::INFINITY,
                // A distance of 0 culls every remaining node: the traversal ends.
                found => {
                    answer = found;
                    0.0
                }
            }
        });
        answer.unwrap_or(Crossings::Found)
    }

    /// The crossing of direction `d` at `t` through the triangle at `leaf` of mesh
    /// `shape`: along its geometric normal (p1 − p0) × (p2 − p0), after `flip_normals`,
    /// or against it.
    #[inline(always)]
    fn triangle_crossing(
        &self,
        shapes: &[Geometry],
        shape: u32,
        leaf: usize,
        t: f32,
        d: Vec3A,
    ) -> Crossing {
        let tri = &self.triangles[leaf];
        let along = d.dot(tri.e1.cross(tri.e2)) > 0.0;
        let flip = matches!(&shapes[shape as usize], Geometry::Mesh(m) if m.flip_normals);
        Crossing {
            t,
            shape,
            along_normal: along != flip,
        }
    }

    /// The crossing of the ray with analytic shape `shape` at `t`.
    #[inline(always)]
    fn analytic_crossing(shapes: &[Geometry], shape: u32, o: Vec3A, d: Vec3A, t: f32) -> Crossing {
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

    /// Whether anything blocks `o + t d` for 0 < t < tmax.
    #[inline]
    pub fn occluded(&self, shapes: &[Geometry], o: Vec3A, d: Vec3A, tmax: f32) -> bool {
        if self
            .analytic
            .iter()
            .any(|&shape| Self::analytic_intersect(shapes, shape, o, d, tmax).is_some())
        {
            return true;
        }
        if self.cuboids.iter().any(|c| c.hit_within(o, d, tmax)) {
            return true;
        }
        if self.prims.is_empty() {
            return false;
        }
        if self.prims.len() <= BRUTE_FORCE_PRIMS {
            return (0..self.prims.len())
                .any(|i| self.prim_intersect(shapes, i, o, d, tmax).is_some());
        }
        let (ray, back) = traversal_ray(o, d, tmax);
        let mut blocked = false;
        self.traverse(ray, |ray_tmax, id| {
            match self.leaf_intersect(shapes, id, o, d, ray_tmax - back) {
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
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::{cube, TriangleMesh};
    use crate::geometry::shape::{Planar, Sphere};
    use crate::sampling::warp::square_to_uniform_sphere;
    use crate::sampling::Pcg32;
    use glam::{Mat3A, Mat4, Vec3};
    use std::path::Path;

    /// Two cubes (Mitsuba `cube`s if `boxes`, else plain meshes), `spheres` spheres and
    /// a rectangle.
    fn scene(spheres: usize, boxes: bool) -> Vec<Geometry> {
        let mut g = Vec::new();
        for k in 0..2 {
            let to_world = Mat4::from_translation(Vec3::new(k as f32 * 3.0 - 1.5, 0.0, 0.0))
                * Mat4::from_rotation_y(0.3 + k as f32);
            let mut m = TriangleMesh::new(cube(), &to_world, true, false, Path::new("cube"))
                .expect("a valid cube");
            m.cube_to_world = boxes.then_some(to_world);
            g.push(Geometry::Mesh(m));
        }
        for k in 0..spheres {
            g.push(Geometry::Sphere(Sphere {
                center: Vec3A::new(-1.0 + 0.3 * k as f32, 1.2, 0.2 * k as f32),
                radius: 0.25,
                flip_normals: false,
                axes: Mat3A::IDENTITY,
            }));
        }
        let floor = Mat4::from_translation(Vec3::new(0.0, -1.2, 0.0))
            * Mat4::from_rotation_x(-1.5)
            * Mat4::from_scale(Vec3::splat(3.0));
        g.push(Geometry::Planar(Planar::new(floor, false, false)));
        g
    }

    /// The nearest hit by testing every primitive: (shape, distance).
    fn brute_force(g: &[Geometry], o: Vec3A, d: Vec3A, tmax: f32) -> Option<(u32, f32)> {
        let mut best = None;
        let mut t_best = tmax;
        for (si, s) in g.iter().enumerate() {
            let t = match s {
                Geometry::Mesh(m) => (0..m.triangles.len() as u32)
                    .filter_map(|t| {
                        let [p0, p1, p2] = m.vertices(t);
                        let tri = LeafTriangle {
                            p0,
                            e1: p1 - p0,
                            e2: p2 - p0,
                        };
                        tri.intersect(o, d, t_best).map(|h| h.0)
                    })
                    .reduce(f32::min),
                Geometry::Sphere(sp) => sp.intersect(o, d, t_best),
                Geometry::Planar(p) => p.intersect(o, d, t_best),
            };
            if let Some(t) = t.filter(|&t| t < t_best) {
                t_best = t;
                best = Some((si as u32, t));
            }
        }
        best
    }

    /// Analytic shapes beside the BVH (3 spheres) and inside it (20 spheres), and cubes
    /// as boxes beside it or as triangles in it, give the hits of testing every
    /// primitive (to rounding where a box's slab test stands for its triangles).
    #[test]
    fn closest_hit_and_occlusion_match_brute_force() {
        for (spheres, boxes) in [(3, false), (3, true), (SEPARATE_ANALYTIC + 4, true)] {
            let g = scene(spheres, boxes);
            let refs: Vec<&Geometry> = g.iter().collect();
            let accel = Accel::build(&refs);
            // Too many shapes beside the BVH: the cubes go into it.
            let as_boxes = boxes && spheres <= SEPARATE_ANALYTIC;
            assert_eq!(accel.cuboids.len(), if as_boxes { 2 } else { 0 });
            // Without the cubes' triangles, 3 spheres and a rectangle are few enough to
            // be tested one by one (in the primitive list: "mixed", with no traversal).
            assert_eq!(accel.mixed, spheres > SEPARATE_ANALYTIC || as_boxes);
            assert_eq!(accel.traverses_bvh(), !as_boxes);
            let mut rng = Pcg32::new(5, spheres as u64);
            let mut hits = 0;
            for i in 0..20_000 {
                let o = Vec3A::new(rng.next_1d(), rng.next_1d(), rng.next_1d()) * 5.0
                    - Vec3A::splat(2.5);
                let d = square_to_uniform_sphere(rng.next_2d());
                let tmax = if i % 2 == 0 { 1.0 } else { f32::INFINITY };
                let got = accel.intersect(&g, o, d, tmax).map(|h| (h.shape, h.t));
                let want = brute_force(&g, o, d, tmax);
                if as_boxes {
                    let (gs, gt) = got.unwrap_or((u32::MAX, 0.0));
                    let (ws, wt) = want.unwrap_or((u32::MAX, 0.0));
                    assert!(
                        gs == ws && (gt - wt).abs() <= 1e-4 * wt.max(1.0),
                        "ray {o} {d} {tmax}: {got:?} vs {want:?}"
                    );
                } else {
                    assert_eq!(got, want, "ray {o} {d} {tmax}");
                }
                assert_eq!(accel.occluded(&g, o, d, tmax), got.is_some());
                hits += got.is_some() as u32;
            }
            assert!(hits > 2_000, "only {hits} rays hit something");
        }
    }

    /// The AVX2 node test answers obvhs's hit mask for every node of a BVH over 20,000
    /// random triangles, for rays from inside and outside it, bounded and not, and
    /// along an axis (where 0 · ∞ gives NaN). (Its FMA could differ from obvhs on a box
    /// grazed to within a rounding; none of these rays does.) Without AVX2 compiled in,
    /// `node_hits` is obvhs's own test and there is nothing to compare: ignored, saying so.
    #[test]
    #[cfg_attr(
        not(all(target_arch = "x86_64", target_feature = "avx2")),
        ignore = "node_hits is obvhs's own test where AVX2 is not compiled in"
    )]
    fn node_test_matches_obvhs() {
        let mut rng = Pcg32::new(11, 2);
        let point = |rng: &mut Pcg32| {
            Vec3A::new(rng.next_1d(), rng.next_1d(), rng.next_1d()) * 4.0 - Vec3A::splat(2.0)
        };
        let mut raw = crate::geometry::mesh::RawMesh {
            positions: Vec::new(),
            normals: None,
            triangles: Vec::new(),
            uvs: None,
            warnings: Vec::new(),
        };
        for i in 0..20_000u32 {
            let c = point(&mut rng);
            for _ in 0..3 {
                let v = c + point(&mut rng) * 0.02;
                raw.positions.push(v);
            }
            raw.triangles.push([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        let mesh = TriangleMesh::new(raw, &Mat4::IDENTITY, false, false, Path::new("soup"))
            .expect("a triangle soup");
        let g = [Geometry::Mesh(mesh)];
        let accel = Accel::build(&[&g[0]]);
        assert!(accel.bvh.nodes.len() > 1000);
        let (mut met, mut tests) = (0u64, 0u64);
        for i in 0..300 {
            let o = point(&mut rng) * if i % 3 == 0 { 2.0 } else { 1.0 };
            let d = match i % 10 {
                0 => Vec3A::X,
                1 => -Vec3A::Z,
                _ => square_to_uniform_sphere(rng.next_2d()),
            };
            let tmax = if i % 2 == 0 { 0.5 } else { f32::INFINITY };
            let (ray, _) = traversal_ray(o, d, tmax);
            let oct_inv4 = accel.bvh.new_traversal(ray.direction).oct_inv4;
            for node in &accel.bvh.nodes {
                let want = node.intersect_ray(&ray, oct_inv4);
                assert_eq!(node_hits(node, &ray, oct_inv4), want, "ray {o} {d} {tmax}");
                met += (want != 0) as u64;
                tests += 1;
            }
        }
        // A ray meets a few nodes on its way down (about 5 of 2,500 here).
        assert!(met >= 1000, "the rays met only {met} of {tests} nodes");
    }

    /// Nanoseconds a closest-hit query takes on 200,000 rays from random points of the
    /// Bunny's box (half of length 0.2 as free flights, half unbounded as shadow rays),
    /// best of 15 rounds: `cargo test --release --lib -- --ignored traversal_speed
    /// --nocapture` (needs .cache/meshes, see scripts/fetch_meshes).
    #[test]
    #[ignore]
    fn traversal_speed() {
        use crate::geometry::mesh::read_ply;
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(".cache/meshes/bunny_watertight.ply");
        let Ok(raw) = read_ply(&path) else {
            eprintln!("no {}: run scripts/fetch_meshes", path.display());
            return;
        };
        let mesh = TriangleMesh::new(raw, &Mat4::IDENTITY, false, false, &path).expect("the Bunny");
        let g = vec![Geometry::Mesh(mesh)];
        let b = g[0].bounds();
        let mut rng = Pcg32::new(3, 1);
        let rays: Vec<(Vec3A, Vec3A, f32)> = (0..200_000)
            .map(|i| {
                let u = Vec3A::new(rng.next_1d(), rng.next_1d(), rng.next_1d());
                let d = square_to_uniform_sphere(rng.next_2d());
                let tmax = if i % 2 == 0 { 0.2 } else { f32::INFINITY };
                (b.min + u * (b.max - b.min), d, tmax)
            })
            .collect();
        let accel = Accel::build(&[&g[0]]);
        let mut best = f64::INFINITY;
        for _ in 0..15 {
            let start = std::time::Instant::now();
            let hits = rays
                .iter()
                .filter(|&&(o, d, tmax)| accel.intersect(&g, o, d, tmax).is_some())
                .count();
            std::hint::black_box(hits);
            best = best.min(start.elapsed().as_secs_f64() * 1e9 / rays.len() as f64);
        }
        eprintln!("closest hit: {best:.0} ns a ray");
    }
}
