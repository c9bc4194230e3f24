//! volpath's tests: shadow transmittance against exact intervals, crossings found
//! once, emitters seen through media, convex and sealed media.

use super::*;
use crate::geometry::accel::{CrossingList, Crossings};
use crate::sampling::warp::square_to_uniform_sphere;

/// Two null cubes around media (one chromatic and turned) and a blocking cube, in
/// the BVH together.
const CUBES: &str = r#"
        <shape type="cube">
            <transform name="to_world"><scale value="0.5"/><translate x="-1"/></transform>
            <bsdf type="null"/>
            <medium type="homogeneous" name="interior">
                <float name="sigma_t" value="2"/><float name="albedo" value="0.5"/></medium>
        </shape>
        <shape type="cube">
            <transform name="to_world"><rotate y="1" angle="30"/><scale value="0.6"/>
                <translate x="0.8"/></transform>
            <bsdf type="null"/>
            <medium type="homogeneous" name="interior">
                <rgb name="sigma_t" value="0.2, 0.6, 1"/><float name="scale" value="5"/>
                <float name="albedo" value="0.5"/></medium>
        </shape>
        <shape type="cube">
            <transform name="to_world"><scale value="0.4"/><translate y="1.5"/></transform>
            <bsdf type="diffuse"/>
        </shape>"#;

/// Analytic shapes beside the BVH: a blocking sphere, a null sphere around a medium
/// and a null rectangle that bounds no medium (crossing it changes nothing).
const ANALYTIC: &str = r#"
        <shape type="sphere">
            <point name="center" x="0" y="-1.5" z="0"/><float name="radius" value="0.4"/>
        </shape>
        <shape type="sphere">
            <point name="center" x="0.9" y="-1" z="1.5"/><float name="radius" value="0.6"/>
            <bsdf type="null"/>
            <medium type="homogeneous" name="interior">
                <float name="sigma_t" value="3"/><float name="albedo" value="0.5"/></medium>
        </shape>
        <shape type="rectangle">
            <transform name="to_world"><scale value="0.5"/><translate x="-1" y="1.2" z="-0.8"/>
            </transform>
            <bsdf type="null"/>
        </shape>"#;

/// The scene with the cubes (if `cubes`) as boxes beside the BVH, as loaded (see
/// `geometry::cuboid`), or as triangles in it (`boxes` false).
fn scene_with(test: &str, cubes: bool, boxes: bool) -> Scene {
    let mut scene = scene(test, cubes);
    if !boxes {
        for g in &mut scene.geometries {
            if let crate::geometry::shape::Geometry::Mesh(m) = g {
                m.cube_to_world = None;
            }
        }
        let refs: Vec<_> = scene.geometries.iter().collect();
        scene.accel = crate::geometry::accel::Accel::build(&refs, true);
    }
    scene
}

/// A scene of [`ANALYTIC`], after [`CUBES`] if `cubes`, written to a file of the
/// test's own (tests run in parallel).
fn scene(test: &str, cubes: bool) -> Scene {
    let xml = format!(
        r#"<scene version="3.0.0">
            <sensor type="perspective"><film type="hdrfilm">
                <integer name="width" value="4"/><integer name="height" value="4"/></film>
            </sensor>{}{ANALYTIC}</scene>"#,
        if cubes { CUBES } else { "" }
    );
    load_xml(test, &xml)
}

/// Loads a scene file's text, written to a file named after `name` (each test its
/// own name: tests run in parallel).
fn load_xml(name: &str, xml: &str) -> Scene {
    crate::integrator::scene_from_xml("volpath", name, xml)
}

/// Where the ray o + t d is inside the box (local [-1, 1]³ mapped by `to_local`
/// from the world), as (t_in, t_out) with t in world units, if it meets it.
fn box_interval(to_local: glam::Affine3A, o: Vec3A, d: Vec3A) -> Option<(f32, f32)> {
    let (lo, ld) = (
        to_local.transform_point3a(o),
        to_local.transform_vector3a(d),
    );
    let (a, b) = ((-Vec3A::ONE - lo) / ld, (Vec3A::ONE - lo) / ld);
    let (t0, t1) = (a.min(b).max_element(), a.max(b).min_element());
    (t0 < t1).then_some((t0, t1))
}

/// Where the ray o + t d (unit d) is inside the sphere (c, r), if it meets it:
/// |o + t d − c|² = r².
fn sphere_interval(c: Vec3A, r: f32, o: Vec3A, d: Vec3A) -> Option<(f32, f32)> {
    let oc = o - c;
    let (b, c) = (oc.dot(d), oc.length_squared() - r * r);
    let disc = b * b - c;
    (disc > 0.0).then(|| (-b - disc.sqrt(), -b + disc.sqrt()))
}

/// The exact transmittance of the shadow ray in [`scene`]`(_, cubes)`: the media's
/// intervals clipped to (0, dist), crossed in order (the medium before the first
/// crossing is `medium`, after one the entered shape's or none), 0 if a blocker lies
/// on the way. Media are numbered as the scene numbers them (in file order).
fn exact(o: Vec3A, d: Vec3A, dist: f32, medium: Option<u32>, cubes: bool) -> Vec3 {
    use glam::{Affine3A, Quat};
    let on_way = |t: f32| t > 0.0 && t < dist;
    let crosses = |i: Option<(f32, f32)>| i.is_some_and(|(a, b)| on_way(a) || on_way(b));
    // (interval, σ_t) of each medium, in file order.
    let mut media = Vec::new();
    if cubes {
        let blocker = Affine3A::from_scale_rotation_translation(
            Vec3::splat(0.4),
            Quat::IDENTITY,
            Vec3::new(0.0, 1.5, 0.0),
        );
        if crosses(box_interval(blocker.inverse(), o, d)) {
            return Vec3::ZERO;
        }
        let cube = |scale: f32, angle: f32, x: f32| {
            let q = Quat::from_rotation_y(angle.to_radians());
            let m = Affine3A::from_scale_rotation_translation(Vec3::splat(scale), q, Vec3::X * x);
            box_interval(m.inverse(), o, d)
        };
        media.push((cube(0.5, 0.0, -1.0), Vec3::splat(2.0)));
        media.push((cube(0.6, 30.0, 0.8), Vec3::new(1.0, 3.0, 5.0)));
    }
    if crosses(sphere_interval(Vec3A::new(0.0, -1.5, 0.0), 0.4, o, d)) {
        return Vec3::ZERO;
    }
    let ball = sphere_interval(Vec3A::new(0.9, -1.0, 1.5), 0.6, o, d);
    media.push((ball, Vec3::splat(3.0)));
    // Crossings: (t, the medium after it).
    let mut crossings = Vec::new();
    for (k, (interval, _)) in media.iter().enumerate() {
        if let Some((a, b)) = *interval {
            crossings.extend(
                [(a, Some(k)), (b, None)]
                    .into_iter()
                    .filter(|x| on_way(x.0)),
            );
        }
    }
    crossings.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (mut depth, mut start) = (Vec3::ZERO, 0.0);
    let mut current = medium.map(|m| m as usize);
    for (t, after) in crossings.into_iter().chain([(dist, None)]) {
        if let Some(m) = current {
            depth += media[m].1 * (t - start);
        }
        (start, current) = (t, after);
    }
    (-depth).exp()
}

/// One search for all crossings gives the exact transmittance on random shadow
/// rays from inside and outside the media, with cubes (as triangles in a BVH, or as
/// boxes) and without (the analytic shapes alone). (One cast per crossing is off
/// where a ray grazes a face:
/// its next cast starts at a point moved off the ray along the normal, which shifts
/// the following crossing by offset / |cos|.)
#[test]
fn crossings_in_one_traversal_give_the_exact_transmittance() {
    for (cubes, boxes) in [(true, false), (true, true), (false, false)] {
        let scene = scene_with(&format!("random_rays_{cubes}_{boxes}"), cubes, boxes);
        let n_media = scene.media.len();
        assert_eq!(n_media, if cubes { 3 } else { 1 });
        // The null sphere's index: after the cubes and the blocking sphere.
        let ball = if cubes { 4 } else { 1 };
        let mut rng = Pcg32::new(7, 3);
        let (mut blocked, mut multi, mut in_ball) = (0, 0, 0);
        let mut hits = CrossingList::new();
        for _ in 0..20_000 {
            let u = Vec3A::new(rng.next_1d(), rng.next_1d(), rng.next_1d());
            let o = Vec3A::new(-2.0, -2.0, -1.0) + u * Vec3A::new(4.0, 4.0, 3.0);
            let d = square_to_uniform_sphere(rng.next_2d());
            let dist = 5.0 * rng.next_1d();
            // Start in any medium or none (the rules are the same for every start).
            let k = (rng.next_1d() * (n_media + 1) as f32) as usize % (n_media + 1);
            let medium = (k < n_media).then_some(k as u32);
            let g = &scene.geometries;
            match scene
                .accel
                .crossings(g, &scene.shadow_pass, o, d, dist, &mut hits)
            {
                Crossings::Blocked => blocked += 1,
                Crossings::Found => {
                    multi += usize::from(hits.len() >= 2);
                    in_ball += usize::from(hits.iter().any(|h| h.shape == ball));
                }
                Crossings::Unsupported => panic!("unsupported without thin dielectrics"),
            }
            let ray = ShadowRay { o, d, dist, medium };
            let tr = shadow_transmittance(
                &scene,
                ray,
                &mut ShadowDerivative::forward(None),
                &mut Pcg32::new(1, 1),
            )
            .tr;
            let tr = Vec3::from(tr);
            let want = exact(o, d, dist, medium, cubes);
            assert!(
                (tr - want).abs().max_element() <= 1e-4 * want.max_element() + 1e-6,
                "o {o} d {d} dist {dist} medium {medium:?}: {tr} vs {want}"
            );
        }
        assert!(
            blocked > 300 && multi > 300 && in_ball > 500,
            "{blocked} blocked, {multi} with 2+ crossings, {in_ball} through the ball"
        );
    }
}

/// A ray through the diagonal shared by two triangles of a cube's face may hit both
/// (it does here): the face is still crossed once.
#[test]
fn a_crossing_found_twice_on_a_shared_edge_counts_once() {
    // Cubes as triangles: a box is one primitive, met once.
    let scene = scene_with("shared_edge", true, false);
    let mut repeats = 0;
    // The first cube spans x in [-1.5, -0.5], y and z in [-0.5, 0.5]; σ_t = 2. Rays
    // along z through its faces z = ±0.5 on either diagonal, and the centre.
    for (x, y) in [(-0.8, 0.2), (-0.8, -0.2), (-1.0, 0.0)] {
        for dir in [1.0f32, -1.0] {
            let o = Vec3A::new(x, y, -2.0 * dir);
            let d = Vec3A::new(0.0, 0.0, dir);
            let mut hits = CrossingList::new();
            let g = &scene.geometries;
            let found = scene
                .accel
                .crossings(g, &scene.shadow_pass, o, d, 4.0, &mut hits);
            repeats += usize::from(found == Crossings::Found && hits.len() > 2);
            // From outside: 1 unit in the medium. Starting "in" it outside the cube
            // (the rules do not check): 1.5 units of it, then the cube's 1 unit,
            // then none after leaving it.
            for (medium, depth) in [(None, 1.0f32), (Some(0), 2.5)] {
                let ray = ShadowRay {
                    o,
                    d,
                    dist: 4.0,
                    medium,
                };
                let through = shadow_transmittance(
                    &scene,
                    ray,
                    &mut ShadowDerivative::forward(Some(0)),
                    &mut Pcg32::new(1, 1),
                );
                let tr = Vec3::from(through.tr);
                // ∂ ln T / ∂σ_t: minus the length in the medium.
                assert!(
                    (through.d_log.x + depth).abs() < 1e-4,
                    "({x}, {y}) dir {dir}: d ln T {} vs {}",
                    through.d_log.x,
                    -depth
                );
                let want = (-2.0 * depth).exp();
                assert!(
                    (tr.x - want).abs() < 1e-3 * want,
                    "({x}, {y}) dir {dir} medium {medium:?}: {tr} vs {want}"
                );
            }
        }
    }
    assert!(
        repeats > 0,
        "no ray hit a face twice: the case is not tested"
    );
}

/// An area emitter seen through a medium that only absorbs (albedo 0): a path
/// either passes to it or dies at its collision, so the estimate of Mitsuba's
/// estimator is L or 0 at random. Counted in expectation, every sample is the exact
/// L e^{−σ_t t}.
#[test]
fn an_emitter_seen_through_a_medium_is_counted_in_expectation() {
    let xml = r#"<scene version="3.0.0">
            <medium type="homogeneous" id="fog">
                <float name="sigma_t" value="0.7"/><float name="albedo" value="0"/></medium>
            <sensor type="perspective"><ref id="fog"/><film type="hdrfilm">
                <integer name="width" value="4"/><integer name="height" value="4"/></film>
            </sensor>
            <shape type="sphere"><float name="radius" value="10"/><bsdf type="null"/>
                <ref name="interior" id="fog"/></shape>
            <shape type="sphere"><point name="center" x="0" y="0" z="3"/>
                <float name="radius" value="0.5"/>
                <emitter type="area"><rgb name="radiance" value="2, 3, 4"/></emitter></shape>
        </scene>"#;
    let scene = load_xml("emitter_in_fog", xml);
    assert!(scene.camera_medium.is_some());
    let albedo: Vec<Vec3> = scene.media.iter().map(|m| m.albedo).collect();
    let le = Vec3::new(2.0, 3.0, 4.0);
    let o = Vec3A::ZERO;
    for x in [0.0f32, 0.1, -0.15] {
        let d = Vec3A::new(x, 0.0, 1.0).normalize();
        // The near hit of o + t d with the sphere (c, 0.5): t = b − √(b² − |c|² + r²).
        let c = Vec3A::new(0.0, 0.0, 3.0);
        let b = d.dot(c);
        let t = b - (b * b - c.length_squared() + 0.25).sqrt();
        let want = le * (-0.7 * t).exp();
        for k in 0..200 {
            let mut rng = Pcg32::new(11, k);
            let settings = PathSettings {
                albedo: &albedo,
                estimand: Estimand::RadianceOnly,
            };
            let l = sample(&scene, &settings, o, d, f32::INFINITY, &mut rng).radiance;
            assert!(
                (l - want).abs().max_element() <= 1e-4 * want.max_element(),
                "direction {d}, sample {k}: {l} vs {want}"
            );
        }
    }
}

/// A medium that fills one convex shape with nothing else inside casts against that
/// shape alone (`Scene::intersect_in_medium`, `geometry::convex`): from points inside,
/// its hits are the scene's, and its clearance is the distance to the nearest face
/// plane (found here from the mesh's own triangles) or to the sphere. Media filling
/// two shapes, with another shape within reach, outside a shape, around the camera
/// or in an open shape get no such shape.
#[test]
fn a_convex_medium_casts_against_its_shape_alone() {
    use crate::geometry::convex::ConvexBoundary;
    use crate::geometry::shape::Geometry;
    let scene_of = |name: &str, extra: &str, camera_medium: &str| {
        let xml = format!(
            r#"<scene version="3.0.0">
            <medium type="homogeneous" id="fog">
                <float name="sigma_t" value="2"/><float name="albedo" value="0.9"/></medium>
            <medium type="homogeneous" id="ball">
                <float name="sigma_t" value="3"/><float name="albedo" value="0.9"/></medium>
            <sensor type="perspective">{camera_medium}<film type="hdrfilm">
                <integer name="width" value="4"/><integer name="height" value="4"/></film>
            </sensor>
            <shape type="cube"><transform name="to_world">
                    <scale x="0.6" y="0.3" z="0.8"/><rotate x="1" y="1" angle="35"/>
                    <scale x="1.3" y="1" z="0.7"/><translate x="0.2" z="-0.1"/></transform>
                <bsdf type="null"/><ref name="interior" id="fog"/></shape>
            <shape type="sphere"><point name="center" x="3" y="0" z="0"/>
                <float name="radius" value="0.7"/>
                <bsdf type="dielectric"/><ref name="interior" id="ball"/></shape>
            <shape type="rectangle"><transform name="to_world"><scale value="5"/>
                <rotate x="1" angle="-90"/><translate y="-1.5"/></transform></shape>
            <shape type="sphere"><point name="center" x="0" y="2.5" z="0"/>
                <float name="radius" value="0.3"/>
                <emitter type="area"><rgb name="radiance" value="5, 5, 5"/></emitter></shape>
            {extra}
        </scene>"#
        );
        load_xml(&format!("convex_{name}"), &xml)
    };
    let scene = scene_of("box_and_ball", "", "");
    let mut rng = Pcg32::new(9, 3);
    for (mi, name) in [(0u32, "box"), (1, "ball")] {
        let b = scene.convex_media[mi as usize]
            .as_ref()
            .unwrap_or_else(|| panic!("{name}: no convex shape found"));
        let shape = b.shape();
        // A point inside and its exact distance to the surface.
        let inside = |rng: &mut Pcg32| match (b, &scene.geometries[shape as usize]) {
            (ConvexBoundary::Box { .. }, Geometry::Mesh(m)) => {
                let to_world = m.cube_to_world.unwrap();
                let l = (rng.next_2d().extend(rng.next_1d()) * 2.0 - glam::Vec3::ONE) * 0.98;
                let p = Vec3A::from(to_world.transform_point3(l));
                let planes = (0..m.triangles.len() as u32).map(|ti| {
                    let [a, b, c] = m.vertices(ti);
                    ((b - a).cross(c - a).normalize().dot(p - a)).abs()
                });
                (p, planes.fold(f32::INFINITY, f32::min))
            }
            (ConvexBoundary::Sphere(_), Geometry::Sphere(s)) => {
                let p = s.center
                    + square_to_uniform_sphere(rng.next_2d())
                        * (0.98 * s.radius * rng.next_1d().cbrt());
                (p, s.radius - (p - s.center).length())
            }
            _ => panic!("{name}: the convex shape is not the one filled"),
        };
        for _ in 0..2000 {
            let (p, distance) = inside(&mut rng);
            let clearance = b.clearance(&scene.geometries, p);
            assert!(
                clearance <= distance && clearance >= 0.999 * distance - 1e-6,
                "{name}: clearance {clearance} at {p}, distance {distance}"
            );
            let d = square_to_uniform_sphere(rng.next_2d());
            let full = scene.intersect(p, d, f32::INFINITY).unwrap();
            let own = scene
                .intersect_in_medium(mi, p, d, f32::INFINITY)
                .unwrap_or_else(|| panic!("{name}: no exit from {p} along {d}"));
            assert_eq!(
                (own.shape, full.shape),
                (shape, shape),
                "{name}: {p} along {d}"
            );
            assert!(
                (own.t - full.t).abs() <= 1e-5 * full.t.max(1.0) && own.t >= clearance,
                "{name}: exit at {} against the scene's {}, clearance {clearance}",
                own.t,
                full.t
            );
            assert!((own.p - full.p).length() <= 1e-5 && own.n.dot(full.n) > 0.9999);
        }
    }
    let none = [
        (
            "two_shapes",
            r#"<shape type="sphere"><point name="center" x="0" y="0" z="3"/>
                    <float name="radius" value="0.2"/><bsdf type="null"/>
                    <ref name="interior" id="fog"/></shape>"#,
            "",
        ),
        (
            "bead_inside",
            r#"<shape type="sphere"><point name="center" x="0.2" y="0" z="-0.1"/>
                    <float name="radius" value="0.1"/></shape>"#,
            "",
        ),
        (
            "fog_outside_a_shape",
            r#"<shape type="sphere"><point name="center" x="0" y="0" z="3"/>
                    <float name="radius" value="0.2"/><bsdf type="null"/>
                    <ref name="exterior" id="fog"/></shape>"#,
            "",
        ),
        ("camera_in_fog", "", r#"<ref id="fog"/>"#),
    ];
    for (name, extra, camera) in none {
        let scene = scene_of(name, extra, camera);
        assert!(scene.convex_media[0].is_none(), "{name}: found convex");
        assert!(
            scene.convex_media[1].is_some(),
            "{name}: the ball is still convex"
        );
    }
    let open = load_xml(
        "convex_rectangle",
        r#"<scene version="3.0.0"><medium type="homogeneous" id="fog"/>
            <sensor type="perspective"><film type="hdrfilm">
                <integer name="width" value="4"/><integer name="height" value="4"/></film>
            </sensor>
            <shape type="rectangle"><bsdf type="null"/><ref name="interior" id="fog"/></shape>
            </scene>"#,
    );
    assert!(
        open.convex_media[0].is_none(),
        "an open rectangle found convex"
    );
}

/// A medium sealed in closed shapes that block shadow rays, with no emitter inside,
/// skips emitter sampling (`Scene::emitters_unreachable`), and every emitter sample
/// it skips would have been 0. Open, passing or partly passing boundaries, an
/// emitter inside, or the medium outside some shape keep the sampling.
#[test]
fn a_sealed_medium_skips_only_emitter_samples_that_cannot_arrive() {
    let scene_of = |name: &str, boundary: &str, bsdf: &str, extra: &str| {
        let xml = format!(
            r#"<scene version="3.0.0">
            <medium type="homogeneous" id="juice">
                <float name="sigma_t" value="2"/><float name="albedo" value="0.9"/></medium>
            <sensor type="perspective"><film type="hdrfilm">
                <integer name="width" value="4"/><integer name="height" value="4"/></film>
            </sensor>
            <shape type="{boundary}"><bsdf type="{bsdf}"/><ref name="interior" id="juice"/></shape>
            <shape type="sphere"><point name="center" x="2" y="2" z="0"/>
                <float name="radius" value="0.3"/>
                <emitter type="area"><rgb name="radiance" value="5, 5, 5"/></emitter></shape>
            <emitter type="point"><point name="position" x="-2" y="1" z="1"/></emitter>
            <emitter type="directional"><vector name="direction" x="0" y="-1" z="0"/></emitter>
            <emitter type="constant"/>
            {extra}
        </scene>"#
        );
        load_xml(&format!("sealed_{name}"), &xml)
    };
    let sealed = [
        ("glass_ball", "sphere", "dielectric", ""),
        ("glass_cube", "cube", "dielectric", ""),
        ("diffuse_ball", "sphere", "diffuse", ""),
    ];
    for (name, boundary, bsdf, extra) in sealed {
        let mut scene = scene_of(name, boundary, bsdf, extra);
        assert!(scene.emitters_unreachable[0], "{name}: not found sealed");
        // What the skipped samples would have been: 0 at every point inside.
        scene.emitters_unreachable[0] = false;
        let mut rng = Pcg32::new(5, 1);
        for _ in 0..2000 {
            let p = square_to_uniform_sphere(rng.next_2d()) * (0.95 * rng.next_1d().cbrt());
            let d_in = square_to_uniform_sphere(rng.next_2d());
            let x = medium_emitter_sample(
                &scene,
                0,
                p,
                d_in,
                0.0,
                &mut ShadowDerivative::forward(None),
                &mut rng,
            );
            let value = x.map_or(Vec3::ZERO, |x| x.value);
            assert_eq!(
                value,
                Vec3::ZERO,
                "{name}: an emitter sample from {p} arrived"
            );
        }
    }
    let open = [
        ("null_ball", "sphere", "null", ""),
        ("thin_glass_ball", "sphere", "thindielectric", ""),
        ("rectangle", "rectangle", "dielectric", ""),
        (
            "point_light_inside",
            "sphere",
            "dielectric",
            r#"<emitter type="point"><point name="position" x="0.1" y="0" z="0"/></emitter>"#,
        ),
        (
            "area_light_inside",
            "sphere",
            "dielectric",
            r#"<shape type="sphere"><float name="radius" value="0.1"/>
                    <emitter type="area"/></shape>"#,
        ),
        (
            "juice_around_a_bead",
            "sphere",
            "dielectric",
            r#"<shape type="sphere"><float name="radius" value="0.1"/><bsdf type="null"/>
                    <ref name="exterior" id="juice"/></shape>"#,
        ),
    ];
    for (name, boundary, bsdf, extra) in open {
        let scene = scene_of(name, boundary, bsdf, extra);
        assert!(!scene.emitters_unreachable[0], "{name}: found sealed");
    }
}
