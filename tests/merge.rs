//! `mediareg merge`: chunks rendered by the command line (distinct seeds) merge into an
//! image that matches independent renders statistically, with a variance file equal to
//! the chunks' spread; bad chunks are refused before anything is written. Renders of
//! consecutive sample ranges of one seed join by their filter weights into the render of
//! all their samples.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{layout, render_chunks, root, scene_text::tmp_dir, ALPHA, FALSE_ALARM};
use mediareg::image::stats::{compare, Comparison, Estimate};
use mediareg::image::{read_exr, read_exr_int_attribute, write_exr, Image};

const CHUNKS: usize = 8;
const SPP: u32 = 16;

fn cbox() -> PathBuf {
    root().join("mitsuba_scenes/cbox.xml")
}

fn mediareg(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_mediareg"))
        .args(args)
        .output()
        .expect("runs mediareg")
}

/// Renders the chunks with `mediareg render` (seeds 0..CHUNKS) into `dir`, merges them.
fn render_and_merge(dir: &Path) -> (Vec<PathBuf>, PathBuf) {
    let scene = cbox();
    let chunks: Vec<PathBuf> = (0..CHUNKS)
        .map(|k| {
            let out = dir.join(format!("chunk{k}.exr"));
            let r = mediareg(&[
                "render",
                scene.to_str().unwrap(),
                "--seed",
                &k.to_string(),
                "--spp",
                &SPP.to_string(),
                "--no-png",
                "-t",
                "2",
                "-o",
                out.to_str().unwrap(),
            ]);
            assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
            out
        })
        .collect();
    let merged = dir.join("merged.exr");
    let mut args = vec!["merge", merged.to_str().unwrap()];
    args.extend(chunks.iter().map(|c| c.to_str().unwrap()));
    let r = mediareg(&args);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    (chunks, merged)
}

fn to64(img: &Image) -> Vec<[f64; 3]> {
    img.pixels.iter().map(|p| p.map(|c| c as f64)).collect()
}

/// The merge against `CHUNKS` renders (in-process, other seeds) with `params`.
fn compare_merged(merged: &Path, params: &[(&str, &str)]) -> Comparison {
    let mean = read_exr(merged).unwrap();
    let var = read_exr(&merged.with_file_name("merged_var.exr")).unwrap();
    let a = Estimate::from_moments(to64(&mean), to64(&var), CHUNKS as f64 - 1.0);
    let lay = layout(&cbox(), params);
    let b = Estimate::from_chunks(&render_chunks(&cbox(), params, CHUNKS, SPP, 100), lay);
    compare(&a, &b, lay, ALPHA, FALSE_ALARM)
}

#[test]
fn merged_chunks_match_independent_renders_and_their_spread() {
    let dir = tmp_dir("merge", "match");
    let (chunks, merged) = render_and_merge(&dir);
    assert_eq!(
        read_exr_int_attribute(&merged, "spp").unwrap(),
        Some((CHUNKS as u32 * SPP) as i32)
    );
    // The variance file is the chunks' sample variance over K (equal spp).
    let imgs: Vec<Image> = chunks.iter().map(|c| read_exr(c).unwrap()).collect();
    let var = read_exr(&dir.join("merged_var.exr")).unwrap();
    let k = CHUNKS as f64;
    for i in 0..var.pixels.len() {
        for c in 0..3 {
            let xs: Vec<f64> = imgs.iter().map(|im| im.pixels[i][c] as f64).collect();
            let mu = xs.iter().sum::<f64>() / k;
            let s2 = xs.iter().map(|x| (x - mu) * (x - mu)).sum::<f64>() / (k - 1.0);
            let got = var.pixels[i][c] as f64;
            assert!(
                (got - s2 / k).abs() <= 1e-5 * (s2 / k) + 1e-12,
                "pixel {i}: {got} vs {}",
                s2 / k
            );
        }
    }
    let c = compare_merged(&merged, &[]);
    assert!(c.passed, "{c}");
    // Power: the same merge against renders with the walls' reflectance 2% off.
    let c = compare_merged(&merged, &[("wall_reflectance", "0.765")]);
    assert!(!c.passed, "a 2% reflectance change went undetected: {c}");
}

#[test]
fn bad_chunks_are_refused_and_nothing_is_written() {
    let dir = tmp_dir("merge", "bad");
    let small = Image {
        width: 2,
        height: 1,
        pixels: vec![[0.5; 3]; 2],
    };
    let no_spp = dir.join("no_spp.exr");
    write_exr(&no_spp, &small).unwrap();
    let out = dir.join("out.exr");
    let r = mediareg(&["merge", out.to_str().unwrap(), no_spp.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        !r.status.success() && err.contains("no_spp.exr") && err.contains("spp"),
        "{err}"
    );

    let a = dir.join("a.exr");
    let b = dir.join("b.exr");
    mediareg::image::write_exr_with(&a, &small, &[("spp", 4)]).unwrap();
    let wide = Image {
        width: 3,
        height: 1,
        pixels: vec![[0.5; 3]; 3],
    };
    mediareg::image::write_exr_with(&b, &wide, &[("spp", 4)]).unwrap();
    let r = mediareg(&[
        "merge",
        out.to_str().unwrap(),
        a.to_str().unwrap(),
        b.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        !r.status.success() && err.contains("b.exr") && err.contains("3x1"),
        "{err}"
    );

    let nan = dir.join("nan.exr");
    // mediareg never writes NaN: this chunk comes from elsewhere.
    exr::prelude::write_rgb_file(&nan, 2, 1, |x, _| {
        if x == 1 {
            (0.5f32, 0.5f32, f32::NAN)
        } else {
            (0.5, 0.5, 0.5)
        }
    })
    .unwrap();
    let r = mediareg(&[
        "merge",
        out.to_str().unwrap(),
        a.to_str().unwrap(),
        nan.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        !r.status.success() && err.contains("nan.exr") && err.contains("(1, 0)"),
        "{err}"
    );
    assert!(!out.exists() && !dir.join("out_var.exr").exists());
}

/// Renders of consecutive sample ranges of one seed (`RenderOptions::first_sample`, as
/// `regularize --frames 1` renders its M, A and B), joined by their filter weights
/// (`merge::mean_by_weights`), are the render of all their samples up to rounding, with
/// a Gaussian filter too, whose weights differ between the ranges. The same ranges
/// joined by their spp (`mean_by_spp`) must not be: that tells the two joins apart.
#[test]
fn sample_ranges_joined_by_weights_are_the_render_of_all_their_samples() {
    use mediareg::image::merge::{mean_by_spp, mean_by_weights};
    use mediareg::integrator::{render, RenderOptions};
    let scene = common::load_seeded(&cbox(), &[("filter", "gaussian"), ("res", "48")], 16, 3);
    let whole = render(&scene, &scene.shot, &RenderOptions::default());
    let range = |first: u32, spp: u32| {
        let opts = RenderOptions {
            first_sample: first,
            ..Default::default()
        };
        render(&scene, &scene.shot.with(spp, scene.shot.seed), &opts)
    };
    let parts = [range(0, 10), range(10, 3), range(13, 3)];
    let largest_difference =
        |img: &Image| common::largest_relative_difference(&img.pixels, &whole.image.pixels);
    let by_weights = mean_by_weights(&parts.each_ref().map(|r| (&r.image, r.weights.as_slice())));
    let by_spp = mean_by_spp(&[
        (&parts[0].image, 10),
        (&parts[1].image, 3),
        (&parts[2].image, 3),
    ]);
    let (w, s) = (largest_difference(&by_weights), largest_difference(&by_spp));
    assert!(
        w < 1e-5,
        "joined by weights, the ranges differ from the render by {w}"
    );
    assert!(
        s > 1e-4,
        "joined by spp they differ by only {s}: the test cannot tell the joins apart"
    );
}
