//! The scalar paths on the scenes the lane path takes (`integrator::packet`): every
//! other test of these scenes renders them in lanes, so here the scalar integrator, the
//! lanes' reference, is held to Mitsuba 3's references too (one scene of each kind the
//! packet takes: a grey medium in a cube under an area light, a chromatic one in a
//! sphere, a medium behind glass, the camera in a medium, a directional light at a
//! small max_depth, the white furnace and a heterogeneous cloud), and the two paths are
//! compared image against image, each as an estimate from independent chunks.
//!
//! The comparison (`image::stats::compare`) and its stated false-alarm rate are those of
//! tests/volpath_equivalence.rs. Power: the lanes with the albedo 2% low must fail
//! against the scalar paths, as must the scalar paths with the albedo 2% low against
//! the reference.

mod common;

use common::{layout, reference, root, ALPHA, FALSE_ALARM};
use mediareg::image::stats::{compare, Comparison, Estimate};
use mediareg::integrator::render::packet_scene;
use mediareg::integrator::{render, RenderOptions};
use mediareg::BuildOverrides;

const CHUNKS: usize = 16;
const SPP: u32 = 128;

/// `CHUNKS` renders of mitsuba_scenes/`scene`.xml (with `params`) from seeds `seed..`,
/// in scalar paths or the packet's lanes.
fn chunks(scene: &str, params: &[(&str, &str)], seed: u64, scalar: bool) -> Estimate {
    let path = root().join("mitsuba_scenes").join(format!("{scene}.xml"));
    let images: Vec<_> = (0..CHUNKS as u64)
        .map(|i| {
            let s = mediareg::load_scene(
                &path,
                &common::options(params),
                &BuildOverrides {
                    spp: Some(SPP),
                    seed: Some(seed + i),
                    ..Default::default()
                },
            )
            .unwrap_or_else(|e| panic!("{e}"));
            let opts = RenderOptions {
                scalar_paths: scalar,
                show_progress: false,
                ..Default::default()
            };
            if !scalar {
                if let Err(why) = packet_scene(&s, &s.shot, &opts) {
                    panic!("{scene}: the lanes refuse it ({why})");
                }
            }
            render(&s, &s.shot, &opts).image.pixels
        })
        .collect();
    Estimate::from_chunks(&images, layout(&path, params))
}

/// The scalar paths against Mitsuba 3's reference, and the lanes against the scalar
/// paths.
fn check(scene: &str, seed: u64) -> (Comparison, Comparison) {
    let path = root().join("mitsuba_scenes").join(format!("{scene}.xml"));
    let scalar = chunks(scene, &[], seed, true);
    let lanes = chunks(scene, &[], seed + 1000, false);
    let l = layout(&path, &[]);
    let against_mitsuba = compare(
        &scalar,
        &reference(scene, &path).estimate,
        l,
        ALPHA,
        FALSE_ALARM,
    );
    let against_lanes = compare(&lanes, &scalar, l, ALPHA, FALSE_ALARM);
    println!("{scene}, scalar paths vs Mitsuba 3: {against_mitsuba}");
    println!("{scene}, lanes vs scalar paths: {against_lanes}");
    (against_mitsuba, against_lanes)
}

macro_rules! scalar_and_lanes_match {
    ($name:ident, $scene:literal, $seed:literal) => {
        #[test]
        fn $name() {
            let (mitsuba, lanes) = check($scene, $seed);
            assert!(mitsuba.passed, "scalar paths vs Mitsuba 3: {mitsuba}");
            assert!(lanes.passed, "lanes vs scalar paths: {lanes}");
        }
    };
}

scalar_and_lanes_match!(medium_cube_in_scalar_paths, "medium_cube", 5411);
scalar_and_lanes_match!(chromatic_sphere_in_scalar_paths, "chromatic_sphere", 5421);
scalar_and_lanes_match!(
    medium_in_dielectric_in_scalar_paths,
    "medium_in_dielectric",
    5431
);
scalar_and_lanes_match!(camera_in_medium_in_scalar_paths, "camera_in_medium", 5441);
scalar_and_lanes_match!(
    max_depth_directional_in_scalar_paths,
    "max_depth_directional",
    5451
);
scalar_and_lanes_match!(furnace_in_scalar_paths, "furnace", 5461);
scalar_and_lanes_match!(cloud_in_scalar_paths, "cloud", 5471);

/// Power, both comparisons: the albedo 2% low (in the lanes against the scalar paths;
/// in the scalar paths against Mitsuba 3) must fail, on the medium behind glass.
#[test]
fn a_two_percent_darker_medium_fails_both_comparisons() {
    let scene = "medium_in_dielectric";
    let path = root().join("mitsuba_scenes").join(format!("{scene}.xml"));
    let l = layout(&path, &[]);
    let albedo = mediareg::load_scene(&path, &common::options(&[]), &Default::default())
        .unwrap()
        .media[0]
        .albedo
        .x;
    let darker = format!("{}", albedo * 0.98);
    let params = [("albedo", darker.as_str())];
    let scalar = chunks(scene, &[], 5481, true);
    let lanes_darker = chunks(scene, &params, 5482, false);
    let c = compare(&lanes_darker, &scalar, l, ALPHA, FALSE_ALARM);
    println!("lanes 2% darker vs scalar paths: {c}");
    assert!(!c.passed, "the lanes' albedo 2% low went unseen: {c}");
    let scalar_darker = chunks(scene, &params, 5483, true);
    let c = compare(
        &scalar_darker,
        &reference(scene, &path).estimate,
        l,
        ALPHA,
        FALSE_ALARM,
    );
    println!("scalar paths 2% darker vs Mitsuba 3: {c}");
    assert!(
        !c.passed,
        "the scalar paths' albedo 2% low went unseen: {c}"
    );
}
