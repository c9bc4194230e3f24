//! A render without derivatives runs the packet's instance without them
//! (`PacketPaths<false>`): the same radiance as the instance with them, bit for bit, and
//! no derivative samples.

use super::test_scenes::{
    box_and_area_light, box_rays, cloud, cloud_rays, fog_rays, glass_and_area_light, lit_rays,
    lit_spheres, load_xml, rays, FOG, TWO_SPHERES,
};
use super::tests::packet_samples_in;
use super::*;
use crate::integrator::volpath::{Estimand, PathSettings};

/// Samples a ray: enough for every kind of vertex on each scene's rays.
const N: usize = 2_000;

/// The bits of what a sample estimates besides the derivatives.
fn bits(s: &PathSample) -> ([u32; 6], bool) {
    let (r, e) = (s.radiance, s.seen_emission);
    let b = [r.x, r.y, r.z, e.x, e.y, e.z].map(f32::to_bits);
    (b, s.valid)
}

fn zero_derivatives(s: &PathSample) -> bool {
    s.d_albedo == Vec3::ZERO && s.d_sigma == Vec3::ZERO && s.d_g == Vec3::ZERO
}

/// The samples of `scene`'s rays without a derivative, in the instance `derivatives`.
fn plain_samples(scene: &Scene, rays: &[Vec3A], derivatives: bool) -> Vec<PathSample> {
    let albedo: Vec<Vec3> = scene.media.iter().map(|m| m.albedo).collect();
    let ps = PacketScene::new(scene).expect("the packet takes the scene");
    let settings = PathSettings {
        albedo: &albedo,
        estimand: Estimand::RadianceOnly,
    };
    assert!(
        !settings.estimand.has_derivatives(),
        "a plain render estimates no derivative"
    );
    let samples = |(i, &d): (usize, &Vec3A)| {
        let ray = (d, 0.0);
        match derivatives {
            true => packet_samples_in::<true>(scene, &ps, &settings, ray, 7 + i as u64, N),
            false => packet_samples_in::<false>(scene, &ps, &settings, ray, 7 + i as u64, N),
        }
    };
    rays.iter().enumerate().flat_map(samples).collect()
}

/// Every scene kind of the comparison with the scalar paths (media behind null and
/// dielectric boundaries, surfaces, area, point and directional lights, the sky, a
/// heterogeneous cloud): the instance without derivatives is the one with them.
#[test]
fn a_plain_render_is_the_instance_with_derivatives_bit_for_bit() {
    let scenes = [
        ("two spheres", load_xml("plain_two", TWO_SPHERES), rays()),
        ("lit", load_xml("plain_lit", &lit_spheres()), lit_rays()),
        (
            "box",
            load_xml("plain_box", &box_and_area_light()),
            box_rays(),
        ),
        ("fog", load_xml("plain_fog", FOG), fog_rays()),
        (
            "glass",
            load_xml("plain_glass", &glass_and_area_light()),
            box_rays(),
        ),
        ("cloud", cloud("plain_cloud", 0.7), cloud_rays()),
    ];
    for (name, scene, rays) in &scenes {
        let without = plain_samples(scene, rays, false);
        let with = plain_samples(scene, rays, true);
        let differ = without
            .iter()
            .zip(&with)
            .filter(|(a, b)| bits(a) != bits(b))
            .count();
        assert_eq!(
            differ,
            0,
            "{name}: {differ} of {} samples differ",
            with.len()
        );
        assert!(without.iter().chain(&with).all(zero_derivatives), "{name}");
        // Not a vacuous comparison: the rays gather light.
        let lit = with.iter().filter(|s| s.radiance != Vec3::ZERO).count();
        assert!(lit > with.len() / 10, "{name}: {lit} lit samples");
    }
}
