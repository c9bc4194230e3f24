//! Shared helpers for the integration tests: mesh search path, rendering independent
//! chunks, and loading committed Mitsuba 3 references.
#![allow(dead_code)]

pub mod scene_text;

use std::path::{Path, PathBuf};

use mediareg::image::stats::{compare, Comparison, Estimate, PixelLayout};
use mediareg::scene::Scene;
use mediareg::xml::LoadOptions;
use mediareg::BuildOverrides;

pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Where the Stanford meshes are found: $MEDIAREG_MESHES, the cache that
/// scripts/fetch_meshes fills, then ../shared/meshes.
pub fn mesh_dirs() -> Vec<PathBuf> {
    let mut dirs = Vec::new();
    if let Ok(d) = std::env::var("MEDIAREG_MESHES") {
        dirs.push(PathBuf::from(d));
    }
    dirs.push(root().join(".cache/meshes"));
    dirs.push(root().join("../shared/meshes"));
    dirs.into_iter().filter(|d| d.is_dir()).collect()
}

pub fn options(params: &[(&str, &str)]) -> LoadOptions {
    options_in(params, mesh_dirs())
}

/// Load options with `params` (`-D name=value`) and a search path.
pub fn options_in(params: &[(&str, &str)], search_dirs: Vec<PathBuf>) -> LoadOptions {
    LoadOptions {
        params: params
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect(),
        search_dirs,
        ..Default::default()
    }
}

/// Loads `scene` with `params` at `spp` samples and `seed`.
pub fn load_seeded(scene: &Path, params: &[(&str, &str)], spp: u32, seed: u64) -> Scene {
    load_seeded_crop(scene, params, spp, seed, None)
}

/// One render of `s` at its own shot with `opts` (progress bar off): the image's pixels,
/// and the gradient's when `opts` asks for one.
pub fn render_pixels(
    s: &Scene,
    opts: mediareg::integrator::RenderOptions,
) -> (Vec<[f32; 3]>, Option<Vec<[f32; 3]>>) {
    let opts = mediareg::integrator::RenderOptions {
        show_progress: false,
        ..opts
    };
    let r = mediareg::integrator::render(s, &s.shot, &opts);
    (r.image.pixels, r.gradient.map(|g| g.pixels))
}

/// `load_seeded` with a crop window `[x, y, w, h]` of the film (`--crop`).
pub fn load_seeded_crop(
    scene: &Path,
    params: &[(&str, &str)],
    spp: u32,
    seed: u64,
    crop: Option<[usize; 4]>,
) -> Scene {
    mediareg::load_scene(
        scene,
        &options(params),
        &BuildOverrides {
            spp: Some(spp),
            seed: Some(seed),
            crop,
            ..Default::default()
        },
    )
    .unwrap_or_else(|e| panic!("{e}"))
}

/// Renders `k` independent images (seeds base_seed..base_seed+k) of `spp` samples each.
pub fn render_chunks(
    scene: &Path,
    params: &[(&str, &str)],
    k: usize,
    spp: u32,
    base_seed: u64,
) -> Vec<Vec<[f32; 3]>> {
    render_chunks_crop(scene, params, k, spp, base_seed, None)
}

/// `render_chunks` of a crop window of the film.
pub fn render_chunks_crop(
    scene: &Path,
    params: &[(&str, &str)],
    k: usize,
    spp: u32,
    base_seed: u64,
    crop: Option<[usize; 4]>,
) -> Vec<Vec<[f32; 3]>> {
    (0..k)
        .map(|i| {
            let s = load_seeded_crop(scene, params, spp, base_seed + i as u64, crop);
            mediareg::integrator::render(&s, &s.shot, &Default::default())
                .image
                .pixels
        })
        .collect()
}

/// Renders `k` independent gradient images (seeds base_seed..): the derivative image of
/// `gradient` from each render.
pub fn render_gradient_chunks(
    scene: &Path,
    params: &[(&str, &str)],
    k: usize,
    spp: u32,
    base_seed: u64,
    estimand: mediareg::integrator::volpath::Estimand,
) -> Vec<Vec<[f32; 3]>> {
    (0..k)
        .map(|i| {
            let s = load_seeded(scene, params, spp, base_seed + i as u64);
            let opts = mediareg::integrator::RenderOptions {
                show_progress: false,
                estimand,
                ..Default::default()
            };
            mediareg::integrator::render(&s, &s.shot, &opts)
                .gradient
                .expect("a gradient was asked for")
                .pixels
        })
        .collect()
}

pub struct Reference {
    pub estimate: Estimate,
    /// The crop window the reference covers, if it is one (`--crop`).
    pub crop: Option<[usize; 4]>,
    /// The width of its image (the window's, for a window).
    pub width: usize,
}

impl Reference {
    /// The window `[x, y, w, h]` of a full-film reference.
    pub fn window(&self, [x, y, w, h]: [usize; 4]) -> Reference {
        assert!(self.crop.is_none(), "the reference is a window already");
        let width = self.width;
        let pick = |v: &[[f64; 3]]| {
            (y..y + h)
                .flat_map(|row| (x..x + w).map(move |col| row * width + col))
                .map(|i| v[i])
                .collect::<Vec<_>>()
        };
        Reference {
            estimate: Estimate::from_moments(
                pick(&self.estimate.mean),
                pick(&self.estimate.var_mean),
                self.estimate.dof,
            ),
            crop: Some([x, y, w, h]),
            width: w,
        }
    }

    /// Mean squared error of `img` against the reference over pixels and channels, with
    /// the reference's own variance of the mean subtracted (an unbiased estimate of the
    /// error against the true image).
    pub fn mse(&self, img: &[[f32; 3]]) -> f64 {
        let n = (img.len() * 3) as f64;
        img.iter()
            .zip(&self.estimate.mean)
            .zip(&self.estimate.var_mean)
            .map(|((a, b), v)| {
                (0..3)
                    .map(|c| (a[c] as f64 - b[c]).powi(2) - v[c])
                    .sum::<f64>()
            })
            .sum::<f64>()
            / n
    }
}

/// Loads reference/NAME.{exr,_var.exr,json} and fails if the scene or any asset no
/// longer hashes to what the reference was made from (the check `mediareg table` makes,
/// with the parameters the reference records).
pub fn reference(name: &str, scene: &Path) -> Reference {
    let dir = root().join("reference");
    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join(format!("{name}.json"))).expect("reference json"),
    )
    .expect("valid json");
    let params: Vec<(String, String)> = json["params"]
        .as_object()
        .map(|m| {
            m.iter()
                .map(|(k, v)| (k.clone(), v.as_str().unwrap_or_default().to_string()))
                .collect()
        })
        .unwrap_or_default();
    let opts = LoadOptions {
        params,
        search_dirs: mesh_dirs(),
        ..Default::default()
    };
    let desc = mediareg::xml::load_file(scene, &opts).unwrap_or_else(|e| panic!("{e}"));
    let r = mediareg::report::table::Reference::load(&dir, name, scene, &opts, &desc)
        .unwrap_or_else(|e| panic!("{e:#}"));
    let to64 = |v: &[[f32; 3]]| v.iter().map(|p| p.map(|c| c as f64)).collect::<Vec<_>>();
    Reference {
        estimate: Estimate::from_moments(
            to64(&r.mean.pixels),
            to64(&r.var.pixels),
            r.meta.chunks as f64 - 1.0,
        ),
        crop: r.meta.crop,
        width: r.mean.width,
    }
}

/// reference/NAME.exr and NAME_var.exr (the mean and the variance of the mean), checked
/// against the sha256 their JSON records, for tests that take the images alone.
pub fn reference_images(name: &str) -> (mediareg::image::Image, mediareg::image::Image) {
    let (mean, var, _) =
        mediareg::report::reference::read_reference_images(&root().join("reference"), name)
            .unwrap_or_else(|e| panic!("{e:#}"));
    (mean, var)
}

/// Per-value outlier level and whole-test false-alarm probability of the comparisons.
pub const ALPHA: f64 = 1e-3;
pub const FALSE_ALARM: f64 = 1e-6;

/// The scene's image width and reconstruction filter: how its pixels depend on each
/// other, which `compare` needs.
pub fn layout(scene: &Path, params: &[(&str, &str)]) -> PixelLayout {
    layout_crop(scene, params, None)
}

/// `layout` of a crop window.
pub fn layout_crop(scene: &Path, params: &[(&str, &str)], crop: Option<[usize; 4]>) -> PixelLayout {
    let overrides = BuildOverrides {
        crop,
        ..Default::default()
    };
    let s =
        mediareg::load_scene(scene, &options(params), &overrides).unwrap_or_else(|e| panic!("{e}"));
    PixelLayout {
        width: s.shot.film.crop_size.0,
        filter_radius: s.shot.film.rfilter.radius(),
    }
}

/// Renders mitsuba_scenes/`scene`.xml as `chunks` independent images of `spp` samples
/// and compares their mean with the committed reference `name`.
pub fn check_against_reference(
    name: &str,
    scene: &str,
    params: &[(&str, &str)],
    chunks: usize,
    spp: u32,
    seed: u64,
) -> Comparison {
    let scene = root().join("mitsuba_scenes").join(format!("{scene}.xml"));
    check_file_against_reference(name, &scene, params, chunks, spp, seed)
}

/// `check_against_reference` for a scene file anywhere (e.g. in ../shared/corpus).
pub fn check_file_against_reference(
    name: &str,
    scene: &Path,
    params: &[(&str, &str)],
    chunks: usize,
    spp: u32,
    seed: u64,
) -> Comparison {
    let r = reference(name, scene);
    compare_render(name, &r, scene, params, r.crop, chunks, spp, seed)
}

/// Renders `scene` as `chunks` independent images of `spp` samples (of the film's
/// window `crop`) and compares their mean with `reference` (of the same window).
#[allow(clippy::too_many_arguments)]
fn compare_render(
    name: &str,
    reference: &Reference,
    scene: &Path,
    params: &[(&str, &str)],
    crop: Option<[usize; 4]>,
    chunks: usize,
    spp: u32,
    seed: u64,
) -> Comparison {
    let layout = layout_crop(scene, params, crop);
    let ours = Estimate::from_chunks(
        &render_chunks_crop(scene, params, chunks, spp, seed, crop),
        layout,
    );
    let c = compare(&ours, &reference.estimate, layout, ALPHA, FALSE_ALARM);
    println!("{name} {params:?}: {c}");
    c
}

/// Compares a window `[x, y, w, h]` of mitsuba_scenes/`scene`.xml with the same window of
/// its full-film reference `name` (box filter: the crop is that window of a full
/// render), so that a large reference costs a small render.
pub fn check_window_against_reference(
    name: &str,
    scene: &str,
    params: &[(&str, &str)],
    window: [usize; 4],
    chunks: usize,
    spp: u32,
    seed: u64,
) -> Comparison {
    let scene = root().join("mitsuba_scenes").join(format!("{scene}.xml"));
    let r = reference(name, &scene).window(window);
    compare_render(name, &r, &scene, params, Some(window), chunks, spp, seed)
}

/// Power checks on files without a parameter to turn: `scene` (with `params`) with each `(from, to)`
/// text replaced (each must occur), rendered from a copy and compared with the
/// reference of the unedited file. The copy lives in a mirror of `tree` (a folder above
/// the scene; everything in it but the scene's own path linked), so relative `<path>`s,
/// includes and assets resolve as for the original.
#[allow(clippy::too_many_arguments)]
pub fn check_edited_against_reference(
    name: &str,
    scene: &Path,
    tree: &Path,
    params: &[(&str, &str)],
    edits: &[(&str, &str)],
    window: Option<[usize; 4]>,
    chunks: usize,
    spp: u32,
    seed: u64,
) -> Comparison {
    let mut r = reference(name, scene);
    let crop = match window {
        Some(w) => {
            r = r.window(w);
            Some(w)
        }
        None => r.crop,
    };
    let mut text = std::fs::read_to_string(scene).expect("scene text");
    for (from, to) in edits {
        assert!(
            text.contains(from),
            "{}: no {from:?} to edit",
            scene.display()
        );
        text = text.replacen(from, to, 1);
    }
    let rel = scene
        .strip_prefix(tree)
        .expect("the scene lies in the tree");
    let mirror = scene_text::tmp_dir("edited", &format!("{name}_{seed}"));
    let edited = mirror_tree(tree, rel, &mirror, &text);
    compare_render(name, &r, &edited, params, crop, chunks, spp, seed)
}

/// Mirrors `tree` into `out`: along `rel`'s folders real folders whose other entries
/// are links to the originals, and at `rel` the file `text`. Returns its path.
fn mirror_tree(tree: &Path, rel: &Path, out: &Path, text: &str) -> PathBuf {
    let (mut src, mut dst) = (tree.to_path_buf(), out.to_path_buf());
    let parts: Vec<_> = rel.components().collect();
    for (i, part) in parts.iter().enumerate() {
        std::fs::create_dir_all(&dst).unwrap();
        for entry in std::fs::read_dir(&src).unwrap().flatten() {
            let link = dst.join(entry.file_name());
            if entry.file_name() != part.as_os_str() && !link.exists() {
                std::os::unix::fs::symlink(entry.path(), &link).unwrap();
            }
        }
        src = src.join(part);
        dst = dst.join(part);
        if i + 1 == parts.len() {
            std::fs::write(&dst, text).unwrap();
        }
    }
    dst
}

/// The environment variable `name` parsed, else `default` (the ignored measurements'
/// knobs).
pub fn env_or<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// The baselines a regularized frame is held to: a plain render of `scene` at `spp` with
/// its own seed (`seed + 1000`, apart from the method's draws) and that render through
/// OIDN, as `render --denoise oidn` makes it (seen emission kept out and added back).
pub fn plain_and_oidn(
    scene: &Scene,
    spp: u32,
    seed: u64,
) -> (mediareg::image::Image, mediareg::image::Image) {
    plain_and_oidn_at(scene, &scene.shot.with(spp, seed + 1000))
}

/// Plain volpath and `render --denoise oidn` of `shot` itself.
pub fn plain_and_oidn_at(
    scene: &Scene,
    shot: &mediareg::scene::shot::Shot,
) -> (mediareg::image::Image, mediareg::image::Image) {
    use mediareg::integrator::{self, denoised, RenderOptions};
    let r = integrator::render(
        scene,
        shot,
        &RenderOptions {
            seen_emission: true,
            ..Default::default()
        },
    );
    let d = denoised::oidn(scene, shot, &r, mediareg::denoise::AuxUse::None, None).unwrap();
    (r.image, d)
}

/// The largest relative difference between two images' values, each over the larger of
/// the two (at least 1e-3, so that near-black pixels do not dominate).
pub fn largest_relative_difference(a: &[[f32; 3]], b: &[[f32; 3]]) -> f32 {
    a.iter()
        .flatten()
        .zip(b.iter().flatten())
        .map(|(x, y)| (x - y).abs() / x.abs().max(y.abs()).max(1e-3))
        .fold(0.0f32, f32::max)
}

/// Whether OIDN loads, for tests whose assertions cover the OIDN baselines. The test
/// command fetches it (`scripts/fetch_oidn`), so a missing library is a broken set-up:
/// it fails here, naming the fix, unless `MEDIAREG_NO_OIDN=1` asks on purpose for the
/// run without it (then the caller checks what remains, and says so).
pub fn oidn_present() -> bool {
    match mediareg::denoise::oidn::load() {
        Ok(_) => true,
        Err(e) => {
            assert!(
                std::env::var_os("MEDIAREG_NO_OIDN").is_some(),
                "OIDN does not load ({e}); run scripts/fetch_oidn (scripts/test does), or set \
                 MEDIAREG_NO_OIDN=1 to run without the OIDN baselines on purpose"
            );
            eprintln!("MEDIAREG_NO_OIDN is set: the OIDN baselines' assertions are left out");
            false
        }
    }
}

/// The sha256 of a file's bytes, in hex (as the fixtures' JSON records it).
pub fn sha256_hex(path: &Path) -> String {
    use sha2::{Digest, Sha256};
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    Sha256::digest(&bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}
