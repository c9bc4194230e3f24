//! One compressed wide BVH (obvhs CWBVH) over every triangle of the scene, with the
//! analytic shapes tested one by one beside it when there are few of them, else in it
//! as one primitive each. Mitsuba `cube`s, when few, are tested beside it as boxes
//! ([`Cuboid`]) instead of as 12 triangles in it. Where Embree 3 is installed, a BVH of
//! triangles only is Embree's instead ([`Backend`], [`embree_api`]); a few dozen
//! triangles are tested all at once in SIMD lanes instead ([`lanes`]).

use std::time::Duration;

use glam::Vec3A;
use obvhs::aabb::Aabb;
use obvhs::cwbvh::builder::build_cwbvh;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::Ray as BvhRay;
use obvhs::BvhBuildParams;

mod backend;
mod embree;
pub mod embree_api;
mod hit;
mod lanes;
mod node;
mod triangle;

pub use backend::{Backend, EMBREE_MIN_TRIANGLES};
pub(super) use hit::cuboid_hit;
pub use hit::{Crossing, CrossingList, Crossings, Hit, ShadowPass, MAX_CROSSINGS};

use super::cuboid::Cuboid;
use super::shape::Geometry;
use super::Bounds;
use lanes::TriangleLanes;
use node::{node_hits, traversal_ray};
use triangle::LeafTriangle;

/// Which primitive of which shape; `index` is [`ANALYTIC`] for a sphere, rectangle or
/// disk (one primitive per shape).
#[derive(Clone, Copy, Debug)]
struct PrimRef {
    shape: u32,
    index: u32,
}

const ANALYTIC: u32 = u32::MAX;

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
    /// obvhs's BVH (empty where Embree traverses).
    bvh: CwBvh,
    embree: Option<embree::EmbreeScene>,
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
    /// The BVH's triangles in SIMD lanes, tested all at once instead of traversing it
    /// (where there are few: [`lanes::MAX_TRIANGLES`]).
    lanes: Option<TriangleLanes>,
    pub bounds: Bounds,
    /// Why the requested backend was not used, when it could not be built (Embree
    /// failed): for the scene's warnings.
    pub warning: Option<String>,
}

impl Accel {
    /// The accelerator over `shapes` with [`Backend::requested`] (obvhs, with a warning,
    /// where that is an error). `filtered`: whether it will be asked the searches that
    /// pass over some shapes ([`Accel::intersect_where`], [`Accel::crossings`]); without,
    /// Embree's scene is built without filter functions, and those searches fall back
    /// to plain casts.
    pub fn build(shapes: &[&Geometry], filtered: bool) -> Accel {
        match Backend::requested() {
            Ok(b) => Self::build_filtered(shapes, b, filtered),
            Err(e) => {
                let mut a = Self::build_filtered(shapes, Backend::Obvhs, filtered);
                a.warning = Some(format!("{e}; rays are cast with obvhs instead"));
                a
            }
        }
    }

    /// What casts this scene's rays, for the render's output: "Embree 3.13.5",
    /// "obvhs", or the shapes tested one by one where there is no BVH.
    pub fn describe(&self) -> String {
        if self.embree.is_some() {
            if let Ok(api) = embree_api::load() {
                return format!("Embree {}", api.version);
            }
        }
        if let Some(l) = &self.lanes {
            format!("{} triangles tested in SIMD lanes", l.len())
        } else if self.traverses_bvh() {
            let below_threshold = !self.mixed
                && self.prims.len() < EMBREE_MIN_TRIANGLES
                && Backend::requested() == Ok(Backend::Embree);
            if below_threshold {
                format!(
                    "obvhs ({} triangles: fewer than the {EMBREE_MIN_TRIANGLES} Embree pays \
                     for)",
                    self.prims.len()
                )
            } else {
                "obvhs".to_string()
            }
        } else {
            "each shape tested in turn (too few for a BVH)".to_string()
        }
    }

    /// Which ray caster traverses the triangles.
    pub fn backend(&self) -> Backend {
        if self.embree.is_some() {
            return Backend::Embree;
        }
        Backend::Obvhs
    }

    /// The accelerator over `shapes` with `backend`, for every kind of search.
    pub fn build_with(shapes: &[&Geometry], backend: Backend) -> Accel {
        Self::build_filtered(shapes, backend, true)
    }

    fn build_filtered(shapes: &[&Geometry], backend: Backend, filtered: bool) -> Accel {
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
        // Embree builds its own BVH (from the meshes, below): prims stay in input order.
        // (Above the threshold, the triangles are never tested one by one.)
        const _: () = assert!(EMBREE_MIN_TRIANGLES > BRUTE_FORCE_PRIMS);
        let embree_wanted =
            backend == Backend::Embree && !mixed && prims.len() >= EMBREE_MIN_TRIANGLES;
        let build = || Self::build_embree(shapes, &prims, filtered);
        let (embree, warning) = match embree_wanted.then(build) {
            Some(Ok(e)) => (Some(e), None),
            Some(Err(e)) => (None, Some(format!("{e}; rays are cast with obvhs instead"))),
            None => (None, None),
        };
        let embree_wanted = embree.is_some();
        let bvh = if aabbs.is_empty() || embree_wanted {
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
        if prims.len() > BRUTE_FORCE_PRIMS && !embree_wanted {
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
        let in_lanes = !mixed && !embree_wanted && prims.len() > BRUTE_FORCE_PRIMS;
        let in_lanes = in_lanes && prims.len() <= lanes::MAX_TRIANGLES;
        let lanes = in_lanes.then(|| TriangleLanes::new(&triangles[..prims.len()]));
        Accel {
            bvh,
            embree,
            prims,
            triangles,
            analytic,
            cuboids,
            mixed,
            lanes,
            bounds,
            warning,
        }
    }

    /// Embree's scene over the triangles of `prims` (in input order: each mesh's
    /// triangles contiguous, in the mesh's order).
    fn build_embree(
        shapes: &[&Geometry],
        prims: &[PrimRef],
        filtered: bool,
    ) -> Result<embree::EmbreeScene, String> {
        let mut meshes = Vec::new();
        let mut leaf = 0;
        while leaf < prims.len() {
            let shape = prims[leaf].shape;
            let Geometry::Mesh(m) = shapes[shape as usize] else {
                return Err(format!("shape {shape} is not a mesh"));
            };
            meshes.push(embree::MeshRef {
                positions: &m.positions,
                triangles: &m.triangles,
                first_leaf: leaf as u32,
                shape,
            });
            leaf += m.triangles.len();
        }
        let api = embree_api::load()
            .map_err(|e| format!("Embree 3 does not load ({e}); {}", embree_api::INSTALL_HINT))?;
        embree::EmbreeScene::build(api, &meshes, filtered)
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
        self.closest(shapes, o, d, tmax, |_| true, false)
    }

    /// Closest hit along `o + t d`, 0 < t < tmax, with a shape `keep` accepts (with
    /// `|_| true`, as [`Accel::intersect`], the test compiles away).
    #[inline(always)]
    pub fn intersect_where(
        &self,
        shapes: &[Geometry],
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
        keep: impl Fn(u32) -> bool,
    ) -> Option<Hit> {
        self.closest(shapes, o, d, tmax, keep, true)
    }

    /// [`Accel::intersect_where`]; `filtered` false says `keep` accepts every shape
    /// (Embree is then asked without a filter callback).
    #[inline(always)]
    fn closest(
        &self,
        shapes: &[Geometry],
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
        keep: impl Fn(u32) -> bool,
        filtered: bool,
    ) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let mut t_best = tmax;
        // The analytic shapes first: a hit among them shortens the BVH's ray.
        for &shape in self.analytic.iter().filter(|&&s| keep(s)) {
            if let Some(t) = Self::analytic_intersect(shapes, shape, o, d, t_best) {
                t_best = t;
                best = Some(Hit::analytic(shape, t));
            }
        }
        for c in self.cuboids.iter().filter(|c| keep(c.shape)) {
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
                if !keep(self.prims[i].shape) {
                    continue;
                }
                if let Some((t, u, v)) = self.prim_intersect(shapes, i, o, d, t_best) {
                    t_best = t;
                    best = Some(self.hit(i, t, u, v));
                }
            }
            return best;
        }
        if let Some(e) = &self.embree {
            let found = if !filtered {
                e.intersect(o, d, t_best)
            } else if e.filters {
                e.intersect_filtered(o, d, t_best, &mut |c| keep(c.shape))
            } else {
                // Built without filters (not expected to be asked): past every hit
                // `keep` refuses, one plain cast after another.
                let mut tnear = 0.0;
                loop {
                    match e.intersect_from(o, d, tnear, t_best) {
                        Some(h) if !keep(h.shape) && h.t < t_best => tnear = h.t.next_up(),
                        Some(h) if keep(h.shape) => break Some(h),
                        _ => break None,
                    }
                }
            };
            return found.or(best);
        }
        if let Some(l) = &self.lanes {
            let found = l.closest(o, d, t_best, |i| keep(self.prims[i].shape));
            return found.map(|h| self.hit(h.index, h.t, h.u, h.v)).or(best);
        }
        let (ray, back) = traversal_ray(o, d, t_best);
        let mut best_prim = None;
        self.traverse(ray, |ray_tmax, id| {
            if !keep(self.prims[id].shape) {
                return f32::INFINITY;
            }
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
            ng: [0.0; 3],
        }
    }

    /// The point of a triangle hit of `o + t d` and its unit geometric normal
    /// (p1 − p0) × (p2 − p0), with no lookups in the mesh (where a surface needs no
    /// shading frame, see `Scene::intersect`). Where the ray caster gave the normal
    /// (Embree), the point is o + t d: reading the triangle for its barycentric point
    /// missed the cache on most hits of a large mesh, and the spawn offset
    /// (`geometry::offset_magnitude`) is far larger than the difference. Else both
    /// come from the copy the hit test has just read.
    #[inline]
    pub fn triangle_surface(&self, o: Vec3A, d: Vec3A, hit: &Hit) -> (Vec3A, Vec3A) {
        if hit.ng != [0.0; 3] {
            return (o + d * hit.t, Vec3A::from_array(hit.ng).normalize_or_zero());
        }
        let t = &self.triangles[hit.leaf as usize];
        (
            t.p0 + t.e1 * hit.u + t.e2 * hit.v,
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
        if let Some(e) = self.embree.as_ref().filter(|e| e.filters) {
            // Embree may hand over a triangle twice (see `each_hit`): each counts once.
            let mut seen = arrayvec::ArrayVec::<u32, MAX_CROSSINGS>::new();
            let mut answer = None;
            e.each_hit(o, d, tmax, &mut |c| {
                if seen.contains(&c.leaf) {
                    return false;
                }
                // Embree's normal is the triangle's (p1 − p0) × (p2 − p0), as the hit
                // has it: no load of the accelerator's copy (a cache miss).
                let flip = matches!(&shapes[c.shape as usize], Geometry::Mesh(m) if m.flip_normals);
                answer = record(Crossing {
                    t: c.t,
                    shape: c.shape,
                    along_normal: (d.dot(c.ng) > 0.0) != flip,
                });
                // A crossing recorded (and so seen) only where the search goes on.
                if answer.is_none() {
                    seen.push(c.leaf);
                }
                answer.is_some()
            });
            return answer.unwrap_or(Crossings::Found);
        }
        if self.embree.is_some() {
            // Built without filters (not expected to be asked): one cast per crossing.
            return Crossings::Unsupported;
        }
        let mut answer = None;
        let mut each = |id: usize, t: f32| {
            answer = record(self.triangle_crossing(shapes, self.prims[id].shape, id, t, d));
            answer.is_none()
        };
        if let Some(l) = &self.lanes {
            l.each_hit(o, d, tmax, each);
            return answer.unwrap_or(Crossings::Found);
        }
        let (ray, _) = traversal_ray(o, d, tmax);
        self.traverse(ray, |_, id| {
            match self.triangles[id].intersect(o, d, tmax) {
                // Not a closer hit for the traversal: the ray's extent stays; a distance
                // of 0 culls every remaining node, and the traversal ends.
                Some((t, _, _)) if !each(id, t) => 0.0,
                _ => f32::INFINITY,
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
        if let Some(e) = &self.embree {
            return e.occluded(o, d, tmax);
        }
        if let Some(l) = &self.lanes {
            return l.any_hit(o, d, tmax);
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
mod embree_tests;
#[cfg(test)]
mod tests;
