//! The accelerator against brute force, its node test against obvhs', and its speed.

use super::build::SEPARATE_ANALYTIC;
use super::node::{node_hits, traversal_ray};
use super::primitive::ANALYTIC;
use super::triangle::LeafTriangle;
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
/// primitive (to rounding where a box's slab test stands for its triangles), with
/// either backend (Embree's triangle test rounds otherwise than ours: to rounding too).
#[test]
fn closest_hit_and_occlusion_match_brute_force() {
    for (spheres, boxes, backend) in [
        (3, false, Backend::Obvhs),
        (3, true, Backend::Obvhs),
        (SEPARATE_ANALYTIC + 4, true, Backend::Obvhs),
        (3, false, Backend::Embree),
    ] {
        let g = scene(spheres, boxes);
        let refs: Vec<&Geometry> = g.iter().collect();
        let accel = Accel::build_with(&refs, backend);
        let exact = accel.backend() == Backend::Obvhs;
        // Too many shapes beside the BVH: the cubes go into it.
        let as_boxes = boxes && spheres <= SEPARATE_ANALYTIC;
        assert_eq!(accel.cuboids.len(), if as_boxes { 2 } else { 0 });
        // Without the cubes' triangles, 3 spheres and a rectangle are few enough to
        // be tested one by one (in the primitive list: "mixed", with no traversal).
        let mixed = accel.prims.refs.iter().any(|p| p.index == ANALYTIC);
        assert_eq!(mixed, spheres > SEPARATE_ANALYTIC || as_boxes);
        assert_eq!(accel.traverses_bvh(), !as_boxes);
        let mut rng = Pcg32::new(5, spheres as u64);
        let mut hits = 0;
        for i in 0..20_000 {
            let o =
                Vec3A::new(rng.next_1d(), rng.next_1d(), rng.next_1d()) * 5.0 - Vec3A::splat(2.5);
            let d = square_to_uniform_sphere(rng.next_2d());
            let tmax = if i % 2 == 0 { 1.0 } else { f32::INFINITY };
            let got = accel.intersect(&g, o, d, tmax).map(|h| (h.shape, h.t));
            let want = brute_force(&g, o, d, tmax);
            if as_boxes || !exact {
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
    let accel = Accel::build_with(&[&g[0]], Backend::Obvhs);
    let Caster::Obvhs(bvh) = &accel.caster else {
        panic!("{}", accel.describe())
    };
    let bvh = &bvh.cwbvh;
    assert!(bvh.nodes.len() > 1000);
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
        let oct_inv4 = bvh.new_traversal(ray.direction).oct_inv4;
        for node in &bvh.nodes {
            let want = node.intersect_ray(&ray, oct_inv4);
            assert_eq!(node_hits(node, &ray, oct_inv4), want, "ray {o} {d} {tmax}");
            met += (want != 0) as u64;
            tests += 1;
        }
    }
    // A ray meets a few nodes on its way down (about 5 of 2,500 here).
    assert!(met >= 1000, "the rays met only {met} of {tests} nodes");
}

/// Nanoseconds a closest-hit query, an occlusion test and a crossings search (the
/// Bunny passing shadow rays) take on 200,000 rays from random points of the Bunny's
/// box (half of length 0.2 as free flights, half unbounded as shadow rays), best of 15
/// rounds, with each backend (both obvhs where Embree 3 is not installed): `cargo test --release --lib -- --ignored traversal_speed
/// --nocapture` (needs .cache/meshes, see scripts/fetch_meshes).
#[test]
#[ignore]
fn traversal_speed() {
    use crate::geometry::ply::read_ply;
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
    // Rounds alternate between the backends (the machine is shared and noisy).
    let accels = [Backend::Obvhs, Backend::Embree].map(|b| Accel::build_with(&[&g[0]], b));
    let pass = [ShadowPass::Passes];
    let mut best = [[f64::INFINITY; 3]; 2];
    let mut list = CrossingList::new();
    for _ in 0..15 {
        for (accel, best) in accels.iter().zip(&mut best) {
            for (kind, best) in best.iter_mut().enumerate() {
                let start = std::time::Instant::now();
                let hits = rays
                    .iter()
                    .filter(|&&(o, d, tmax)| match kind {
                        0 => accel.intersect(&g, o, d, tmax).is_some(),
                        1 => accel.occluded(&g, o, d, tmax),
                        _ => accel.crossings(&g, &pass, o, d, tmax, &mut list) == Crossings::Found,
                    })
                    .count();
                std::hint::black_box(hits);
                *best = best.min(start.elapsed().as_secs_f64() * 1e9 / rays.len() as f64);
            }
        }
    }
    for (accel, [hit, occluded, crossings]) in accels.iter().zip(best) {
        eprintln!(
            "{:?}: closest hit {hit:.0} ns, occluded {occluded:.0} ns, crossings {crossings:.0} ns a ray",
            accel.backend()
        );
    }
}

/// Triangles in lanes answer what the BVH over the same triangles does: the same
/// closest hit (distance and barycentrics to the bit; the same triangle unless two lie
/// at that distance, on a shared edge), the same occlusion and the same crossings, on
/// rays from random points and from the meshes' surfaces. Two meshes (one with its
/// normals flipped, so crossings take both sides) of few enough triangles for lanes
/// at either register width, and a sphere beside them that blocks shadow rays.
#[test]
fn lanes_answer_what_the_bvh_does() {
    use super::embree_tests::{mesh, rays, uv_sphere};
    // 2 n_lon (n_lat − 1) triangles: 32 and 24.
    let g = vec![
        mesh(uv_sphere(Vec3A::ZERO, 1.0, 3, 8), false),
        mesh(uv_sphere(Vec3A::new(1.5, 0.3, 0.0), 0.5, 3, 6), true),
        Geometry::Sphere(Sphere {
            center: Vec3A::new(-1.5, 1.0, 0.0),
            radius: 0.4,
            flip_normals: false,
            axes: Mat3A::IDENTITY,
        }),
    ];
    let refs: Vec<&Geometry> = g.iter().collect();
    let in_lanes = Accel::build_with(&refs, Backend::Obvhs);
    assert!(
        matches!(in_lanes.caster, Caster::Lanes(_)),
        "{}",
        in_lanes.describe()
    );
    let bvh = Accel::build_caster(&refs, Backend::Obvhs, true, false);
    assert!(matches!(bvh.caster, Caster::Obvhs(_)), "{}", bvh.describe());
    let pass = [ShadowPass::Passes, ShadowPass::Passes, ShadowPass::Blocks];
    let (mut hits, mut found, mut ties) = (0, 0, 0);
    let (mut la, mut lb) = (CrossingList::new(), CrossingList::new());
    for (o, d, tmax) in rays(&g, &in_lanes, 20_000) {
        let key = |h: Hit| (h.t, h.u, h.v, h.shape, h.leaf);
        let a = in_lanes.intersect(&g, o, d, tmax).map(key);
        let b = bvh.intersect(&g, o, d, tmax).map(key);
        if a != b {
            let (a, b) = (a.unwrap(), b.unwrap());
            assert_eq!(a.0, b.0, "ray {o} {d} {tmax}");
            ties += 1;
        }
        hits += a.is_some() as u32;
        assert_eq!(
            in_lanes.occluded(&g, o, d, tmax),
            bvh.occluded(&g, o, d, tmax)
        );
        let ca = in_lanes.crossings(&g, &pass, o, d, tmax, &mut la);
        let cb = bvh.crossings(&g, &pass, o, d, tmax, &mut lb);
        assert_eq!(ca, cb, "ray {o} {d} {tmax}");
        if ca == Crossings::Found {
            let sorted = |l: &CrossingList| {
                let mut v: Vec<(f32, u32, bool)> =
                    l.iter().map(|c| (c.t, c.shape, c.along_normal)).collect();
                v.sort_by(|x, y| x.0.total_cmp(&y.0));
                v
            };
            assert_eq!(sorted(&la), sorted(&lb), "ray {o} {d} {tmax}");
            found += !la.is_empty() as u32;
        }
    }
    assert!(
        hits > 1_000 && found > 1_000,
        "{hits} hits, {found} rays with crossings"
    );
    assert!(
        ties < 20,
        "{ties} hits on another triangle at the same distance"
    );
}
