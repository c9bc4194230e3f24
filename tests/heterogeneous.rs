//! Heterogeneous media (Mitsuba 3's `heterogeneous` with a `gridvolume`): the cloud
//! scene against Mitsuba 3 (reference/cloud), with power tests (density scale 5% off,
//! albedo 0.99 → 0.98, g negated); the albedo gradient against finite differences with
//! common random numbers; bad `.vol` files refused with the file and what is wrong.
//! (The corpus's heterogeneous scenes are compared in tests/corpus.rs.)

mod common;

use common::scene_text::{load_or_build_error, load_text, tmp_dir, write};
use common::{check_against_reference, load_seeded, render_pixels, root};
use mediareg::integrator::volpath::Estimand;
use mediareg::integrator::RenderOptions;
use mediareg::medium::grid::write_vol;

const CHUNKS: usize = 8;
const SPP: u32 = 64;

#[test]
fn cloud_matches_mitsuba() {
    let c = check_against_reference("cloud", "cloud", &[], CHUNKS, SPP, 31);
    assert!(c.passed, "{c}");
}

#[test]
fn cloud_power_density_scale_5_percent_off() {
    // Twice the chunks (16 × 64 spp): at CHUNKS × 64 the image mean moves by 6.0–8.3 σ
    // (three seeds; limit 5.3), too near the limit in blue; at 16 × 64 by 8.8–11.1 σ.
    let c = check_against_reference("cloud", "cloud", &[("scale", "8.4")], 2 * CHUNKS, SPP, 32);
    assert!(!c.passed, "a 5% denser cloud passed: {c}");
}

#[test]
fn cloud_power_albedo_0_98() {
    let c = check_against_reference("cloud", "cloud", &[("albedo", "0.98")], CHUNKS, SPP, 33);
    assert!(!c.passed, "albedo 0.98 instead of 0.99 passed: {c}");
}

#[test]
fn cloud_power_g_negated() {
    let c = check_against_reference("cloud", "cloud", &[("g", "-0.6")], CHUNKS, SPP, 34);
    assert!(!c.passed, "g = -0.6 instead of 0.6 passed: {c}");
}

/// The render of the cloud with the albedo volume scaled by `factor`, and the gradient
/// with respect to that factor when asked.
fn render_cloud(factor: f32, gradient: Estimand) -> (Vec<[f32; 3]>, Option<Vec<[f32; 3]>>) {
    // Russian roulette off (rr_depth ≥ max_depth): renders at two factors follow the
    // same paths, as the tracking's decisions depend on σ_t only.
    let params = [("albedo", "0.9"), ("max_depth", "12"), ("rr_depth", "100")];
    let s = load_seeded(&root().join("mitsuba_scenes/cloud.xml"), &params, 8, 5);
    render_pixels(
        &s,
        RenderOptions {
            estimand: gradient,
            albedo: Some(vec![glam::Vec3::splat(factor)]),
            ..Default::default()
        },
    )
}

/// d(radiance)/d(factor on the albedo volume) at factor 1 against central differences
/// at 1 ± h with common random numbers. Each path's weight is c · f^k (k ≤ K − 1
/// vertices, K = max_depth 12), so the difference differs from the derivative by its
/// truncation, at most (K−1)(K−2)/6 · h² relative, plus float rounding.
#[test]
fn cloud_albedo_gradient_matches_finite_differences() {
    let worst = finite_difference_excess(Estimand::AlbedoDerivative(0));
    assert!(worst <= 1.0, "|FD − G| reaches {worst:.2}× the tolerance");
}

/// Power: a gradient that leaves out the vertex each emitter sample is made from fails
/// the same check.
#[test]
fn cloud_albedo_gradient_power_missing_nee_vertex() {
    let worst = finite_difference_excess(Estimand::AlbedoDerivativeIgnoringNeeVertex(0));
    assert!(
        worst > 1.0,
        "a wrong gradient passed (|FD − G| ≤ {worst:.2}× the tolerance)"
    );
}

/// The largest |FD − G| / tolerance over the film, for the gradient `gradient`.
fn finite_difference_excess(gradient: Estimand) -> f64 {
    let h = 0.01f32;
    let (plus, _) = render_cloud(1.0 + h, Estimand::RadianceOnly);
    let (minus, _) = render_cloud(1.0 - h, Estimand::RadianceOnly);
    let (_, grad) = render_cloud(1.0, gradient);
    let grad = grad.unwrap();
    let trunc = 11.0 * 10.0 / 6.0 * (h * h) as f64 * 1.01;
    let round = 1e-5 / (2.0 * h as f64);
    let (mut worst, mut nonzero) = (0.0f64, 0);
    for i in 0..grad.len() {
        for c in 0..3 {
            let fd = (plus[i][c] as f64 - minus[i][c] as f64) / (2.0 * h as f64);
            let g = grad[i][c] as f64;
            let tol = g.abs() * trunc + round * (plus[i][c].abs() + minus[i][c].abs()) as f64;
            worst = worst.max((fd - g).abs() / tol.max(1e-12));
            nonzero += (g > 0.0) as usize;
        }
    }
    // The cloud covers about a third of the film; the sky around it has no gradient.
    println!(
        "{gradient:?}: largest |FD − G| / tolerance {worst:.3}; {nonzero} of {} values non-zero",
        3 * grad.len()
    );
    assert!(
        nonzero * 5 > 3 * grad.len(),
        "the gradient image is (nearly) empty"
    );
    worst
}

/// A scene with a heterogeneous medium whose sigma_t is `vol` (written beside it as
/// `grid.vol`), or `sigma_t` given as the XML when `vol` is None; the load/build error.
fn error_for(tag: &str, vol: Option<&[u8]>, sigma_t: &str) -> String {
    let dir = tmp_dir("heterogeneous", tag);
    if let Some(bytes) = vol {
        std::fs::write(dir.join("grid.vol"), bytes).unwrap();
    }
    let text = format!(
        r#"<scene version="3.0.0">{}
    <medium type="heterogeneous" id="m">
        {sigma_t}
    </medium>
    <shape type="cube"><bsdf type="null"/><ref name="interior" id="m"/></shape>
</scene>"#,
        common::scene_text::SENSOR
    );
    let path = write(&dir, "scene.xml", &text);
    let loaded = mediareg::xml::load_file(&path, &common::options(&[])).map_err(|e| e.to_string());
    load_or_build_error(tag, loaded)
}

const GRID: &str = r#"<volume name="sigma_t" type="gridvolume"><string name="filename" value="grid.vol"/></volume>"#;

#[test]
fn bad_vol_files_are_refused_with_the_file_and_what_is_wrong() {
    let good = write_vol([2, 2, 2], 1, &[0.5; 8]);
    let mut cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("truncated", good[..good.len() - 3].to_vec(), "truncated"),
        (
            "not_vol",
            b"PNG\x03 not a volume".to_vec(),
            "does not start with \"VOL\"",
        ),
    ];
    let mut version = good.clone();
    version[3] = 2;
    cases.push(("version", version, "version 2"));
    let mut encoding = good.clone();
    encoding[4..8].copy_from_slice(&2i32.to_le_bytes());
    cases.push(("encoding", encoding, "encoding 2"));
    let mut huge = good.clone();
    for k in 0..3 {
        huge[8 + 4 * k..12 + 4 * k].copy_from_slice(&100_000i32.to_le_bytes());
    }
    cases.push(("huge", huge, "100000×100000×100000"));
    let mut channels = good.clone();
    channels[20..24].copy_from_slice(&6i32.to_le_bytes());
    cases.push(("channels", channels, "of 6 channels"));
    let header = good.len() - 32;
    let mut nan = good.clone();
    nan[header + 4..header + 8].copy_from_slice(&f32::NAN.to_le_bytes());
    cases.push(("nan", nan, "value #1 is NaN"));
    let mut negative = good.clone();
    negative[header..header + 4].copy_from_slice(&(-1.0f32).to_le_bytes());
    cases.push(("negative", negative, "value #0 is -1"));
    for (tag, bytes, needle) in cases {
        let e = error_for(tag, Some(&bytes), GRID);
        assert!(e.contains("grid.vol") && e.contains(needle), "{tag}: {e}");
        assert!(
            e.contains("scene.xml:"),
            "{tag}: the error names no file:line: {e}"
        );
    }
    let e = error_for("missing", None, GRID);
    assert!(e.contains("\"grid.vol\" not found"), "{e}");
}

#[test]
fn an_empty_medium_and_bad_volume_options_are_refused() {
    let zero = write_vol([2, 2, 2], 1, &[0.0; 8]);
    let e = error_for("zero", Some(&zero), GRID);
    assert!(
        e.contains("the medium is empty") && e.contains("scene.xml:"),
        "{e}"
    );
    let good = write_vol([2, 2, 2], 1, &[0.5; 8]);
    for (tag, xml, needle) in [
        (
            "filter",
            r#"<volume name="sigma_t" type="gridvolume"><string name="filename" value="grid.vol"/><string name="filter_type" value="cubic"/></volume>"#,
            "filter_type \"cubic\"",
        ),
        (
            "max_value",
            r#"<volume name="sigma_t" type="gridvolume"><string name="filename" value="grid.vol"/><float name="max_value" value="0.1"/></volume>"#,
            "below the grid's largest value",
        ),
        (
            "albedo_above_one",
            r#"<float name="albedo" value="1.5"/>"#,
            "albedo reaches 1.5",
        ),
    ] {
        let e = error_for(tag, Some(&good), xml);
        assert!(e.contains(needle), "{tag}: {e}");
    }
    // A constant text error: a negative sigma_t.
    let e = load_or_build_error(
        "negative_const",
        load_text(
            "heterogeneous",
            "negative_const",
            &format!(
                r#"<scene version="3.0.0">{}<medium type="heterogeneous"><float name="sigma_t" value="-1"/></medium></scene>"#,
                common::scene_text::SENSOR
            ),
            &[],
        ),
    );
    assert!(e.contains("must be finite and nonnegative"), "{e}");
}
