//! `mediareg optimize` and `mediareg backward` from the command line, on
//! mitsuba_scenes/grid_adjoint.xml: the optimizer brings a uniform start towards a
//! target rendered from the scene's grid, the files written are volumes of the grid's
//! shape (read back by mediareg's own .vol reader), and what reverse mode cannot do is
//! refused with a message saying what to do.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::root;
use mediareg::medium::grid::parse_vol;

fn mediareg() -> Command {
    Command::new(env!("CARGO_BIN_EXE_mediareg"))
}

fn tmp(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("mediareg_optimize_{tag}_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn run_ok(cmd: &mut Command) -> String {
    let out = cmd.output().unwrap();
    let text = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(out.status.success(), "{cmd:?} failed: {text}");
    text
}

/// `mediareg backward SCENE --adjoint A -o PREFIX`, which must fail: its message.
fn backward_refused(scene: &Path, adjoint: &Path, prefix: &Path) -> String {
    let out = mediareg()
        .arg("backward")
        .arg(scene)
        .arg("--adjoint")
        .arg(adjoint)
        .arg("-o")
        .arg(prefix)
        .output()
        .unwrap();
    assert!(
        !out.status.success(),
        "backward on {} succeeded",
        scene.display()
    );
    String::from_utf8_lossy(&out.stderr).to_string()
}

fn scene() -> PathBuf {
    root().join("mitsuba_scenes/grid_adjoint.xml")
}

fn read_grid(path: &Path) -> mediareg::medium::grid::GridData {
    parse_vol(&std::fs::read(path).unwrap()).unwrap_or_else(|e| panic!("{}: {e:?}", path.display()))
}

/// From a uniform 8³ grid, 40 Adam steps at 16 spp (one stage, with its own rate) bring the loss of the grid's own
/// target image (256 spp) to under a third of the first iteration's (the mean of the
/// last five iterations), and the written volume has the scene grid's shape and lies in
/// the range asked for; the JSON has every iteration.
#[test]
fn optimize_fits_a_grid_to_its_image() {
    let dir = tmp("fit");
    let target = dir.join("target.exr");
    run_ok(
        mediareg()
            .arg("render")
            .arg(scene())
            .args(["--spp", "256", "--seed", "7", "--no-png", "-o"])
            .arg(&target),
    );
    let out = dir.join("fit.vol");
    run_ok(
        mediareg()
            .arg("optimize")
            .arg(scene())
            .arg("--target")
            .arg(&target)
            .args([
                "--params",
                "sigma_t",
                "--init",
                "0.3",
                "--stage",
                "40:-:16:0.05",
            ])
            .args(["--range", "0,1.2", "-o"])
            .arg(&out),
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.with_extension("json")).unwrap())
            .unwrap();
    let losses: Vec<f64> = report["iterations"]
        .as_array()
        .unwrap()
        .iter()
        .map(|i| i["loss"].as_f64().unwrap())
        .collect();
    assert_eq!(losses.len(), 40);
    let last: f64 = losses[35..].iter().sum::<f64>() / 5.0;
    assert!(last < losses[0] / 3.0, "loss {} → {last}", losses[0]);
    let g = read_grid(&out);
    assert_eq!((g.res, g.channels), ([8, 8, 8], 1));
    assert!(g.data.iter().all(|v| (0.0..=1.2).contains(v)));
}

/// `mediareg backward` writes PREFIX_sigma_t.vol and PREFIX_albedo.vol shaped as the
/// grids; a homogeneous medium and an adjoint of the wrong size are refused with what
/// to do instead.
#[test]
fn backward_writes_volumes_and_refuses_what_it_cannot_do() {
    let dir = tmp("cli");
    let prefix = dir.join("g");
    let adjoint = root().join("mitsuba_scenes/grid_adjoint_A.exr");
    run_ok(
        mediareg()
            .arg("backward")
            .arg(scene())
            .arg("--adjoint")
            .arg(&adjoint)
            .args(["--params", "sigma_t,albedo", "--spp", "4", "-o"])
            .arg(&prefix),
    );
    for name in ["sigma_t", "albedo"] {
        // A gradient is signed, which a volume may not be: its header and size read raw.
        let bytes = std::fs::read(dir.join(format!("g_{name}.vol"))).unwrap();
        let int = |at: usize| i32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
        assert_eq!(&bytes[..3], b"VOL");
        assert_eq!([int(8), int(12), int(16), int(20)], [8, 8, 8, 1], "{name}");
        let values = (bytes.len() - mediareg::medium::grid::VOL_HEADER_BYTES) / 4;
        assert_eq!(values, 512, "{name}");
    }
    let cube = root().join("mitsuba_scenes/medium_cube.xml");
    let err = backward_refused(&cube, &adjoint, &prefix);
    assert!(err.contains("render --gradient"), "{err}");
    let small = dir.join("small.exr");
    run_ok(
        mediareg()
            .arg("render")
            .arg(&cube)
            .args(["--spp", "1", "--no-png", "-o"])
            .arg(&small),
    );
    let err = backward_refused(&scene(), &small, &prefix);
    assert!(err.contains("the adjoint image is"), "{err}");
}
