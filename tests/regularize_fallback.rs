//! Issue 41, item 5: with one frame, OIDN and `--oidn-check`, `regularize` is plain
//! volpath, through OIDN where the check of `regularize::fallback` finds that OIDN lowers
//! the error (without `--oidn-check` it is `render --denoise oidn`, the last test). The check
//! must keep plain volpath where OIDN raises the error (a camera in a medium, a
//! max_depth cut-off, the furnace) and keep OIDN where it lowers it (a chromatic sphere, a
//! medium in glass, a mesh, the cloud), each verified against the scene's Mitsuba 3
//! reference (issue 57); below the check's sample count the output is `render --denoise
//! oidn`'s, bit for bit.
//!
//! Needs the library (`scripts/fetch_oidn`, which `scripts/test` runs).

mod common;

use mediareg::regularize::{self, choices, Choices};
use mediareg::report::metrics::mse_against;

use common::{load_seeded, root};

fn one_frame(scene: &mediareg::scene::Scene) -> regularize::Regularized {
    let c = Choices {
        frames: 1,
        oidn_check: true,
        ..Default::default()
    };
    let (opts, shot) = choices::options(scene, &scene.shot, &c).unwrap();
    regularize::regularize(scene, &shot, &opts).unwrap()
}

/// The check's choice on `name` at `spp`, and whether OIDN really lowers the corrected
/// MSE against the reference there (a separate render of the same spp, plain and
/// denoised).
fn choice_and_truth(name: &str, spp: u32, seed: u64) -> (bool, bool, f64, f64, f64) {
    let scene = load_seeded(
        &root().join(format!("mitsuba_scenes/{name}.xml")),
        &[],
        spp,
        seed,
    );
    let out = one_frame(&scene);
    let check = out.oidn_check.expect("enough spp for the check");
    let (reference, var) = common::reference_images(name);
    let (plain_image, d) = common::plain_and_oidn(&scene, spp, seed);
    let (plain, oidn) = (
        mse_against(&plain_image, &reference, &var).1,
        mse_against(&d, &reference, &var).1,
    );
    (
        check.chose_oidn,
        oidn < plain,
        plain,
        oidn,
        check.oidn_error_se,
    )
}

/// (scene, spp, whether OIDN lowers the error there): the check must choose the better
/// image. Every case is clear (no near tie, where either choice would pass and the case
/// would constrain nothing): OIDN ÷ plain MSE measured at these spp over seeds 1–6 (this
/// test's seeds are 1 and 2; `measure_false_alarms_and_power` in
/// `tests/regularize_never_loses.rs` with `NEVER_LOSES_SEEDS=6 NEVER_LOSES_CASES=...`) in
/// the comments.
const CASES: &[(&str, u32, bool)] = &[
    // 3.6–4.5 (the check kept plain on all six). At 1024 spp it was 1.04–1.17, a near tie
    // that a 1.25 allowance let either choice pass.
    ("furnace", 4096, false),
    // 103–156.
    ("camera_in_medium", 1024, false),
    // 2.12–2.39.
    ("max_depth_directional", 1024, false),
    // 0.70–0.87.
    ("chromatic_sphere", 1024, true),
    // 0.13–0.38.
    ("medium_in_dielectric", 1024, true),
    // A mesh (the Stanford Bunny, from `.cache/meshes`): 0.19–0.21. 256 spp here and for
    // the cloud, whose samples cost more (the Bunny's 5–15× the analytic scenes').
    ("bunny_medium", 256, true),
    // A heterogeneous medium: 0.13–0.74, the plain image's error varying most.
    ("cloud", 256, true),
];

#[test]
fn the_check_keeps_plain_volpath_where_oidn_raises_the_error_and_oidn_where_it_lowers_it() {
    // Every scene is run and every wrong one named.
    let mut wrong = Vec::new();
    for &(name, spp, want_oidn) in CASES {
        for seed in [1, 2] {
            let (chose, truth, plain, oidn, se) = choice_and_truth(name, spp, seed);
            let errors = format!("MSE plain {plain:.3e}, OIDN {oidn:.3e}");
            if truth != want_oidn {
                wrong.push(format!(
                    "{name} seed {seed}: the scene no longer tests what it is here for ({errors})"
                ));
            }
            if chose != want_oidn {
                wrong.push(format!(
                    "{name} seed {seed}: the check chose {} ({errors}, the check's standard error {se:.1e})",
                    if chose { "OIDN" } else { "plain" }
                ));
            }
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

#[test]
fn below_the_check_one_frame_is_render_denoise_oidn() {
    let scene = load_seeded(&root().join("mitsuba_scenes/medium_cube.xml"), &[], 16, 5);
    let out = one_frame(&scene);
    assert!(out.oidn_check.is_none(), "16 spp is below the check");
    let (plain, d) = common::plain_and_oidn_at(&scene, &scene.shot);
    assert_eq!(out.source.pixels, plain.pixels, "the plain render");
    // Bit for bit: OIDN's input scale is computed in order (`oidn::autoexposure`), not by its
    // parallel sum, which made this differ 1 run in 2 beside the other test of this file.
    let bits = |p: &[[f32; 3]]| p.iter().flatten().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert!(
        bits(&out.predicted.pixels) == bits(&d.pixels),
        "its OIDN differs from render --denoise oidn's"
    );
}

/// Above the check, the frame's samples are M, A and B: three ranges of the shot's own
/// streams, which together are the plain render of all N spp. So the one-frame plain
/// image is that render and, where OIDN is kept, the output `render --denoise oidn`'s,
/// both up to the rounding of joining three images by their filter weights. Seen failing with A and B rendered
/// from seeds of their own (differences of a few percent: other samples).
#[test]
fn above_the_check_one_frame_is_the_plain_render_of_all_its_samples() {
    let scene = load_seeded(&root().join("mitsuba_scenes/medium_cube.xml"), &[], 64, 5);
    let out = one_frame(&scene);
    let check = out.oidn_check.as_ref().expect("64 spp is above the check");
    assert!(check.chose_oidn, "OIDN lowers the cube's error 7-14x");
    let (plain, d) = common::plain_and_oidn_at(&scene, &scene.shot);
    let differs = common::largest_relative_difference(&out.source.pixels, &plain.pixels);
    assert!(
        differs < 1e-5,
        "the plain image differs by {differs} (relative)"
    );
    let oidn = common::largest_relative_difference(&out.predicted.pixels, &d.pixels);
    assert!(oidn < 1e-4, "the OIDN image differs by {oidn} (relative)");
}

/// Without `--oidn-check` (the default) one frame is `render --denoise oidn`, bit for bit,
/// above the check's spp too, and where the check would keep plain volpath (a camera in
/// a medium, OIDN 25-30x plain's error at 128 spp): no check runs. Seen failing with the
/// check left on by default (the plain image came back).
#[test]
fn without_the_check_one_frame_is_render_denoise_oidn() {
    let scene = load_seeded(
        &root().join("mitsuba_scenes/camera_in_medium.xml"),
        &[],
        128,
        5,
    );
    let c = Choices {
        frames: 1,
        ..Default::default()
    };
    let (opts, shot) = choices::options(&scene, &scene.shot, &c).unwrap();
    let out = regularize::regularize(&scene, &shot, &opts).unwrap();
    assert!(out.oidn_check.is_none(), "no check without --oidn-check");
    let (plain, d) = common::plain_and_oidn_at(&scene, &scene.shot);
    let bits = |p: &[[f32; 3]]| p.iter().flatten().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert!(
        bits(&out.source.pixels) == bits(&plain.pixels),
        "the plain render"
    );
    assert!(
        bits(&out.predicted.pixels) == bits(&d.pixels),
        "its image differs from render --denoise oidn's"
    );
}
