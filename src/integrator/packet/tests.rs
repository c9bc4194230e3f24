//! The packet kernel against its reference, the scalar `volpath`: the same expectation
//! on every ray (radiance, the albedo derivative and the albedo difference), a power
//! test beside it, and the scenes it takes or refuses.

use super::test_scenes::*;
use super::*;
use crate::integrator::volpath::{self, Differentiated, Estimand, PathSettings};

/// The images a sample holds: radiance, d_albedo (the albedo's derivative or the
/// difference), and the derivatives in the extinction and in g.
const IMAGES: usize = 4;

fn image(s: &PathSample, q: usize) -> Vec3 {
    [s.radiance, s.d_albedo, s.d_sigma, s.d_g][q]
}

/// Mean and variance of the mean of `n` samples, per channel of each image.
struct Moments {
    mean: [Vec3; IMAGES],
    var_of_mean: [Vec3; IMAGES],
}

fn moments(samples: &[PathSample]) -> Moments {
    let n = samples.len() as f64;
    let mut out = Moments {
        mean: [Vec3::ZERO; IMAGES],
        var_of_mean: [Vec3::ZERO; IMAGES],
    };
    for q in 0..IMAGES {
        for c in 0..3 {
            let v = |s: &PathSample| image(s, q)[c] as f64;
            let m = samples.iter().map(v).sum::<f64>() / n;
            let var = samples.iter().map(|s| (v(s) - m).powi(2)).sum::<f64>() / (n - 1.0);
            out.mean[q][c] = m as f32;
            out.var_of_mean[q][c] = (var / n) as f32;
        }
    }
    out
}

const N: usize = 40_000;

/// Sample `k`'s direction: `d`, or moved by up to `jitter` in each axis (alike on both
/// sides). A grid's extinction derivative takes its point on a segment from a hash of
/// the segment (`HeterogeneousMedium::depth_estimate`): along one fixed ray every
/// sample's segments hash alike, and the two sides' differ in their last bits.
fn direction(d: Vec3A, jitter: f32, k: u64) -> Vec3A {
    if jitter == 0.0 {
        return d;
    }
    let mut rng = Pcg32::new(0x6a17, k);
    let mut u = || (2.0 * rng.next_1d() - 1.0) * jitter;
    (d + Vec3A::new(u(), u(), u())).normalize()
}

/// `n` scalar samples along `d` (jittered by up to `jitter`: [`direction`]).
fn scalar_samples(
    scene: &Scene,
    settings: &PathSettings,
    (d, jitter): (Vec3A, f32),
    seed: u64,
    n: usize,
) -> Vec<PathSample> {
    (0..n as u64)
        .map(|k| {
            let mut rng = Pcg32::new(seed, k);
            let d = direction(d, jitter, k);
            volpath::sample(scene, settings, Vec3A::ZERO, d, f32::INFINITY, &mut rng)
        })
        .collect()
}

/// `n` packet samples along `d` (jittered: [`direction`]), [`WIDTH`] lanes at a time.
pub(super) fn packet_samples(
    scene: &Scene,
    ps: &PacketScene,
    settings: &PathSettings,
    ray: (Vec3A, f32),
    seed: u64,
    n: usize,
) -> Vec<PathSample> {
    match settings.estimand.has_derivatives() {
        true => packet_samples_in::<true>(scene, ps, settings, ray, seed, n),
        false => packet_samples_in::<false>(scene, ps, settings, ray, seed, n),
    }
}

/// [`packet_samples`] in the instance with derivative weights (`D`) or without.
pub(super) fn packet_samples_in<const D: bool>(
    scene: &Scene,
    ps: &PacketScene,
    settings: &PathSettings,
    (d, jitter): (Vec3A, f32),
    seed: u64,
    n: usize,
) -> Vec<PathSample> {
    let mut out = vec![PathSample::default(); n];
    for (j, chunk) in out.chunks_mut(WIDTH).enumerate() {
        let rays: Vec<_> = (0..chunk.len())
            .map(|k| {
                let d = direction(d, jitter, (j * WIDTH + k) as u64);
                (Vec3A::ZERO, d, f32::INFINITY)
            })
            .collect();
        let mut rngs: Vec<Pcg32> = (0..chunk.len())
            .map(|k| Pcg32::new(seed, (j * WIDTH + k) as u64))
            .collect();
        sample_packet_in::<D>(scene, ps, settings, &rays, &mut rngs, chunk);
    }
    out
}

/// Largest |z| of the packet's means against the scalar ones, over the rays, the
/// images and the channels (z from the variances of both means).
fn largest_z(
    scene: &Scene,
    rays: &[Vec3A],
    gradient: Estimand,
    packet_albedo: Option<Vec<Vec3>>,
    seed: u64,
) -> f32 {
    largest_z_against(scene, scene, rays, gradient, packet_albedo, seed)
}

/// [`largest_z`] with the packet rendering `packet_scene` (an edited copy, for power).
fn largest_z_against(
    scene: &Scene,
    packet_scene: &Scene,
    rays: &[Vec3A],
    gradient: Estimand,
    packet_albedo: Option<Vec<Vec3>>,
    seed: u64,
) -> f32 {
    largest_z_over(
        scene,
        packet_scene,
        rays,
        (gradient, packet_albedo, 0.0),
        seed,
        N,
    )
}

/// [`largest_z_against`] over `n` samples a ray, each jittered by up to `jitter`
/// ([`direction`]).
fn largest_z_over(
    scene: &Scene,
    packet_scene: &Scene,
    rays: &[Vec3A],
    (estimand, packet_albedo, jitter): (Estimand, Option<Vec<Vec3>>, f32),
    seed: u64,
    n: usize,
) -> f32 {
    let albedo: Vec<Vec3> = scene.media.iter().map(|m| m.albedo).collect();
    let settings = PathSettings {
        albedo: &albedo,
        estimand,
    };
    let ps = PacketScene::new(packet_scene).expect("the packet takes the scene");
    let packet_albedo = packet_albedo.unwrap_or_else(|| albedo.clone());
    let packet_settings = PathSettings {
        albedo: &packet_albedo,
        estimand,
    };
    let mut worst = 0f32;
    for &d in rays {
        let a = moments(&scalar_samples(scene, &settings, (d, jitter), seed, n));
        let b = moments(&packet_samples(
            packet_scene,
            &ps,
            &packet_settings,
            (d, jitter),
            seed + 1,
            n,
        ));
        for q in 0..IMAGES {
            for c in 0..3 {
                let var = a.var_of_mean[q][c] + b.var_of_mean[q][c];
                let diff = a.mean[q][c] - b.mean[q][c];
                if var > 0.0 {
                    worst = worst.max(diff.abs() / var.sqrt());
                } else if diff != 0.0 {
                    // Noiseless on both sides (the light seen directly) and different.
                    worst = f32::INFINITY;
                }
            }
        }
    }
    worst
}

/// |z| above which a difference counts: 6 rays × 4 images × 3 channels = 72 tests
/// per comparison; at 4.5 a Gaussian false alarm has probability 72 · 6.8e-6 = 4.9e-4.
const Z_LIMIT: f32 = 4.5;

/// The derivatives in a medium's extinction, albedo and g, all three.
const ALL_PARAMS: Differentiated = Differentiated::ALL;

/// The packet's radiance and each derivative (the albedo's, the difference, and the
/// extinction's, the albedo's and g's together) equal the scalar integrator's in
/// expectation, ray by ray.
#[test]
fn packets_equal_scalar_paths_in_expectation() {
    let two = load_xml("two_spheres", TWO_SPHERES);
    let lit = load_xml("lit_spheres", &lit_spheres());
    let boxed = load_xml("box_area_light", &box_and_area_light());
    let fog = load_xml("fog", FOG);
    let glass = load_xml("glass", &glass_and_area_light());
    let cloud = cloud("cloud", 0.7);
    let gradients = [
        Estimand::RadianceOnly,
        Estimand::AlbedoDerivative(0),
        Estimand::AlbedoDerivative(1),
        Estimand::AlbedoDifference {
            medium: 1,
            target: Vec3::new(0.95, 0.9, 0.8),
        },
        Estimand::MediumDerivatives {
            medium: 0,
            params: ALL_PARAMS,
        },
        Estimand::MediumDerivatives {
            medium: 1,
            params: ALL_PARAMS,
        },
    ];
    for (i, g) in gradients.into_iter().enumerate() {
        let scenes = [
            ("two spheres", &two, rays()),
            ("lit", &lit, lit_rays()),
            ("box", &boxed, box_rays()),
            ("fog", &fog, fog_rays()),
            ("glass", &glass, box_rays()),
            ("cloud", &cloud, cloud_rays()),
        ];
        for (name, scene, rays) in scenes {
            // The cloud's one medium is medium 0.
            let g = match g {
                Estimand::AlbedoDerivative(m) => {
                    Estimand::AlbedoDerivative(m.min(scene.media.len() as u32 - 1))
                }
                Estimand::AlbedoDifference { medium, target } => Estimand::AlbedoDifference {
                    medium: medium.min(scene.media.len() as u32 - 1),
                    target,
                },
                Estimand::MediumDerivatives { medium, params } => Estimand::MediumDerivatives {
                    medium: medium.min(scene.media.len() as u32 - 1),
                    params,
                },
                g => g,
            };
            // The cloud's rays jittered: its extinction's derivative ([`direction`]).
            let jitter = if name == "cloud" { 2e-3 } else { 0.0 };
            let seed = 100 + 10 * i as u64;
            let z = largest_z_over(scene, scene, &rays, (g, None, jitter), seed, N);
            println!("{name}, {g:?}: largest |z| {z:.2}");
            assert!(z < Z_LIMIT, "{name}, {g:?}: |z| = {z} ≥ {Z_LIMIT}");
        }
    }
}

/// Power: the same comparison catches a packet that renders the grey medium's albedo
/// 2% low (0.8 → 0.784), and the chromatic one's green channel 2% low.
#[test]
fn the_comparison_detects_an_albedo_two_percent_off() {
    let two = load_xml("two_spheres_power", TWO_SPHERES);
    let lit = load_xml("lit_spheres_power", &lit_spheres());
    for (name, scene, rays) in [("two spheres", &two, rays()), ("lit", &lit, lit_rays())] {
        let albedo: Vec<Vec3> = scene.media.iter().map(|m| m.albedo).collect();
        for (m, scale) in [(0, Vec3::splat(0.98)), (1, Vec3::new(1.0, 0.98, 1.0))] {
            let mut off = albedo.clone();
            off[m] *= scale;
            let z = largest_z(
                scene,
                &rays,
                Estimand::RadianceOnly,
                Some(off),
                300 + m as u64,
            );
            println!("{name}, medium {m} off by 2%: largest |z| {z:.2}");
            assert!(
                z >= Z_LIMIT,
                "{name}: medium {m}'s albedo 2% off went undetected: |z| = {z}"
            );
        }
    }
}

/// Power in the heterogeneous medium: the packet's cloud with its albedo 2% low, or
/// its density 5% high (delta and ratio tracking against a different volume), must be
/// caught.
#[test]
fn the_comparison_detects_a_cloud_two_percent_darker_or_five_percent_denser() {
    let scene = cloud("cloud_power", 0.7);
    let albedo: Vec<Vec3> = scene.media.iter().map(|m| m.albedo).collect();
    let darker = albedo.iter().map(|a| *a * 0.98).collect();
    let z = largest_z(
        &scene,
        &cloud_rays(),
        Estimand::RadianceOnly,
        Some(darker),
        800,
    );
    println!("cloud 2% darker: largest |z| {z:.2}");
    assert!(
        z >= Z_LIMIT,
        "the cloud 2% darker went undetected: |z| = {z}"
    );
    let denser = cloud("cloud_denser", 0.735);
    let z = largest_z_against(
        &scene,
        &denser,
        &cloud_rays(),
        Estimand::RadianceOnly,
        None,
        810,
    );
    println!("cloud 5% denser: largest |z| {z:.2}");
    assert!(
        z >= Z_LIMIT,
        "the cloud 5% denser went undetected: |z| = {z}"
    );
}

/// Power on the emitter samples: a point light 5% brighter, or a directional light 5%
/// brighter, in the packet's copy of the lit scene, must be caught (the floor and the
/// ball see them mostly by emitter sampling).
#[test]
fn the_comparison_detects_a_light_five_percent_off() {
    let lit = load_xml("lit_spheres_lights", &lit_spheres());
    for (name, from, to) in [
        (
            "point",
            r#"<rgb name="intensity" value="5, 5, 5"/>"#,
            r#"<rgb name="intensity" value="5.25, 5.25, 5.25"/>"#,
        ),
        (
            "directional",
            r#"<rgb name="irradiance" value="1.5, 1.5, 1.5"/>"#,
            r#"<rgb name="irradiance" value="1.575, 1.575, 1.575"/>"#,
        ),
    ] {
        let off = load_xml(
            &format!("lit_spheres_{name}_off"),
            &lit_spheres().replace(from, to),
        );
        let z = largest_z_against(&lit, &off, &lit_rays(), Estimand::RadianceOnly, None, 500);
        println!("{name} light 5% brighter: largest |z| {z:.2}");
        assert!(
            z >= Z_LIMIT,
            "the {name} light 5% off went undetected: |z| = {z}"
        );
    }
}

/// Power on the area lights: 5% brighter in the packet's copy of the box scene (a
/// rectangle) or of the fog (a sphere, sampled by its cone) must be caught by the rays
/// that see it lit (not the one that sees it directly, whose noiseless value would
/// catch it alone). Over 4N samples a ray: at N the expected |z| sat near the limit
/// (4.4–5.2 by seed), so a seed could miss it; at 4N it is twice that.
#[test]
fn the_comparison_detects_an_area_light_five_percent_off() {
    let boxed = load_xml("box_area_light_power", &box_and_area_light());
    let off = box_and_area_light().replace(
        r#"<rgb name="radiance" value="6, 5, 4"/>"#,
        r#"<rgb name="radiance" value="6.3, 5.25, 4.2"/>"#,
    );
    let off = load_xml("box_area_light_off", &off);
    let rays = box_rays();
    let lit_by_it = &rays[..rays.len() - 1];
    let z = largest_z_over(
        &boxed,
        &off,
        lit_by_it,
        (Estimand::RadianceOnly, None, 0.0),
        600,
        4 * N,
    );
    println!("rectangle light 5% brighter: largest |z| {z:.2}");
    assert!(
        z >= Z_LIMIT,
        "the rectangle light 5% off went undetected: |z| = {z}"
    );

    let fog = load_xml("fog_power", FOG);
    let off = FOG.replace(
        r#"<rgb name="radiance" value="20, 18, 15"/>"#,
        r#"<rgb name="radiance" value="21, 18.9, 15.75"/>"#,
    );
    let off = load_xml("fog_off", &off);
    let mut lit_by_it = fog_rays();
    lit_by_it.remove(2);
    let z = largest_z_over(
        &fog,
        &off,
        &lit_by_it,
        (Estimand::RadianceOnly, None, 0.0),
        650,
        4 * N,
    );
    println!("sphere light 5% brighter: largest |z| {z:.2}");
    assert!(
        z >= Z_LIMIT,
        "the sphere light 5% off went undetected: |z| = {z}"
    );
}

/// Power on the dielectric: the packet's copy of the glass scene that transmits 5%
/// less must be caught (an index 1.45 for 1.5 was not, |z| 1.47: on these rays a
/// different index mostly moves light around).
#[test]
fn the_comparison_detects_a_glass_transmitting_five_percent_less() {
    let glass = load_xml("glass_power", &glass_and_area_light());
    let off = glass_and_area_light().replace(
        r#"<float name="int_ior" value="1.5"/>"#,
        r#"<float name="int_ior" value="1.5"/><rgb name="specular_transmittance" value="0.95, 0.95, 0.95"/>"#,
    );
    let off = load_xml("glass_off", &off);
    let z = largest_z_against(&glass, &off, &box_rays(), Estimand::RadianceOnly, None, 700);
    println!("glass transmitting 5% less: largest |z| {z:.2}");
    assert!(
        z >= Z_LIMIT,
        "the glass's transmittance off went undetected: |z| = {z}"
    );
}

/// The false-alarm rate of [`Z_LIMIT`], measured: scalar against scalar over many
/// seeds, the largest |z| of each comparison. Gaussian tails would put 4.5 beyond
/// every one of them; a heavier tail (the roulette's 1/q) would show here.
#[test]
fn the_z_limit_holds_for_scalar_against_scalar() {
    let scene = load_xml("lit_spheres_alarm", &lit_spheres());
    let albedo: Vec<Vec3> = scene.media.iter().map(|m| m.albedo).collect();
    let settings = PathSettings {
        albedo: &albedo,
        estimand: Estimand::AlbedoDerivative(1),
    };
    let mut alarms = 0;
    let trials = 8;
    for t in 0..trials {
        let mut worst = 0f32;
        for d in lit_rays() {
            let a = moments(&scalar_samples(
                &scene,
                &settings,
                (d, 0.0),
                1000 + 2 * t,
                N,
            ));
            let b = moments(&scalar_samples(
                &scene,
                &settings,
                (d, 0.0),
                1001 + 2 * t,
                N,
            ));
            for q in 0..IMAGES {
                for c in 0..3 {
                    let var = a.var_of_mean[q][c] + b.var_of_mean[q][c];
                    if var > 0.0 {
                        worst = worst.max((a.mean[q][c] - b.mean[q][c]).abs() / var.sqrt());
                    }
                }
            }
        }
        println!("trial {t}: largest |z| {worst:.2}");
        alarms += (worst >= Z_LIMIT) as u32;
    }
    assert_eq!(
        alarms, 0,
        "{alarms} of {trials} same-estimator comparisons alarmed"
    );
}

/// The white furnace in packets: a medium that does not absorb, under a sky of 1, gives
/// back 1 in expectation; every path is valid (it meets the sphere) and non-negative.
#[test]
fn a_white_furnace_gives_back_the_sky() {
    let scene = load_xml(
        "furnace",
        &std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/mitsuba_scenes/furnace.xml"
        ))
        .unwrap()
        .replace("$sigma_t", "2")
        .replace("$g", "0.6")
        .replace("$spp", "4")
        .replace("$res", "4"),
    );
    let ps = PacketScene::new(&scene).expect("the furnace is a packet scene");
    let settings = PathSettings {
        albedo: &[Vec3::ONE],
        estimand: Estimand::RadianceOnly,
    };
    let d = Vec3A::new(0.05, -0.1, -1.0).normalize();
    let samples = packet_samples(&scene, &ps, &settings, (d, 0.0), 7, N);
    let m = moments(&samples);
    let z = ((m.mean[0] - Vec3::ONE).abs() / m.var_of_mean[0].max(Vec3::splat(1e-30)).powf(0.5))
        .max_element();
    assert!(z < Z_LIMIT, "furnace mean {} (|z| {z})", m.mean[0]);
    assert!(samples
        .iter()
        .all(|s| s.radiance.min_element() >= 0.0 && s.valid));
}

/// Scenes the packet refuses, each for its reason, and the one it takes.
#[test]
fn the_packet_takes_media_spheres_diffuse_shapes_and_delta_lights_only() {
    let scene = load_xml("takes", TWO_SPHERES);
    assert!(PacketScene::new(&scene).is_ok());
    let scene = load_xml("takes_lit", &lit_spheres());
    assert!(PacketScene::new(&scene).is_ok());
    let scene = load_xml("takes_box", &box_and_area_light());
    assert!(PacketScene::new(&scene).is_ok());
    let scene = load_xml("takes_glass", &glass_and_area_light());
    assert!(PacketScene::new(&scene).is_ok_and(|ps| ps.dielectrics));
    let scene = cloud("takes_cloud", 1.0);
    assert!(PacketScene::new(&scene).is_ok());
    let scene = load_xml("takes_fog", FOG);
    let ps = PacketScene::new(&scene).expect("the fog is a packet scene");
    assert!(ps.takes_camera_ray(Vec3::ZERO, 1e4));
    assert!(
        !ps.takes_camera_ray(Vec3::new(0.0, 0.0, 6.5), 1e4),
        "outside its medium"
    );
    assert!(
        !ps.takes_camera_ray(Vec3::ZERO, 5.0),
        "clipped inside its medium"
    );
    let refused = [
        (
            "diffuse",
            TWO_SPHERES.replacen(r#"<bsdf type="null"/>"#, r#"<bsdf type="diffuse"/>"#, 1),
            "not null",
        ),
        (
            "overlap",
            TWO_SPHERES.replace(r#"x="0.6" y="0.1" z="4.5""#, r#"x="0.2" y="0" z="4""#),
            "within reach",
        ),
        (
            "hidden_area",
            box_and_area_light().replace(
                r#"<integer name="rr_depth" value="3"/>"#,
                r#"<integer name="rr_depth" value="3"/><boolean name="hide_emitters" value="true"/>"#,
            ),
            "hidden",
        ),
        (
            "box_on_floor",
            box_and_area_light().replace(
                r#"<translate x="0.6" y="0" z="4.5"/>"#,
                r#"<translate x="0.6" y="-0.05" z="4.5"/>"#,
            ),
            "coincident",
        ),
        (
            "box_near_sphere",
            box_and_area_light().replace(r#"<translate x="0.6" y="0" z="4.5"/>"#, r#"<translate x="0.1" y="0" z="4.2"/>"#),
            "within reach",
        ),
        (
            "floor_cuts_sphere",
            lit_spheres().replace(r#"y="-0.5" z="4""#, r#"y="-0.45" z="4""#),
            "crosses a medium",
        ),
        (
            "textured",
            lit_spheres().replace(
                r#"<rgb name="reflectance" value="0.5, 0.6, 0.7"/>"#,
                r#"<texture type="checkerboard" name="reflectance"/>"#,
            ),
            "textured",
        ),
        (
            "path",
            TWO_SPHERES.replace(r#"type="volpath""#, r#"type="path""#),
            "not volpath",
        ),
        (
            "cloud_and_sphere",
            CLOUD.replace("$scale", "1").replace(
                "<emitter type=\"point\">",
                r#"<shape type="sphere"><point name="center" x="1.5" y="0" z="4"/>
                    <float name="radius" value="0.3"/><bsdf type="null"/>
                    <medium type="homogeneous" name="interior"/></shape>
                <emitter type="point">"#,
            ),
            "only one",
        ),
        (
            "peaked",
            TWO_SPHERES.replace(r#"value="0.6""#, r#"value="0.97""#),
            "phase",
        ),
    ];
    for (name, xml, why) in refused {
        let scene = load_xml(name, &xml);
        match PacketScene::new(&scene) {
            Ok(_) => panic!("{name}: taken"),
            Err(e) => assert!(e.contains(why), "{name}: {e}"),
        }
    }
}
