//! A fuzz harness without nightly: proptest mutates real inputs (every scene of
//! mitsuba_scenes/ and tests/bad_input/, and small PLY/OBJ meshes, ASCII and binary) by
//! deleting, duplicating and inserting bytes, splicing in XML fragments and extreme
//! numbers, and truncating. Each mutant is loaded and built, and rendered when it is
//! small; the property is that nothing panics and every render is finite and ≥ 0.
//!
//! A refused mutant must be refused with a message that names the file and the line.
//!
//! CI runs `MEDIAREG_FUZZ_CASES` cases per target (default 2000) from a fixed seed
//! (`MEDIAREG_FUZZ_SEED`, printed with any failure); more on demand:
//! `MEDIAREG_FUZZ_CASES=20000 cargo test --release --test fuzz`.

mod common;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use mediareg::geometry::mesh::read_obj;
use mediareg::geometry::ply::read_ply;
use mediareg::load::build_scene;
use mediareg::BuildOverrides;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, TestCaseError, TestRng, TestRunner};

use common::scene_text::{tmp_dir, write};

/// Byte-level edits, applied in order (positions are taken modulo the current length).
#[derive(Clone, Debug)]
enum Edit {
    Delete { at: usize, len: usize },
    Duplicate { at: usize, len: usize },
    Insert { at: usize, bytes: Vec<u8> },
    Splice { at: usize, fragment: usize },
    Number { at: usize, number: usize },
    Truncate { at: usize },
}

/// What mutated scenes tend to need to reach deep code: tags, references, includes,
/// parameters.
const FRAGMENTS: &[&str] = &[
    "<",
    ">",
    "\"",
    "/>",
    "</shape>",
    "</scene>",
    "<scene version=\"3.0.0\">",
    "<shape type=\"ply\"><string name=\"filename\" value=\"tri.ply\"/></shape>",
    "<shape type=\"obj\"><string name=\"filename\" value=\"tri.obj\"/></shape>",
    "<include filename=\"scene.xml\"/>",
    "<ref id=\"m\"/>",
    "<medium type=\"homogeneous\" id=\"m\"><float name=\"sigma_t\" value=\"1\"/></medium>",
    "<bsdf type=\"null\"/>",
    "<emitter type=\"constant\"/>",
    "<transform name=\"to_world\"><scale value=\"0\"/></transform>",
    "<default name=\"x\" value=\"1\"/>",
    "$x",
    "&amp;",
    "&#0;",
    "<!--",
    "-->",
    "<![CDATA[",
    "\u{0}",
    "é",
];

const NUMBERS: &[&str] = &[
    "0",
    "-1",
    "1e309",
    "-1e309",
    "nan",
    "inf",
    "1e-45",
    "4294967296",
    "18446744073709551616",
    "-0",
    "0x10",
    "1,2",
    "",
];

fn edit() -> impl Strategy<Value = Edit> {
    let at = any::<usize>();
    prop_oneof![
        (at, 1usize..64).prop_map(|(at, len)| Edit::Delete { at, len }),
        (at, 1usize..64).prop_map(|(at, len)| Edit::Duplicate { at, len }),
        (at, proptest::collection::vec(any::<u8>(), 1..8))
            .prop_map(|(at, bytes)| Edit::Insert { at, bytes }),
        (at, 0..FRAGMENTS.len()).prop_map(|(at, fragment)| Edit::Splice { at, fragment }),
        (at, 0..NUMBERS.len()).prop_map(|(at, number)| Edit::Number { at, number }),
        at.prop_map(|at| Edit::Truncate { at }),
    ]
}

/// Applies the edits. `Number` replaces the run of number characters at or after `at`.
fn mutate(mut data: Vec<u8>, edits: &[Edit]) -> Vec<u8> {
    for e in edits {
        let n = data.len().max(1);
        match e {
            Edit::Delete { at, len } => {
                let a = at % n;
                let b = (a + len).min(data.len());
                data.drain(a.min(data.len())..b);
            }
            Edit::Duplicate { at, len } => {
                let a = (at % n).min(data.len());
                let b = (a + len).min(data.len());
                let piece = data[a..b].to_vec();
                data.splice(b..b, piece);
            }
            Edit::Insert { at, bytes } => {
                let a = (at % n).min(data.len());
                data.splice(a..a, bytes.iter().copied());
            }
            Edit::Splice { at, fragment } => {
                let a = (at % n).min(data.len());
                data.splice(a..a, FRAGMENTS[*fragment].bytes());
            }
            Edit::Number { at, number } => {
                let from = (at % n).min(data.len());
                let is_num = |b: &u8| b.is_ascii_digit() || *b == b'.' || *b == b'-';
                if let Some(s) = data[from..].iter().position(is_num).map(|p| p + from) {
                    let e = data[s..]
                        .iter()
                        .position(|b| !is_num(b))
                        .map_or(data.len(), |p| p + s);
                    data.splice(s..e, NUMBERS[*number].bytes());
                }
            }
            Edit::Truncate { at } => data.truncate(at % n),
        }
    }
    data
}

fn cases() -> u32 {
    std::env::var("MEDIAREG_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(2000)
}

/// The fuzzing seed: `MEDIAREG_FUZZ_SEED` (a number), else a fixed one, so a CI failure
/// replays with the same mutants. Failures print it.
fn seed() -> u64 {
    std::env::var("MEDIAREG_FUZZ_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(20261125)
}

fn runner() -> TestRunner {
    let mut key = [0u8; 32];
    key[..8].copy_from_slice(&seed().to_le_bytes());
    let config = Config {
        cases: cases(),
        failure_persistence: None,
        ..Config::default()
    };
    TestRunner::new_with_rng(config, TestRng::from_seed(RngAlgorithm::ChaCha, &key))
}

/// Runs `test` on the cases of `strategy` with the fixed seed; a failure names the seed
/// and the case count to replay it with.
fn run<S: Strategy>(strategy: &S, test: impl Fn(S::Value) -> Result<(), TestCaseError>) {
    runner().run(strategy, test).unwrap_or_else(|e| {
        panic!(
            "{e}\nreplay: MEDIAREG_FUZZ_SEED={} MEDIAREG_FUZZ_CASES={} cargo test --release --test fuzz",
            seed(),
            cases()
        )
    })
}

fn files_in(dir: &str, ext: &str) -> Vec<(String, Vec<u8>)> {
    let dir = common::root().join(dir);
    let mut v: Vec<(String, Vec<u8>)> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == ext))
        .map(|p| {
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                std::fs::read(&p).unwrap(),
            )
        })
        .collect();
    v.sort();
    v
}

const TRI_PLY_ASCII: &str = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
const TRI_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n";

fn tri_ply_binary() -> Vec<u8> {
    let mut b = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n".to_vec();
    for v in [[0f32, 0., 0.], [1., 0., 0.], [0., 1., 0.]] {
        for x in v.into_iter().chain([0., 0., 1.]) {
            b.extend(x.to_le_bytes());
        }
    }
    b.push(3);
    for i in 0i32..3 {
        b.extend(i.to_le_bytes());
    }
    b
}

/// How far mutants got: loaded, built, rendered.
static REACHED: [AtomicUsize; 3] = [
    AtomicUsize::new(0),
    AtomicUsize::new(0),
    AtomicUsize::new(0),
];

/// A refusal must say where: a file and a line in it. The one exception is a file-wide
/// error about another file (a mesh or an image), which has no line to name.
fn names_file_and_line(e: &mediareg::error::SceneError, scene: &Path) -> bool {
    e.loc
        .as_ref()
        .is_some_and(|l| l.line > 0 || l.file.as_path() != scene)
}

/// Loads, builds and (when small) renders a scene file; panics and refusals that do not
/// say where are the failures.
fn exercise_scene(path: &Path) -> Result<(), TestCaseError> {
    let desc = match mediareg::xml::load_file(path, &common::options_in(&[], vec![])) {
        Ok(d) => d,
        Err(e) => {
            prop_assert!(
                names_file_and_line(&e, path),
                "refused without file:line: {e}"
            );
            return Ok(());
        }
    };
    REACHED[0].fetch_add(1, Ordering::Relaxed);
    let scene = match build_scene(
        &desc,
        &BuildOverrides {
            spp: Some(1),
            seed: Some(1),
            crop: None,
            ..Default::default()
        },
    ) {
        Ok(s) => s,
        Err(e) => {
            prop_assert!(
                names_file_and_line(&e, path),
                "refused without file:line: {e}"
            );
            return Ok(());
        }
    };
    REACHED[1].fetch_add(1, Ordering::Relaxed);
    let (w, h) = scene.shot.film.crop_size;
    if w * h <= 32 * 32
        && mediareg::scene::cost::long_render_warning(&scene, &scene.shot, 1).is_none()
    {
        REACHED[2].fetch_add(1, Ordering::Relaxed);
        let img = mediareg::integrator::render(&scene, &scene.shot, &Default::default()).image;
        prop_assert!(
            img.pixels
                .iter()
                .flatten()
                .all(|v| v.is_finite() && *v >= 0.0),
            "a pixel is negative or not finite"
        );
    }
    Ok(())
}

#[test]
fn fuzz_scene_files() {
    let mut seeds = files_in("mitsuba_scenes", "xml");
    seeds.extend(files_in("tests/bad_input", "xml"));
    // Small films so that mutants which still load can be rendered.
    for (_, text) in seeds.iter_mut() {
        let s = String::from_utf8_lossy(text)
            .replace("value=\"$res\"", "value=\"8\"")
            .replace("value=\"$spp\"", "value=\"1\"");
        *text = s.into_bytes();
    }
    let dir = tmp_dir("fuzz", "scenes");
    write(&dir, "tri.ply", TRI_PLY_ASCII);
    write(&dir, "tri.obj", TRI_OBJ);
    let path: PathBuf = dir.join("scene.xml");
    let strategy = (0..seeds.len(), proptest::collection::vec(edit(), 1..4));
    run(&strategy, |(i, edits)| {
        let data = mutate(seeds[i].1.clone(), &edits);
        std::fs::write(&path, &data).unwrap();
        exercise_scene(&path)
    });
    let [l, b, r] = REACHED.each_ref().map(|a| a.load(Ordering::Relaxed));
    println!("{} mutants: {l} loaded, {b} built, {r} rendered", cases());
    // The harness reaches the builder and the integrator, not only the XML parser.
    assert!(b > 0 && r > 0, "no mutant got past the loader");
}

#[test]
fn fuzz_mesh_files() {
    let mut seeds: Vec<(String, Vec<u8>)> = vec![
        ("ply".into(), TRI_PLY_ASCII.as_bytes().to_vec()),
        ("ply".into(), tri_ply_binary()),
        ("obj".into(), TRI_OBJ.as_bytes().to_vec()),
    ];
    for ext in ["ply", "obj"] {
        seeds.extend(
            files_in("tests/bad_input", ext)
                .into_iter()
                .map(|(_, d)| (ext.to_string(), d)),
        );
    }
    let dir = tmp_dir("fuzz", "meshes");
    let strategy = (0..seeds.len(), proptest::collection::vec(edit(), 1..4));
    run(&strategy, |(i, edits)| {
        let (ext, data) = &seeds[i];
        let path = dir.join(format!("mesh.{ext}"));
        std::fs::write(&path, mutate(data.clone(), &edits)).unwrap();
        let r = if ext == "ply" {
            read_ply(&path)
        } else {
            read_obj(&path)
        };
        // A panic inside ply-rs or tobj is caught and reported as an error; count it
        // as a failure all the same (the message would be vaguer than it can be).
        if let Err(e) = r {
            prop_assert!(
                !e.to_string().contains("reader failed"),
                "a mesh reader panicked: {e}"
            );
        }
        Ok(())
    });
}
