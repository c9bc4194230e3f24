//! The Embree backend against obvhs on random rays: the same closest hits (shape,
//! triangle, distance, barycentrics), occlusion answers and shadow-ray crossings, to
//! rounding. The two triangle tests round differently, so a ray through an edge shared
//! by two triangles (or grazing one) may be given either; such answers are accepted only
//! where the ray is within rounding of an edge, and must stay rare.

use super::*;
use crate::geometry::mesh::{RawMesh, TriangleMesh};
use crate::geometry::offset_point;
use crate::geometry::shape::{Planar, Sphere};
use crate::sampling::warp::square_to_uniform_sphere;
use crate::sampling::Pcg32;
use glam::{Mat3A, Mat4, Vec3};
use std::path::Path;

fn raw(positions: Vec<Vec3A>, triangles: Vec<[u32; 3]>) -> RawMesh {
    RawMesh {
        positions,
        normals: None,
        triangles,
        uvs: None,
        warnings: Vec::new(),
    }
}

/// `r` as a mesh shape in world space (its normals flipped if `flip`).
pub(super) fn mesh(r: RawMesh, flip: bool) -> Geometry {
    let m = TriangleMesh::new(r, &Mat4::IDENTITY, true, flip, Path::new("test"));
    Geometry::Mesh(m.expect("a valid mesh"))
}

/// A closed latitude-longitude sphere mesh (shared vertices, poles as fans).
pub(super) fn uv_sphere(center: Vec3A, r: f32, n_lat: u32, n_lon: u32) -> RawMesh {
    let mut p = vec![center + Vec3A::Z * r, center - Vec3A::Z * r];
    for i in 1..n_lat {
        let theta = std::f32::consts::PI * i as f32 / n_lat as f32;
        for j in 0..n_lon {
            let phi = std::f32::consts::TAU * j as f32 / n_lon as f32;
            let (st, ct) = theta.sin_cos();
            p.push(center + Vec3A::new(st * phi.cos(), st * phi.sin(), ct) * r);
        }
    }
    let ring = |i: u32, j: u32| 2 + (i - 1) * n_lon + j % n_lon;
    let mut t = Vec::new();
    for j in 0..n_lon {
        t.push([0, ring(1, j), ring(1, j + 1)]);
        t.push([1, ring(n_lat - 1, j + 1), ring(n_lat - 1, j)]);
        for i in 1..n_lat - 1 {
            let (a, b, c, d) = (
                ring(i, j),
                ring(i + 1, j),
                ring(i + 1, j + 1),
                ring(i, j + 1),
            );
            t.push([a, b, c]);
            t.push([a, c, d]);
        }
    }
    raw(p, t)
}

/// Two sphere meshes (the second with `flip_normals`), a soup of small random
/// triangles, an analytic sphere and a rectangle: the BVH holds triangles only, with
/// the analytic shapes beside it, as in the mesh scenes.
fn scene() -> Vec<Geometry> {
    let mut rng = Pcg32::new(17, 3);
    let mut point = || Vec3A::new(rng.next_1d(), rng.next_1d(), rng.next_1d());
    let (mut p, mut t) = (Vec::new(), Vec::new());
    for i in 0..3000u32 {
        let c = point() * 4.0 - Vec3A::splat(2.0);
        for _ in 0..3 {
            p.push(c + (point() - Vec3A::splat(0.5)) * 0.15);
        }
        t.push([3 * i, 3 * i + 1, 3 * i + 2]);
    }
    let floor = Mat4::from_translation(Vec3::new(0.0, -1.6, 0.0))
        * Mat4::from_rotation_x(-1.5)
        * Mat4::from_scale(Vec3::splat(3.0));
    vec![
        mesh(uv_sphere(Vec3A::ZERO, 1.0, 24, 48), false),
        mesh(uv_sphere(Vec3A::new(1.5, 0.3, 0.0), 0.5, 12, 24), true),
        mesh(raw(p, t), false),
        Geometry::Sphere(Sphere {
            center: Vec3A::new(-1.5, 1.0, 0.0),
            radius: 0.3,
            flip_normals: false,
            axes: Mat3A::IDENTITY,
        }),
        Geometry::Planar(Planar::new(floor, false, false)),
    ]
}

/// Whether the hit lies within rounding of its triangle's edge (never, for an analytic
/// shape: both backends test those alike).
fn near_edge(h: &Hit) -> bool {
    h.leaf != u32::MAX && h.u.min(h.v).min(1.0 - h.u - h.v) < 1e-4
}

/// Random rays: from random points (bounded and not), and from points just off the
/// surfaces the previous ray hit, as a path's next segment starts.
pub(super) fn rays(g: &[Geometry], accel: &Accel, n: usize) -> Vec<(Vec3A, Vec3A, f32)> {
    let mut rng = Pcg32::new(23, 9);
    let mut out = Vec::with_capacity(n);
    let mut from: Option<(Vec3A, Vec3A)> = None;
    for i in 0..n {
        let d = square_to_uniform_sphere(rng.next_2d());
        let tmax = if i % 2 == 0 { 1.0 } else { f32::INFINITY };
        let o = match from.take() {
            Some((p, n)) => offset_point(p.into(), n.into(), d.into(), 1.0).into(),
            None => {
                Vec3A::new(rng.next_1d(), rng.next_1d(), rng.next_1d()) * 5.0 - Vec3A::splat(2.5)
            }
        };
        if i % 3 != 2 {
            if let Some(h) = accel.intersect(g, o, d, f32::INFINITY) {
                if h.leaf != u32::MAX {
                    from = Some(accel.triangle_surface(g, o, d, &h));
                }
            }
        }
        out.push((o, d, tmax));
    }
    out
}

fn backends(g: &[Geometry]) -> (Accel, Accel) {
    let refs: Vec<&Geometry> = g.iter().collect();
    let ours = Accel::build_with(&refs, Backend::Obvhs);
    let embree = Accel::build_with(&refs, Backend::Embree);
    assert_eq!(ours.backend(), Backend::Obvhs);
    assert_eq!(embree.backend(), Backend::Embree, "{:?}", embree.warning);
    (ours, embree)
}

/// Embree is asked for but not used below [`EMBREE_MIN_TRIANGLES`] triangles (a call
/// into it costs more than obvhs's traversal of so few), and used from there on.
#[test]
fn embree_starts_at_its_triangle_threshold() {
    // 2 n_lon (n_lat − 1) triangles.
    for (n_lat, n_lon, want) in [(4, 8, Backend::Obvhs), (17, 32, Backend::Embree)] {
        let g = mesh(uv_sphere(Vec3A::ZERO, 1.0, n_lat, n_lon), false);
        let Geometry::Mesh(m) = &g else {
            unreachable!()
        };
        let below = m.triangles.len() < EMBREE_MIN_TRIANGLES;
        assert_eq!(
            below,
            want == Backend::Obvhs,
            "{} triangles",
            m.triangles.len()
        );
        let accel = Accel::build_with(&[&g], Backend::Embree);
        assert_eq!(accel.backend(), want, "{} triangles", m.triangles.len());
    }
}

/// The same closest hits and occlusion answers, unfiltered and filtered.
#[test]
fn closest_hit_and_occlusion_match_obvhs() {
    let g = scene();
    let (ours, embree) = backends(&g);
    let rays = rays(&g, &ours, 40_000);
    let (mut hits, mut edge_cases) = (0, 0);
    for (i, &(o, d, tmax)) in rays.iter().enumerate() {
        // Every fourth ray skips the big sphere mesh (`intersect_where`).
        let keep = |s: u32| i % 4 != 0 || s != 0;
        let (a, b) = if i % 4 == 0 {
            (
                ours.intersect_where(&g, o, d, tmax, keep),
                embree.intersect_where(&g, o, d, tmax, keep),
            )
        } else {
            (
                ours.intersect(&g, o, d, tmax),
                embree.intersect(&g, o, d, tmax),
            )
        };
        let why = format!("ray {i}: {o} {d} {tmax}: obvhs {a:?}, Embree {b:?}");
        match (a, b) {
            (Some(a), Some(b)) if a.shape == b.shape && a.prim == b.prim => {
                assert!(keep(a.shape), "{why}");
                assert!((a.t - b.t).abs() <= 1e-5 * a.t.max(1.0), "{why}");
                assert!(
                    (a.u - b.u).abs() < 1e-4 && (a.v - b.v).abs() < 1e-4,
                    "{why}"
                );
                if a.leaf != u32::MAX {
                    let (pa, na) = ours.triangle_surface(&g, o, d, &a);
                    let (pb, nb) = embree.triangle_surface(&g, o, d, &b);
                    assert!(
                        (pa - pb).length() < 1e-4 && (na - nb).length() < 1e-4,
                        "{why}"
                    );
                }
                hits += 1;
            }
            // Two triangles at the same distance: through the edge they share.
            (Some(a), Some(b)) => {
                assert!((a.t - b.t).abs() <= 1e-5 * a.t.max(1.0), "{why}");
                assert!(near_edge(&a) && near_edge(&b), "{why}");
                edge_cases += 1;
            }
            (Some(h), None) | (None, Some(h)) => {
                assert!(near_edge(&h), "{why}");
                edge_cases += 1;
            }
            (None, None) => {}
        }
        if i % 4 != 0 {
            assert_eq!(
                ours.occluded(&g, o, d, tmax),
                embree.occluded(&g, o, d, tmax),
                "{why}"
            );
        }
    }
    eprintln!(
        "{} rays: {hits} same hits, {edge_cases} through an edge",
        rays.len()
    );
    assert!(hits > 10_000, "only {hits} rays hit something");
    assert!(edge_cases * 1000 < rays.len(), "{edge_cases} edge cases");
}

/// The same crossings (as sets: the backends find them in different orders), with the
/// soup passing shadow rays and with it blocking them; the rectangle always blocks.
#[test]
fn crossings_match_obvhs() {
    let g = scene();
    let (ours, embree) = backends(&g);
    let rays = rays(&g, &ours, 40_000);
    let sorted = |l: &CrossingList| {
        let mut v: Vec<Crossing> = l.to_vec();
        v.sort_by(|a, b| a.t.total_cmp(&b.t));
        v
    };
    use ShadowPass::{Blocks, Passes};
    for pass in [
        [Passes, Passes, Passes, Passes, Blocks],
        [Passes, Passes, Blocks, Passes, Blocks],
    ] {
        let (mut found, mut blocked, mut differ) = (0, 0, 0);
        let (mut la, mut lb) = (CrossingList::new(), CrossingList::new());
        for (i, &(o, d, tmax)) in rays.iter().enumerate() {
            let a = ours.crossings(&g, &pass, o, d, tmax, &mut la);
            let b = embree.crossings(&g, &pass, o, d, tmax, &mut lb);
            let same = a == b
                && (a != Crossings::Found || {
                    let (sa, sb) = (sorted(&la), sorted(&lb));
                    sa.len() == sb.len()
                        && sa.iter().zip(&sb).all(|(x, y)| {
                            x.shape == y.shape
                                && x.along_normal == y.along_normal
                                && (x.t - y.t).abs() <= 1e-5 * x.t.max(1.0)
                        })
                });
            if !same {
                // Only a ray through an edge may be answered otherwise: its closest
                // hit, or a crossing of either list, lies there.
                let hit = ours.intersect(&g, o, d, tmax);
                let on_edge = |l: &CrossingList| {
                    l.iter().any(|c| {
                        let h = ours.intersect(&g, o + d * (c.t * 0.999), d, c.t * 0.002);
                        h.is_some_and(|h| near_edge(&h))
                    })
                };
                assert!(
                    hit.is_some_and(|h| near_edge(&h)) || on_edge(&la) || on_edge(&lb),
                    "ray {i} {o} {d} {tmax}: obvhs {a:?} {la:?}, Embree {b:?} {lb:?}"
                );
                differ += 1;
            }
            found += (a == Crossings::Found && !la.is_empty()) as usize;
            blocked += (a == Crossings::Blocked) as usize;
        }
        eprintln!(
            "{pass:?}: {found} rays with crossings, {blocked} blocked, {differ} through an edge"
        );
        assert!(
            found > 2_000 && blocked > 2_000,
            "{found} found, {blocked} blocked"
        );
        assert!(differ * 1000 < rays.len(), "{differ} differ");
    }
}

/// Built without filter functions (for a scene that never asks for them), the searches
/// that pass over shapes still answer: `intersect_where` by plain casts past the hits it
/// refuses, the same hits as the filtered build's; the crossings as unsupported (the
/// caller then casts once per crossing).
#[test]
fn without_filters_the_filtered_searches_fall_back() {
    let g = scene();
    let refs: Vec<&Geometry> = g.iter().collect();
    let filtered = Accel::build_with(&refs, Backend::Embree);
    let plain = Accel::build_filtered(&refs, Backend::Embree, false);
    assert!(matches!(&filtered.caster, Caster::Embree(e) if e.filters));
    assert!(matches!(&plain.caster, Caster::Embree(e) if !e.filters));
    let pass = vec![ShadowPass::Passes; g.len()];
    let mut list = CrossingList::new();
    let mut past_refused = 0;
    for (i, &(o, d, tmax)) in rays(&g, &filtered, 4000).iter().enumerate() {
        // The big sphere mesh refused.
        let keep = |s: u32| s != 0;
        let a = filtered.intersect_where(&g, o, d, tmax, keep);
        let b = plain.intersect_where(&g, o, d, tmax, keep);
        let why = format!("ray {i}: {o} {d} {tmax}: filtered {a:?}, plain {b:?}");
        match (a, b) {
            (None, None) => {}
            (Some(a), Some(b)) => {
                assert!(keep(b.shape), "{why}");
                assert!((a.t - b.t).abs() <= 1e-5 * a.t.max(1.0), "{why}");
                assert!(
                    a.prim == b.prim || (near_edge(&a) && near_edge(&b)),
                    "{why}"
                );
                if plain
                    .intersect(&g, o, d, tmax)
                    .is_some_and(|h| h.shape == 0)
                {
                    past_refused += 1;
                }
            }
            _ => panic!("{why}"),
        }
        let c = plain.crossings(&g, &pass, o, d, tmax, &mut list);
        assert_eq!(c, Crossings::Unsupported, "ray {i}");
    }
    // The refused sphere stood in the way of many of the rays that found a hit past it.
    assert!(
        past_refused > 100,
        "{past_refused} rays past the refused sphere"
    );
}

/// Embree's medium-quality build (large meshes, [`embree::build_quality`]) gives the
/// high-quality build's closest hits: the same triangle at the same distance and
/// barycentrics (one triangle test), a different one only within rounding of a shared
/// edge, where the traversal order may pick either. Power: against the scene with its
/// soup of small triangles moved by 1e-3, most hits on the soup differ.
#[test]
fn medium_and_high_quality_builds_give_the_same_hits() {
    let g = scene();
    let refs: Vec<&Geometry> = g.iter().collect();
    let api = embree_api::load().expect("Embree loads");
    let build = |refs: &[&Geometry], q| {
        embree::EmbreeScene::build(api, build::embree_meshes(refs, &[]), false, q).unwrap()
    };
    let high = build(&refs, embree_api::BUILD_QUALITY_HIGH);
    let medium = build(&refs, embree_api::BUILD_QUALITY_MEDIUM);
    let mut moved = scene();
    if let Geometry::Mesh(m) = &mut moved[2] {
        m.positions = std::sync::Arc::new(
            m.positions
                .iter()
                .map(|p| *p + Vec3A::splat(1e-3))
                .collect(),
        );
    }
    let moved_refs: Vec<&Geometry> = moved.iter().collect();
    let shifted = build(&moved_refs, embree_api::BUILD_QUALITY_MEDIUM);
    let (ours, _) = backends(&g);
    let rays = rays(&g, &ours, 40_000);
    let (mut hits, mut edges, mut soup, mut soup_differs) = (0, 0, 0, 0);
    for &(o, d, tmax) in &rays {
        let (a, b) = (high.intersect(o, d, tmax), medium.intersect(o, d, tmax));
        match (a, b) {
            (Some(a), Some(b)) if a.leaf == b.leaf => {
                assert_eq!((a.t, a.u, a.v), (b.t, b.u, b.v), "{o} {d}");
                hits += 1;
                if a.shape == 2 {
                    soup += 1;
                    let c = shifted.intersect(o, d, tmax);
                    if c.is_none_or(|c| c.leaf != a.leaf || c.t != a.t) {
                        soup_differs += 1;
                    }
                }
            }
            (None, None) => {}
            (a, b) => {
                let at_edge =
                    a.as_ref().is_some_and(near_edge) || b.as_ref().is_some_and(near_edge);
                assert!(at_edge, "{o} {d} {tmax}: high {a:?}, medium {b:?}");
                edges += 1;
            }
        }
    }
    assert!(
        hits > 5_000 && edges * 1000 < hits,
        "{hits} hits, {edges} at edges"
    );
    assert!(
        soup > 500 && soup_differs * 2 > soup,
        "{soup_differs} of {soup}"
    );
}
