//! Bad input through the real command line: each file in tests/bad_input/ must give a
//! clear error naming the problem and where it is, a non-zero exit code, no panic and no
//! output file.

use std::path::PathBuf;
use std::process::Command;

fn run_bad(file: &str, extra: &[&str]) -> (i32, String) {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/bad_input");
    let out = std::env::temp_dir().join(format!("mediareg_bad_{}_{file}.exr", std::process::id()));
    let output = Command::new(env!("CARGO_BIN_EXE_mediareg"))
        .arg("render")
        .arg(dir.join(file))
        .arg("-o")
        .arg(&out)
        .args(extra)
        .output()
        .expect("run mediareg");
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(
        !stderr.contains("panicked"),
        "{file}: mediareg panicked:\n{stderr}"
    );
    assert!(
        !out.exists(),
        "{file}: an output file was written despite the error"
    );
    (output.status.code().unwrap_or(-1), stderr)
}

/// Asserts a failing exit, and that stderr names `file:line` and each of `needles`.
fn expect_error(file: &str, line: u32, needles: &[&str]) {
    let (code, stderr) = run_bad(file, &[]);
    assert_ne!(code, 0, "{file}: expected failure, got success");
    let loc = format!("{file}:{line}:");
    assert!(
        stderr.contains(&loc),
        "{file}: message does not name {loc}:\n{stderr}"
    );
    for n in needles {
        assert!(
            stderr.contains(n),
            "{file}: message does not mention {n:?}:\n{stderr}"
        );
    }
}

#[test]
fn malformed_xml() {
    expect_error("malformed.xml", 8, &["malformed XML"]);
}

#[test]
fn unclosed_tag() {
    expect_error("unclosed_tag.xml", 8, &["malformed XML", "</shape>"]);
}

#[test]
fn missing_mesh_file() {
    expect_error(
        "missing_mesh.xml",
        7,
        &["no_such_mesh.ply", "not found", "-a DIR"],
    );
}

#[test]
fn unknown_plugin() {
    expect_error("unknown_plugin.xml", 6, &["teapot", "ply, obj, sphere"]);
}

#[test]
fn misspelled_property() {
    expect_error(
        "misspelled_property.xml",
        7,
        &["unreferenced property \"raduis\"", "radius"],
    );
}

#[test]
fn wrong_property_type() {
    expect_error(
        "wrong_property_type.xml",
        7,
        &["radius", "<float>", "<string>"],
    );
}

#[test]
fn nan_sigma_t() {
    expect_error("nan_sigma_t.xml", 7, &["NaN", "not a finite number"]);
}

#[test]
fn negative_sigma_t() {
    expect_error("negative_sigma_t.xml", 7, &["sigma_t", "nonnegative"]);
}

/// Mitsuba 3 renders chromatic extinction with has_spectral_extinction = false by a
/// biased estimator; mediareg refuses rather than render something else silently.
#[test]
fn chromatic_sigma_t_without_spectral_extinction() {
    expect_error(
        "chromatic_no_spectral_extinction.xml",
        8,
        &["has_spectral_extinction", "chromatic"],
    );
}

/// Mitsuba 3 refuses an <rgb> sigma_t above 1 (it reads <rgb> there as a reflectance).
#[test]
fn rgb_sigma_t_above_one() {
    expect_error("rgb_sigma_t_above_one.xml", 7, &["sigma_t", "scale"]);
}

#[test]
fn truncated_ply() {
    expect_error("truncated_ply.xml", 6, &["truncated.ply", "PLY"]);
}

#[test]
fn obj_with_out_of_range_indices() {
    expect_error(
        "obj_bad_indices.xml",
        6,
        &["bad_indices.obj", "out of bounds"],
    );
}

#[test]
fn undefined_parameter() {
    expect_error("undefined_parameter.xml", 7, &["$size", "-D size="]);
}

#[test]
fn unused_define_is_an_error() {
    let (code, stderr) = run_bad("undefined_parameter.xml", &["-D", "size=1", "-D", "sise=2"]);
    assert_ne!(code, 0);
    assert!(stderr.contains("\"sise\""), "{stderr}");
}

#[test]
fn film_too_large_for_memory_is_refused_up_front() {
    expect_error("huge_film.xml", 1, &["32768 x 32768", "GiB", "limit"]);
}

#[test]
fn output_folder_missing() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("mitsuba_scenes/cbox.xml");
    let output = Command::new(env!("CARGO_BIN_EXE_mediareg"))
        .args([
            "render",
            dir.to_str().unwrap(),
            "--spp",
            "1",
            "-o",
            "/nonexistent_mediareg_dir/out.exr",
        ])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success());
    assert!(
        stderr.contains("/nonexistent_mediareg_dir") && stderr.contains("does not exist"),
        "{stderr}"
    );
}
