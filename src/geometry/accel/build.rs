//! The accelerator's build: which shapes are tested beside the ray caster (few analytic
//! shapes, few Mitsuba `cube`s as boxes), the caster's primitives in its order, and the
//! caster itself, chosen once here ([`super::Caster`]).

use std::sync::Arc;

use glam::Vec3A;
use obvhs::aabb::Aabb;
use rayon::prelude::*;

use super::backend::{Backend, EMBREE_MIN_TRIANGLES};
use super::brute_force::BRUTE_FORCE_PRIMS;
use super::bvh::Bvh;
use super::bvh_build;
use super::embree::{build_quality, EmbreeScene, MeshRef};
use super::embree_api;
use super::lanes::{self, TriangleLanes};
use super::primitive::{PrimRef, Primitives, ANALYTIC};
use super::triangle::LeafTriangle;
use super::{Accel, Caster};
use crate::geometry::cuboid::Cuboid;
use crate::geometry::shape::Geometry;
use crate::geometry::Bounds;

/// Up to this many analytic shapes are tested one by one beside the BVH, which then
/// holds triangles only: its leaf test reads one contiguous triangle, without first
/// looking up what kind of primitive it is (a cache miss per candidate on a large mesh).
/// More of them go into the BVH with the triangles.
pub(super) const SEPARATE_ANALYTIC: usize = 16;

impl Accel {
    /// The accelerator over `shapes` with `backend`; `filtered` as for [`Accel::build`].
    pub(super) fn build_filtered(shapes: &[&Geometry], backend: Backend, filtered: bool) -> Accel {
        Self::build_caster(shapes, backend, filtered, true)
    }

    /// [`Accel::build_filtered`]; `lanes_allowed` false keeps a BVH where few triangles
    /// would be tested in lanes (for tests that compare the two).
    pub(super) fn build_caster(
        shapes: &[&Geometry],
        backend: Backend,
        filtered: bool,
        lanes_allowed: bool,
    ) -> Accel {
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
        // caster's primitive list; else few analytic shapes are kept out of the BVH.
        let mixed = n_analytic + n_triangles <= BRUTE_FORCE_PRIMS || n_analytic > SEPARATE_ANALYTIC;
        let n_prims = n_triangles + if mixed { n_analytic } else { 0 };
        // Embree builds its own BVH from the meshes, first: the primitive list is not
        // needed for it, and is not held during its build (the load's peak). The
        // primitives stay in input order then. (Above the threshold, the triangles are
        // never tested one by one.)
        const _: () = assert!(EMBREE_MIN_TRIANGLES > BRUTE_FORCE_PRIMS);
        let embree_wanted = backend == Backend::Embree && !mixed && n_prims >= EMBREE_MIN_TRIANGLES;
        let build = || build_embree(shapes, &cuboids, filtered);
        let (embree, warning) = match embree_wanted.then(build) {
            Some(Ok(e)) => (Some(e), None),
            Some(Err(e)) => (None, Some(format!("{e}; rays are cast with obvhs instead"))),
            None => (None, None),
        };
        let mut analytic = Vec::new();
        let mut prims = Vec::with_capacity(n_prims);
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
                }
            }
        }
        // obvhs's BVH, unless Embree traverses or the primitives are few enough to be
        // tested one by one (in input order). Its leaf order is the primitives' order,
        // for triangles in lanes too (the first of two hits at one distance wins).
        // The boxes only while obvhs builds (Embree boxes the triangles itself).
        let cwbvh = (embree.is_none() && prims.len() > BRUTE_FORCE_PRIMS)
            .then(|| bvh_build::build(prims.len(), |i| prim_aabb(shapes, &prims[i])));
        if let Some(b) = &cwbvh {
            prims = b
                .primitive_indices
                .par_iter()
                .map(|&i| prims[i as usize])
                .collect();
        }
        let cuboid_triangles: usize = cuboids
            .iter()
            .map(|c| match shapes[c.shape as usize] {
                Geometry::Mesh(m) => m.triangles.len(),
                _ => 0,
            })
            .sum();
        // Embree reads its own copy of the meshes: the hit tests' copy of their triangles
        // (48 bytes each) would only take memory (see `Primitives::unstored`).
        let unstored = if embree.is_some() { prims.len() } else { 0 };
        let mut triangles: Vec<LeafTriangle> =
            Vec::with_capacity(prims.len() - unstored + cuboid_triangles);
        // In parallel: on a mesh of millions of triangles, each a cache miss into the
        // mesh (leaf order is not the mesh's), this copy took seconds.
        triangles.par_extend(prims[unstored..].par_iter().map(|p| {
            match shapes[p.shape as usize] {
                Geometry::Mesh(m) if p.index != ANALYTIC => LeafTriangle::of(m, p.index),
                _ => LeafTriangle {
                    p0: Vec3A::ZERO,
                    e1: Vec3A::ZERO,
                    e2: Vec3A::ZERO,
                },
            }
        }));
        for c in &mut cuboids {
            c.first_leaf = (unstored + triangles.len()) as u32;
            if let Geometry::Mesh(m) = shapes[c.shape as usize] {
                triangles.extend((0..m.triangles.len() as u32).map(|ti| LeafTriangle::of(m, ti)));
            }
        }
        let n = prims.len();
        // A large mesh cast without Embree because it does not load (not because
        // MEDIAREG_ACCEL asked for obvhs) is told what Embree would save.
        let warning = match warning {
            None if cwbvh.is_some()
                && n_triangles >= bvh_build::LARGE_MESH
                && backend == Backend::Obvhs =>
            {
                let asked = matches!(embree_api::request(), Ok(embree_api::Request::Obvhs));
                match (asked, embree_api::load()) {
                    (false, Err(e)) => Some(large_mesh_hint(n_triangles, &e)),
                    _ => None,
                }
            }
            w => w,
        };
        let caster = match (embree, cwbvh) {
            (Some(e), _) => Caster::Embree(e),
            (None, None) => Caster::BruteForce,
            (None, Some(_)) if !mixed && lanes_allowed && n <= lanes::MAX_TRIANGLES => {
                Caster::Lanes(TriangleLanes::new(&triangles[..n]))
            }
            (None, Some(cwbvh)) => Caster::Obvhs(Bvh { cwbvh, mixed }),
        };
        Accel {
            caster,
            prims: Primitives {
                refs: prims,
                triangles,
                unstored,
            },
            analytic,
            cuboids,
            bounds,
            warning,
        }
    }
}

/// What a render of `triangles` without Embree (which does not load: `why`) is told.
fn large_mesh_hint(triangles: usize, why: &str) -> String {
    format!(
        "{:.1}M triangles are cast with the built-in BVH, Embree 3 not loading ({why}): \
         with Embree a mesh this large renders about twice as fast; {}",
        triangles as f64 / 1e6,
        embree_api::INSTALL_HINT
    )
}

/// Primitive `p`'s bounding box, for obvhs's build.
fn prim_aabb(shapes: &[&Geometry], p: &PrimRef) -> Aabb {
    let b = match shapes[p.shape as usize] {
        Geometry::Mesh(m) if p.index != ANALYTIC => {
            let mut b = Bounds::EMPTY;
            for v in m.vertices(p.index) {
                b.expand(v);
            }
            b
        }
        g => g.bounds(),
    };
    Aabb {
        min: b.min,
        max: b.max,
    }
}

/// The meshes of `shapes` for Embree but the cubes' (tested as boxes), as the primitive
/// list has them: each mesh's triangles contiguous, in the mesh's order.
pub(super) fn embree_meshes(shapes: &[&Geometry], cuboids: &[Cuboid]) -> Vec<MeshRef> {
    let mut meshes = Vec::new();
    let mut leaf = 0;
    for (si, g) in shapes.iter().enumerate() {
        let Geometry::Mesh(m) = g else { continue };
        if m.triangles.is_empty() || cuboids.iter().any(|c| c.shape == si as u32) {
            continue;
        }
        meshes.push(MeshRef {
            positions: Arc::clone(&m.positions),
            triangles: Arc::clone(&m.triangles),
            first_leaf: leaf as u32,
            shape: si as u32,
        });
        leaf += m.triangles.len();
    }
    meshes
}

/// Embree's scene over [`embree_meshes`], at the build quality their size asks for.
fn build_embree(
    shapes: &[&Geometry],
    cuboids: &[Cuboid],
    filtered: bool,
) -> Result<EmbreeScene, String> {
    let meshes = embree_meshes(shapes, cuboids);
    let triangles = meshes.iter().map(|m| m.triangles.len()).sum();
    let api = embree_api::load()
        .map_err(|e| format!("Embree 3 does not load ({e}); {}", embree_api::INSTALL_HINT))?;
    EmbreeScene::build(api, meshes, filtered, build_quality(triangles))
}
