//! `Scene::new` builds a scene from plain Rust objects, no XML: one made by hand is hit
//! where its shape is and renders what it should, and a loaded scene taken apart and
//! rebuilt renders bit for bit as loaded (the loader builds through the same door).

use glam::{Mat3A, Mat4, Vec2, Vec3, Vec3A, Vec4};
use mediareg::bsdf::Bsdf;
use mediareg::emitter::Emitter;
use mediareg::geometry::shape::{Geometry, Sphere};
use mediareg::integrator::{render, RenderOptions};
use mediareg::scene::camera::PerspectiveCamera;
use mediareg::scene::film::{Film, Rfilter};
use mediareg::scene::shot::Shot;
use mediareg::scene::{IntegratorKind, IntegratorSettings, Scene, SceneParts, ShapeInfo};
use mediareg::texture::Texture;
use mediareg::BuildOverrides;

const SIZE: usize = 16;

/// A grey diffuse unit sphere at the origin under a white sky (Mitsuba's `constant`),
/// seen from (0, 0, 5) with a 40° field of view, traced by `path`.
fn sphere_under_sky() -> SceneParts {
    // Mitsuba's look_at: columns left, up, forward, origin.
    let camera_to_world = Mat4::from_cols(
        Vec4::new(-1.0, 0.0, 0.0, 0.0),
        Vec4::new(0.0, 1.0, 0.0, 0.0),
        Vec4::new(0.0, 0.0, -1.0, 0.0),
        Vec4::new(0.0, 0.0, 5.0, 1.0),
    );
    SceneParts {
        geometries: vec![Geometry::Sphere(Sphere {
            center: Vec3A::ZERO,
            radius: 1.0,
            flip_normals: false,
            axes: Mat3A::IDENTITY,
        })],
        shapes: vec![ShapeInfo {
            bsdf: 0,
            emitter: None,
            interior: None,
            exterior: None,
            id: None,
            origin: "the test's sphere".to_string(),
            tangent_frame: false,
        }],
        bsdfs: vec![Bsdf::Diffuse {
            reflectance: Texture::Constant(Vec3::splat(0.5)),
        }],
        emitters: vec![Emitter::Constant {
            radiance: Vec3::ONE,
        }],
        environment: Some(0),
        media: Vec::new(),
        camera_medium: None,
        shot: Shot {
            camera: PerspectiveCamera {
                to_world: camera_to_world,
                tan_half_fov_x: 20f32.to_radians().tan(),
                aspect: 1.0,
                near_clip: 1e-2,
                far_clip: 1e4,
                principal_point_offset: Vec2::ZERO,
                film_size: Vec2::splat(SIZE as f32),
            },
            film: Film {
                width: SIZE,
                height: SIZE,
                crop_offset: (0, 0),
                crop_size: (SIZE, SIZE),
                rfilter: Rfilter::Box,
                pixel_format: Default::default(),
                component_format: Default::default(),
            },
            spp: 4,
            seed: 1,
        },
        integrator: IntegratorSettings {
            kind: IntegratorKind::Path,
            max_depth: u32::MAX,
            rr_depth: 5,
            hide_emitters: false,
            moment_aovs_dropped: false,
        },
        warnings: Vec::new(),
    }
}

#[test]
fn a_scene_built_by_hand_is_hit_where_its_shape_is() {
    let scene = Scene::new(sphere_under_sky());
    let hit = scene
        .intersect(Vec3A::new(0.0, 0.0, 5.0), Vec3A::NEG_Z, f32::INFINITY)
        .expect("the ray down the axis meets the sphere");
    assert_eq!(hit.shape, 0);
    assert!((hit.t - 4.0).abs() < 1e-5, "t = {}", hit.t);
    assert!((hit.n - Vec3A::Z).length() < 1e-5, "n = {}", hit.n);
    assert!(scene
        .intersect(Vec3A::new(0.0, 1.5, 5.0), Vec3A::NEG_Z, f32::INFINITY)
        .is_none());
}

/// The sky is seen as it is at the corner; the sphere, convex and diffuse, reflects
/// half of the unit sky at every point (each path bounces once and escapes).
#[test]
fn a_scene_built_by_hand_renders() {
    let scene = Scene::new(sphere_under_sky());
    let img = render(&scene, &scene.shot, &RenderOptions::default()).image;
    assert_eq!((img.width, img.height), (SIZE, SIZE));
    assert_eq!(img.pixels[0], [1.0; 3]);
    let centre = img.pixels[(SIZE / 2) * SIZE + SIZE / 2];
    for c in centre {
        assert!((c - 0.5).abs() < 1e-3, "centre {centre:?}");
    }
}

#[test]
fn a_loaded_scene_rebuilt_from_its_parts_renders_the_same() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("mitsuba_scenes/medium_cube.xml");
    let overrides = BuildOverrides {
        spp: Some(4),
        seed: Some(3),
        crop: None,
        ..Default::default()
    };
    let render_it = |s: &Scene| render(s, &s.shot, &RenderOptions::default()).image.pixels;
    let loaded = mediareg::load_scene(&path, &Default::default(), &overrides).unwrap();
    let want = render_it(&loaded);
    let rebuilt = Scene::new(SceneParts {
        geometries: loaded.geometries,
        shapes: loaded.shapes,
        bsdfs: loaded.bsdfs,
        emitters: loaded.emitters,
        environment: loaded.environment,
        media: loaded.media,
        camera_medium: loaded.camera_medium,
        shot: loaded.shot,
        integrator: loaded.integrator,
        warnings: loaded.warnings,
    });
    let got = render_it(&rebuilt);
    assert!(want.iter().any(|p| p.iter().any(|&c| c > 0.0)));
    assert!(
        got.iter()
            .zip(&want)
            .all(|(a, b)| a.map(f32::to_bits) == b.map(f32::to_bits)),
        "the rebuilt scene renders differently"
    );
}
