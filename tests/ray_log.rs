//! `scene::ray_log` on a scene loaded from a file: casting the logged rays again, and
//! (feature `ray-log`) a render recording its casts. Here rather than beside the
//! module, which sits below the loader and the integrators.

use glam::Vec3A;
use mediareg::scene::ray_log::{time_casts, Cast, LoggedRay, RayLog};
use mediareg::scene::Scene;
use mediareg::BuildOverrides;

/// A directory per test: the tests run in parallel threads of one process, and one
/// writing `scene.xml` while the other reads it made the reader see an empty file.
fn temp(test: &str, name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("mediareg_ray_log_{}_{test}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// Two spheres in a row, a medium inside the first, and a wall of 18 triangles
/// behind them (more than the brute-force limit, so casts traverse the BVH).
fn scene(with_log: bool) -> Scene {
    let xml = r#"<scene version="3.0.0">
        <integrator type="volpath"/>
        <sensor type="perspective"><float name="fov" value="40"/>
            <transform name="to_world"><lookat origin="0,0,5" target="0,0,0" up="0,1,0"/></transform>
            <sampler type="independent"><integer name="sample_count" value="4"/></sampler>
            <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film>
        </sensor>
        <shape type="sphere"><float name="radius" value="0.5"/><bsdf type="null"/>
            <medium type="homogeneous" name="interior"><float name="sigma_t" value="2"/></medium>
        </shape>
        <shape type="sphere"><point name="center" x="0" y="0" z="-1.5"/><float name="radius" value="0.5"/></shape>
        <shape type="obj"><string name="filename" value="wall.obj"/></shape>
        <emitter type="point"><point name="position" x="0" y="2" z="2"/></emitter>
    </scene>"#;
    // A 3 × 3 grid of squares at z = −3.
    let mut obj = String::new();
    for j in 0..4 {
        for i in 0..4 {
            obj += &format!("v {} {} -3\n", i as f32 - 1.5, j as f32 - 1.5);
        }
    }
    for j in 0..3 {
        for i in 0..3 {
            let v = 1 + i + 4 * j;
            obj += &format!("f {} {} {}\nf {} {} {}\n", v, v + 1, v + 5, v, v + 5, v + 4);
        }
    }
    let test = if with_log { "logged" } else { "plain" };
    std::fs::write(temp(test, "wall.obj"), obj).unwrap();
    let path = temp(test, "scene.xml");
    std::fs::write(&path, xml).unwrap();
    let mut scene =
        mediareg::load_scene(&path, &Default::default(), &BuildOverrides::default()).unwrap();
    if with_log {
        scene.ray_log = Some(RayLog::default());
    }
    scene
}

#[test]
fn casting_again_times_each_kind_present() {
    let scene = scene(false);
    assert!(scene.accel.traverses_bvh());
    let ray = |kind, z: f32| LoggedRay {
        kind,
        o: Vec3A::new(0.0, 0.0, z),
        d: Vec3A::NEG_Z,
        tmax: f32::INFINITY,
    };
    let rays = [
        ray(Cast::ClosestHit, 5.0),
        ray(Cast::ClosestHit, 0.0),
        ray(Cast::Crossings, 0.0),
    ];
    let timings = time_casts(&scene, &rays, 2);
    let kinds: Vec<(Cast, usize)> = timings.iter().map(|t| (t.kind, t.count)).collect();
    assert_eq!(kinds, [(Cast::ClosestHit, 2), (Cast::Crossings, 1)]);
    assert!(timings
        .iter()
        .all(|t| t.ns_per_ray.is_finite() && t.ns_per_ray > 0.0));
}

/// With the `ray-log` feature, a render records its casts: a closest hit for every
/// camera ray at least, and shadow searches from the medium and the surfaces.
#[cfg(feature = "ray-log")]
#[test]
fn a_render_records_its_casts() {
    let scene = scene(true);
    let rendered = mediareg::integrator::render(&scene, &scene.shot, &Default::default());
    let samples = rendered.stats.samples as usize;
    let rays = scene.ray_log.unwrap().into_rays();
    let count = |k| rays.iter().filter(|r| r.kind == k).count();
    assert!(
        count(Cast::ClosestHit) >= samples,
        "{} < {samples}",
        count(Cast::ClosestHit)
    );
    assert!(count(Cast::Crossings) > 0);
    assert!(rays
        .iter()
        .all(|r| r.o.is_finite() && r.d.is_normalized() && r.tmax > 0.0));
}
