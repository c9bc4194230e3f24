//! Nothing lost: Ctrl-C (SIGINT) during a render writes the image of the passes
//! completed, with the spp reached in the EXR header, and exits with status 130; and the
//! same seed gives the same file across runs (processes).

mod common;

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::scene_text::tmp_dir;
use mediareg::image::{read_exr, read_exr_int_attribute};

fn mediareg() -> Command {
    Command::new(env!("CARGO_BIN_EXE_mediareg"))
}

/// Runs `mediareg render SCENE ARGS -o OUT` and asserts it succeeded.
fn render_ok(scene: &Path, args: &[&str], out: &Path) {
    let st = mediareg()
        .arg("render")
        .arg(scene)
        .args(args)
        .arg("-o")
        .arg(out)
        .output()
        .unwrap();
    assert!(
        st.status.success(),
        "{}",
        String::from_utf8_lossy(&st.stderr)
    );
}

fn cube() -> std::path::PathBuf {
    common::root().join("mitsuba_scenes/medium_cube.xml")
}

/// Files in `dir` other than the expected outputs (a leftover temporary file would be
/// one).
fn others(dir: &Path, expected: &[&str]) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| !expected.contains(&n.as_str()))
        .collect()
}

#[test]
fn sigint_writes_the_image_so_far_with_its_spp() {
    let dir = tmp_dir("interrupt", "sigint");
    let out = dir.join("cube.exr");
    let requested = 1_000_000;
    let mut child = mediareg()
        .arg("render")
        .arg(cube())
        .args(["-D", "res=48", "--seed", "5", "--no-png", "-t", "2"])
        .args(["--spp", &requested.to_string(), "-o"])
        .arg(&out)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Long enough for the first passes (1 and 1 spp: milliseconds), far from the end.
    std::thread::sleep(Duration::from_millis(1500));
    let status = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let start = Instant::now();
    let output = loop {
        if child.try_wait().unwrap().is_some() {
            break child.wait_with_output().unwrap();
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "mediareg did not stop within 60 s of SIGINT"
        );
        std::thread::sleep(Duration::from_millis(50));
    };
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(
        output.status.code(),
        Some(130),
        "exit status; stderr:\n{stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(stderr.contains("interrupted at"), "{stderr}");

    let spp = read_exr_int_attribute(&out, "spp")
        .unwrap()
        .expect("spp attribute");
    assert!(spp > 0 && spp < requested, "spp reached {spp}");
    assert!(
        others(&dir, &["cube.exr"]).is_empty(),
        "left behind: {:?}",
        others(&dir, &["cube.exr"])
    );

    // The image is that of `spp` samples per pixel: a render of exactly `spp` with the
    // same seed draws the same samples (each has its own random stream), summed in
    // other passes (so equal up to f32 rounding, not bit for bit).
    let partial = read_exr(&out).unwrap();
    assert!(partial
        .pixels
        .iter()
        .flatten()
        .all(|v| v.is_finite() && *v >= 0.0));
    let full_out = dir.join("full.exr");
    let spp_arg = spp.to_string();
    render_ok(
        &cube(),
        &["-D", "res=48", "--seed", "5", "--no-png", "--spp", &spp_arg],
        &full_out,
    );
    assert_eq!(read_exr_int_attribute(&full_out, "spp").unwrap(), Some(spp));
    let full = read_exr(&full_out).unwrap();
    let worst = common::largest_relative_difference(&partial.pixels, &full.pixels);
    assert!(
        worst < 1e-4,
        "the interrupted image is not the {spp}-spp image: relative difference {worst:e}"
    );
}

/// The same seed gives a bit-identical EXR in two runs of the program, at 1 and at 2
/// threads.
#[test]
fn same_seed_same_file_across_runs() {
    let dir = tmp_dir("interrupt", "runs");
    let mut files = Vec::new();
    for (run, threads) in [(0, "2"), (1, "2"), (2, "1")] {
        let out = dir.join(format!("run{run}.exr"));
        render_ok(
            &common::root().join("mitsuba_scenes/chromatic_sphere.xml"),
            &[
                "-D", "res=40", "--spp", "8", "--seed", "11", "--no-png", "-t", threads,
            ],
            &out,
        );
        files.push(std::fs::read(&out).unwrap());
    }
    assert!(files[0] == files[1], "two runs at 2 threads differ");
    assert!(files[0] == files[2], "1 and 2 threads differ");
}
