//! A mesh of a million triangles or more cast without Embree (it does not load) says in
//! one line what Embree would save and how to install it; one just below that size, or
//! one cast without Embree because `MEDIAREG_ACCEL=obvhs` asked for it, does not. The
//! mesh is a flat grid written here as a binary PLY (24 MB, in a temporary folder).

mod common;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

use common::scene_text::{tmp_dir, write};

/// A binary PLY of an n × n grid of quads (2 (n − 1)² triangles) in [−1, 1]², z = 0.
fn grid_ply(dir: &Path, n: usize) -> PathBuf {
    let path = dir.join(format!("grid{n}.ply"));
    let quads = (n - 1) * (n - 1);
    let mut out = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
    write!(
        out,
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\n\
         property float y\nproperty float z\nelement face {}\n\
         property list uchar int vertex_indices\nend_header\n",
        n * n,
        2 * quads
    )
    .unwrap();
    let step = 2.0 / (n - 1) as f32;
    for j in 0..n {
        for i in 0..n {
            for v in [i as f32 * step - 1.0, j as f32 * step - 1.0, 0.0] {
                out.write_all(&v.to_le_bytes()).unwrap();
            }
        }
    }
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let a = (j * n + i) as i32;
            for tri in [
                [a, a + 1, a + n as i32 + 1],
                [a, a + n as i32 + 1, a + n as i32],
            ] {
                out.write_all(&[3u8]).unwrap();
                for k in tri {
                    out.write_all(&k.to_le_bytes()).unwrap();
                }
            }
        }
    }
    out.flush().unwrap();
    path
}

/// stderr of a 1-spp render of the grid of side `n` with the environment `env` (the
/// caster's variables set by nothing else: the test command sets MEDIAREG_ACCEL).
fn render(n: usize, env: &[(&str, &str)]) -> String {
    let dir = tmp_dir("large_mesh", &format!("grid{n}"));
    let ply = grid_ply(&dir, n);
    let scene = write(
        &dir,
        "scene.xml",
        &format!(
            r#"<scene version="3.0.0">
    <integrator type="path"/>
    <sensor type="perspective">
        <transform name="to_world"><lookat origin="0, 0, 3" target="0, 0, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="1"/></sampler>
        <film type="hdrfilm"><integer name="width" value="16"/><integer name="height" value="16"/></film>
    </sensor>
    <shape type="ply"><string name="filename" value="{}"/></shape>
    <emitter type="constant"/>
</scene>"#,
            ply.display()
        ),
    );
    let out = Command::new(env!("CARGO_BIN_EXE_mediareg"))
        .args(["render", scene.to_str().unwrap(), "--no-png", "-o"])
        .arg(dir.join("out.exr"))
        .env_remove("MEDIAREG_ACCEL")
        .env_remove("MEDIAREG_EMBREE")
        .envs(env.iter().copied())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{stderr}");
    stderr
}

const HINT: &str = "triangles are cast with the built-in BVH";

#[test]
fn a_large_mesh_without_embree_says_what_embree_would_save() {
    let missing = [("MEDIAREG_EMBREE", "/nonexistent/libembree3.so.3")];
    // 2 · 708² = 1,002,528 triangles.
    let large = render(709, &missing);
    let lines: Vec<&str> = large.lines().filter(|l| l.contains(HINT)).collect();
    assert_eq!(lines.len(), 1, "{large}");
    assert!(
        lines[0].contains("1.0M") && lines[0].contains("apt-get install libembree3-3"),
        "{}",
        lines[0]
    );
    // 2 · 706² = 996,872: below the size.
    let below = render(707, &missing);
    assert!(!below.contains(HINT), "{below}");
    // Asked for the built-in BVH: no hint.
    let asked = render(709, &[missing[0], ("MEDIAREG_ACCEL", "obvhs")]);
    assert!(!asked.contains(HINT), "{asked}");
}
