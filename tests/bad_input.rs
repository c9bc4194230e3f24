//! Bad input through the real command line: each file in tests/bad_input/ must give a
//! clear error naming the problem and where it is, a non-zero exit code, no panic and no
//! output file.

use std::path::PathBuf;
use std::process::Command;

fn run_bad(file: &str, extra: &[&str]) -> (i32, String) {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/bad_input");
    run_bad_path(&dir.join(file), extra)
}

/// `run_bad` for a scene file anywhere (one a test generates).
fn run_bad_path(scene: &std::path::Path, extra: &[&str]) -> (i32, String) {
    let file = scene.file_name().unwrap().to_string_lossy();
    let out = std::env::temp_dir().join(format!("mediareg_bad_{}_{file}.exr", std::process::id()));
    let output = Command::new(env!("CARGO_BIN_EXE_mediareg"))
        .arg("render")
        .arg(scene)
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
    expect_error(
        "unknown_plugin.xml",
        6,
        &["teapot", "ply, obj, serialized, sphere"],
    );
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

#[test]
fn cyclic_include() {
    // The cycle is found where it closes: in the included file, naming the includer.
    let (code, stderr) = run_bad("cyclic_include_a.xml", &[]);
    assert_ne!(code, 0);
    for n in [
        "cyclic_include_b.xml:2:",
        "cyclic include",
        "cyclic_include_a.xml",
    ] {
        assert!(stderr.contains(n), "no {n:?} in:\n{stderr}");
    }
}

/// A generated file of 200,000 nested shapes (5.8 MB; Mitsuba 3 itself overflows its
/// stack on it) is refused where the nesting passes the bound, not with a crash.
#[test]
fn deeply_nested_elements() {
    let dir = tempdir("deep");
    let scene = dir.join("deep.xml");
    let depth = 200_000;
    let mut text = String::from("<scene version=\"3.0.0\">\n");
    text.push_str(&"<shape type=\"sphere\">\n".repeat(depth));
    text.push_str(&"</shape>\n".repeat(depth));
    text.push_str("</scene>\n");
    std::fs::write(&scene, text).unwrap();
    let (code, stderr) = run_bad_path(&scene, &[]);
    assert_eq!(code, 1, "{stderr}");
    // The root is line 1; the 64th nested shape opens on line 65.
    let limit = mediareg::xml::element::MAX_DEPTH;
    for n in [
        format!("deep.xml:{}:", limit + 1),
        "nested more than".into(),
    ] {
        assert!(stderr.contains(&n), "no {n:?} in:\n{stderr}");
    }
}

/// A chain of includes, each file including the next, is bounded like nesting.
#[test]
fn long_include_chain() {
    let dir = tempdir("chain");
    let n = 40;
    for i in 0..n {
        let body = if i + 1 < n {
            format!("<include filename=\"chain{}.xml\"/>", i + 1)
        } else {
            String::new()
        };
        std::fs::write(
            dir.join(format!("chain{i}.xml")),
            format!("<scene version=\"3.0.0\">\n{body}\n</scene>\n"),
        )
        .unwrap();
    }
    let (code, stderr) = run_bad_path(&dir.join("chain0.xml"), &[]);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("includes are nested more than"), "{stderr}");
    assert!(stderr.contains(".xml:2:"), "no file:line in:\n{stderr}");
}

fn tempdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("mediareg_bad_{}_{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn include_of_a_missing_file() {
    expect_error(
        "include_missing.xml",
        6,
        &["no_such_include.xml", "not found", "-a DIR"],
    );
}

#[test]
fn fov_zero_and_180() {
    expect_error("fov_0.xml", 2, &["fov = 0", "(0, 180)"]);
    expect_error("fov_180.xml", 2, &["fov = 180", "(0, 180)"]);
}

#[test]
fn zero_and_negative_film_size() {
    expect_error("zero_size_film.xml", 4, &["0 x 8", "[1, 32768]"]);
    expect_error("negative_film.xml", 4, &["-64 x 8", "[1, 32768]"]);
}

#[test]
fn a_billion_samples_per_pixel() {
    expect_error("spp_1e9.xml", 4, &["sample_count = 1000000000", "16777216"]);
}

#[test]
fn shape_nested_in_a_bsdf() {
    expect_error("wrong_nesting.xml", 7, &["shape", "bsdf \"diffuse\""]);
}

#[test]
fn ply_face_index_beyond_the_vertex_count() {
    expect_error(
        "mesh_wrong_count.xml",
        6,
        &["wrong_count.ply", "vertex 7", "4 vertices"],
    );
}

#[test]
fn ply_ascii_data_under_a_binary_header_and_the_reverse() {
    for (xml, ply) in [
        ("mesh_ascii_as_binary.xml", "ascii_as_binary.ply"),
        ("mesh_binary_as_ascii.xml", "binary_as_ascii.ply"),
    ] {
        expect_error(xml, 6, &[ply, "cannot parse PLY", "ascii vs binary"]);
    }
}

#[test]
fn empty_obj() {
    expect_error("mesh_empty.xml", 6, &["empty.obj", "no faces"]);
}

/// A PLY with more data than its header declares renders as Mitsuba does (the
/// declared elements only), with a warning that names the file.
#[test]
fn ply_with_data_past_its_declared_counts_warns() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/bad_input");
    let out = std::env::temp_dir().join(format!("mediareg_extra_face_{}.exr", std::process::id()));
    let output = Command::new(env!("CARGO_BIN_EXE_mediareg"))
        .arg("render")
        .arg(dir.join("mesh_extra_face.xml"))
        .args(["--spp", "1", "--no-png", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert!(
        stderr.contains("warning")
            && stderr.contains("extra_face.ply")
            && stderr.contains("1 faces"),
        "{stderr}"
    );
    let _ = std::fs::remove_file(&out);
}

/// An output that cannot be written fails before rendering, not after.
#[test]
fn unwritable_output_fails_before_rendering() {
    let scene = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("mitsuba_scenes/cbox.xml");
    // /proc refuses new files even to root (permissions would not stop root).
    let output = Command::new(env!("CARGO_BIN_EXE_mediareg"))
        .arg("render")
        .arg(&scene)
        .args(["--spp", "1", "-o", "/proc/mediareg_out.exr"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(!output.status.success());
    assert!(
        stderr.contains("cannot write the output /proc/mediareg_out.exr"),
        "{stderr}"
    );
    assert!(!stdout.contains("rendered"), "it rendered first:\n{stdout}");
    assert!(!stderr.contains("panicked"), "{stderr}");
}

/// Found by tests/fuzz.rs: ply-rs panicked on a header count that overflows u64.
#[test]
fn ply_count_beyond_u64() {
    expect_error(
        "mesh_huge_count.xml",
        6,
        &["huge_count.ply", "header line 3", "below 2^32"],
    );
}

/// Found by tests/fuzz.rs: a sphere of radius 1e19 made the BVH builder panic.
#[test]
fn shape_too_large_for_single_precision() {
    expect_error("huge_sphere.xml", 6, &["1e19", "within ±1e12", "to_world"]);
}

#[test]
fn spot_beam_wider_than_its_cutoff() {
    expect_error(
        "spot_beam_wider_than_cutoff.xml",
        6,
        &[
            "cutoff_angle 10",
            "beam_width 20",
            "beam_width <= cutoff_angle",
        ],
    );
}

#[test]
fn corrupt_serialized_mesh() {
    expect_error(
        "serialized_corrupt.xml",
        6,
        &["corrupt.serialized", "truncated or corrupt", "re-export"],
    );
}

/// A sampled spectrum must list wavelengths in increasing order…
#[test]
fn spectrum_wavelengths_out_of_order() {
    expect_error(
        "spectrum_decreasing.xml",
        8,
        &["sampled spectrum", "500 follows 600"],
    );
}

/// …and nonnegative values.
#[test]
fn spectrum_negative_value() {
    expect_error(
        "spectrum_negative.xml",
        7,
        &["sampled spectrum", "700:-2", ">= 0"],
    );
}

/// Anisotropic roughness on a cube is refused (its orientation follows ∂p/∂u, from
/// texture coordinates mediareg's cube lacks), naming the shape.
#[test]
fn anisotropic_roughness_on_a_cube_refused() {
    expect_error(
        "anisotropic_roughness.xml",
        6,
        &[
            "anisotropic roughness",
            "\"cube\"",
            "meshes, rectangles, disks and spheres",
        ],
    );
}

#[test]
fn unknown_microfacet_distribution() {
    expect_error(
        "unknown_distribution.xml",
        7,
        &["distribution \"phong\"", "beckmann", "ggx"],
    );
}

#[test]
fn negative_roughness() {
    expect_error(
        "negative_alpha.xml",
        8,
        &["\"alpha\" = -0.2", "out of range"],
    );
}

#[test]
fn bitmap_file_missing() {
    expect_error(
        "bitmap_missing.xml",
        9,
        &["no_such_texture.png", "not found", "-a DIR"],
    );
}

/// A reflectance texture with values above 1 (an HDR sky) is refused.
#[test]
fn bitmap_reflectance_above_one() {
    expect_error("bitmap_above_one.xml", 9, &["sky.exr", "outside [0, 1]"]);
}

/// A wrong output is told before the scene loads (a large mesh loads for seconds): the
/// output error, not the load's, for a scene whose mesh is not found without `-a`.
#[test]
fn output_checked_before_the_load() {
    let scene = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("mitsuba_scenes/lucy.xml");
    let run = |out: &str| {
        let output = Command::new(env!("CARGO_BIN_EXE_mediareg"))
            .args(["render", scene.to_str().unwrap(), "--spp", "1", "-o", out])
            .output()
            .unwrap();
        assert!(!output.status.success());
        String::from_utf8_lossy(&output.stderr).into_owned()
    };
    let wrong = run("/tmp/mediareg_out.png");
    assert!(
        wrong.contains("must end in .exr") && !wrong.contains("not found"),
        "{wrong}"
    );
    // Power: with a good output the load's error is the one told.
    let good = std::env::temp_dir().join("mediareg_output_checked.exr");
    let load = run(good.to_str().unwrap());
    assert!(load.contains("not found"), "{load}");
}
