//! Same seed → bit-identical image, whatever the thread count; another seed → another image.

mod common;

use common::{options, root};
use mediareg::BuildOverrides;

fn render_with_threads(threads: usize, seed: u64) -> Vec<[f32; 3]> {
    render_scene_with_threads("dielectric_sphere", threads, seed)
}

fn render_scene_with_threads(name: &str, threads: usize, seed: u64) -> Vec<[f32; 3]> {
    render_window(name, threads, seed, None)
}

/// Renders mitsuba_scenes/NAME.xml at 48² and 16 spp, or the crop window `crop` of it.
fn render_window(name: &str, threads: usize, seed: u64, crop: Option<[usize; 4]>) -> Vec<[f32; 3]> {
    let scene = mediareg::load_scene(
        &root().join(format!("mitsuba_scenes/{name}.xml")),
        &options(&[("res", "48")]),
        &BuildOverrides {
            spp: Some(16),
            seed: Some(seed),
            crop,
            ..Default::default()
        },
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        mediareg::integrator::render(&scene, &scene.shot, &Default::default())
            .image
            .pixels
    })
}

#[test]
fn same_seed_is_bit_identical_across_thread_counts() {
    let one = render_with_threads(1, 7);
    let two = render_with_threads(2, 7);
    let again = render_with_threads(2, 7);
    let bits = |v: &[[f32; 3]]| {
        v.iter()
            .flat_map(|p| p.map(f32::to_bits))
            .collect::<Vec<_>>()
    };
    assert_eq!(bits(&one), bits(&two), "1 vs 2 threads differ");
    assert_eq!(bits(&two), bits(&again), "two runs differ");
    let other = render_with_threads(2, 8);
    assert_ne!(
        bits(&one),
        bits(&other),
        "a different seed gave the same image"
    );
}

/// volpath too (media, chromatic MIS, Russian roulette): 1 and 2 threads agree bit for bit.
#[test]
fn volpath_same_seed_is_bit_identical_across_thread_counts() {
    for name in ["chromatic_sphere", "camera_in_medium"] {
        let one = render_scene_with_threads(name, 1, 3);
        let two = render_scene_with_threads(name, 2, 3);
        assert!(
            one.iter()
                .zip(&two)
                .all(|(a, b)| a.map(f32::to_bits) == b.map(f32::to_bits)),
            "{name}: 1 vs 2 threads differ"
        );
    }
}

/// A crop window (`--crop`) renders the same pixels as the full film (each pixel's
/// random numbers depend on its place in the full film), with a box filter bit for bit.
#[test]
fn crop_window_is_the_same_window_of_the_full_render() {
    let full = render_window("medium_cube", 2, 5, None);
    let [x, y, w, h] = [10, 7, 20, 16];
    let crop = render_window("medium_cube", 2, 5, Some([x, y, w, h]));
    assert_eq!(crop.len(), w * h);
    for r in 0..h {
        for c in 0..w {
            assert_eq!(
                crop[r * w + c].map(f32::to_bits),
                full[(y + r) * 48 + x + c].map(f32::to_bits),
                "pixel ({}, {})",
                x + c,
                y + r
            );
        }
    }
}
