//! Sampled spectra in an RGB renderer: Mitsuba 3's RGB variants turn
//! `<spectrum value="λ₁:v₁, λ₂:v₂, …"/>` into an sRGB colour when the scene loads
//! (`spectrum_list_to_srgb`, `src/core/spectrum.cpp`; which flags apply where is decided
//! in `Properties::get_texture_impl`, `src/core/properties.cpp`). mediareg does the same,
//! so the same file gives the same colours.
//!
//! The conversion integrates the piecewise-linear spectrum against the CIE 1931 2°
//! colour-matching functions (tabulated every 5 nm from 360 to 830 nm and interpolated
//! linearly), by the midpoint-free Riemann sum Mitsuba uses (1000 points over
//! [360, 830] nm, points outside [λ₁, λₙ] contribute nothing):
//!
//!   XYZ = (830 − 360) / (1000 · ∫ȳ) · Σᵢ s(λᵢ) · x̄ȳz̄(λᵢ) · w(λᵢ),
//!
//! with w = D65(λ)/∫(ȳ·D65) for reflectances and other unitless colours (a flat
//! spectrum of 1 becomes white, since D65 is sRGB's white point) and w = 1 for emitted
//! radiance. XYZ goes to linear sRGB by the Rec. 709 matrix. Reflectances are clipped to
//! [0, 1], the others only at 0.

use glam::Vec3;

/// What a colour means, which decides how a spectrum becomes RGB.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpectrumUse {
    /// A reflectance or transmittance: D65-weighted, clipped to [0, 1].
    Reflectance,
    /// A unitless quantity that may exceed 1 (extinction, albedo of a medium, a
    /// conductor's η and κ): D65-weighted, clipped at 0 only.
    Unbounded,
    /// Emitted radiance, intensity or irradiance: not D65-weighted, clipped at 0 only.
    Emission,
}

const LAMBDA_MIN: f64 = 360.0;
const LAMBDA_MAX: f64 = 830.0;
const SAMPLES: usize = 95;
/// 1/∫ȳ dλ of the tabulated, linearly interpolated ȳ: a flat spectrum of 1 has Y = 1.
const Y_NORMALIZATION: f64 = 1.0 / 106.750_259_399_414_06;
/// 1/∫(ȳ · D65) dλ: the D65 weight keeps a flat reflectance of 1 at Y = 1.
const D65_NORMALIZATION: f64 = 1.0 / 98.997_417_518_762_55;

/// Linear sRGB (Rec. 709 primaries, D65 white) from CIE XYZ, Mitsuba's `xyz_to_srgb`.
pub fn xyz_to_srgb(xyz: [f64; 3]) -> [f64; 3] {
    let [x, y, z] = xyz;
    [
        3.240479 * x - 1.537150 * y - 0.498535 * z,
        -0.969256 * x + 1.875991 * y + 0.041556 * z,
        0.055648 * x - 0.204043 * y + 1.057311 * z,
    ]
}

/// The tables at λ (nm), linearly interpolated; zero outside [360, 830].
fn lookup(table: &[f64; SAMPLES], lambda: f64) -> f64 {
    if !(LAMBDA_MIN..=LAMBDA_MAX).contains(&lambda) {
        return 0.0;
    }
    let t = (lambda - LAMBDA_MIN) * ((SAMPLES - 1) as f64 / (LAMBDA_MAX - LAMBDA_MIN));
    let i0 = (t as usize).min(SAMPLES - 2);
    let w1 = t - i0 as f64;
    (1.0 - w1) * table[i0] + w1 * table[i0 + 1]
}

/// The sRGB colour of a spectrum given as (wavelength in nm, value) pairs with strictly
/// increasing wavelengths (the parser checks that), as Mitsuba 3's RGB mode computes it.
pub fn spectrum_to_srgb(samples: &[(f64, f64)], usage: SpectrumUse) -> Vec3 {
    let d65 = usage != SpectrumUse::Emission;
    let (first, last) = (samples[0].0, samples[samples.len() - 1].0);
    let steps = 1000;
    let mut xyz = [0.0f64; 3];
    for i in 0..steps {
        let lambda = LAMBDA_MIN + (i as f64 / (steps - 1) as f64) * (LAMBDA_MAX - LAMBDA_MIN);
        if lambda < first || lambda > last {
            continue;
        }
        // The interval [λ_k, λ_k+1] holding λ (the last one for λ = λₙ).
        let k = samples[..samples.len() - 1]
            .partition_point(|&(w, _)| w <= lambda)
            .saturating_sub(1)
            .min(samples.len().saturating_sub(2));
        let value = if samples.len() == 1 {
            samples[0].1
        } else {
            let ((w0, v0), (w1, v1)) = (samples[k], samples[k + 1]);
            ((lambda - w1) * v0 + (w0 - lambda) * v1) / (w0 - w1)
        };
        let weight = if d65 {
            lookup(&D65, lambda) * D65_NORMALIZATION
        } else {
            1.0
        };
        let v = value * weight;
        xyz[0] += lookup(&CIE_X, lambda) * v;
        xyz[1] += lookup(&CIE_Y, lambda) * v;
        xyz[2] += lookup(&CIE_Z, lambda) * v;
    }
    let norm = (LAMBDA_MAX - LAMBDA_MIN) * Y_NORMALIZATION / steps as f64;
    let rgb = xyz_to_srgb(xyz.map(|c| c * norm));
    let hi = if usage == SpectrumUse::Reflectance {
        1.0
    } else {
        f64::INFINITY
    };
    Vec3::new(
        rgb[0].clamp(0.0, hi) as f32,
        rgb[1].clamp(0.0, hi) as f32,
        rgb[2].clamp(0.0, hi) as f32,
    )
}

// CIE 1931 2° standard observer x̄, ȳ, z̄ and the CIE standard illuminant D65 (relative
// spectral power, 100 at 560 nm), every 5 nm from 360 to 830 nm (CIE 015:2018 tables,
// the ones Mitsuba 3 tabulates).
const CIE_X: [f64; SAMPLES] = [
    0.0001299,
    0.0002321,
    0.0004149,
    0.0007416,
    0.001368,
    0.002236,
    0.004243,
    0.00765,
    0.01431,
    0.02319,
    0.04351,
    0.07763,
    0.13438,
    0.21477,
    0.2839,
    0.3285,
    0.34828,
    0.34806,
    0.3362,
    0.3187,
    0.2908,
    0.2511,
    0.19536,
    0.1421,
    0.09564,
    0.05795001,
    0.03201,
    0.0147,
    0.0049,
    0.0024,
    0.0093,
    0.0291,
    0.06327,
    0.1096,
    0.1655,
    0.2257499,
    0.2904,
    0.3597,
    0.4334499,
    0.5120501,
    0.5945,
    0.6784,
    0.7621,
    0.8425,
    0.9163,
    0.9786,
    1.0263,
    1.0567,
    1.0622,
    1.0456,
    1.0026,
    0.9384,
    0.8544499,
    0.7514,
    0.6424,
    0.5419,
    0.4479,
    0.3608,
    0.2835,
    0.2187,
    0.1649,
    0.1212,
    0.0874,
    0.0636,
    0.04677,
    0.0329,
    0.0227,
    0.01584,
    0.01135916,
    0.008110916,
    0.005790346,
    0.004109457,
    0.002899327,
    0.00204919,
    0.001439971,
    0.0009999493,
    0.0006900786,
    0.0004760213,
    0.0003323011,
    0.0002348261,
    0.0001661505,
    0.000117413,
    8.307527e-05,
    5.870652e-05,
    4.150994e-05,
    2.935326e-05,
    2.067383e-05,
    1.455977e-05,
    1.025398e-05,
    7.221456e-06,
    5.085868e-06,
    3.581652e-06,
    2.522525e-06,
    1.776509e-06,
    1.251141e-06,
];
const CIE_Y: [f64; SAMPLES] = [
    3.917e-06, 6.965e-06, 1.239e-05, 2.202e-05, 3.9e-05, 6.4e-05, 0.00012, 0.000217, 0.000396,
    0.00064, 0.00121, 0.00218, 0.004, 0.0073, 0.0116, 0.01684, 0.023, 0.0298, 0.038, 0.048, 0.06,
    0.0739, 0.09098, 0.1126, 0.13902, 0.1693, 0.20802, 0.2586, 0.323, 0.4073, 0.503, 0.6082, 0.71,
    0.7932, 0.862, 0.9148501, 0.954, 0.9803, 0.9949501, 1.0, 0.995, 0.9786, 0.952, 0.9154, 0.87,
    0.8163, 0.757, 0.6949, 0.631, 0.5668, 0.503, 0.4412, 0.381, 0.321, 0.265, 0.217, 0.175, 0.1382,
    0.107, 0.0816, 0.061, 0.04458, 0.032, 0.0232, 0.017, 0.01192, 0.00821, 0.005723, 0.004102,
    0.002929, 0.002091, 0.001484, 0.001047, 0.00074, 0.00052, 0.0003611, 0.0002492, 0.0001719,
    0.00012, 8.48e-05, 6e-05, 4.24e-05, 3e-05, 2.12e-05, 1.499e-05, 1.06e-05, 7.4657e-06,
    5.2578e-06, 3.7029e-06, 2.6078e-06, 1.8366e-06, 1.2934e-06, 9.1093e-07, 6.4153e-07, 4.5181e-07,
];
const CIE_Z: [f64; SAMPLES] = [
    0.0006061,
    0.001086,
    0.001946,
    0.003486,
    0.006450001,
    0.01054999,
    0.02005001,
    0.03621,
    0.06785001,
    0.1102,
    0.2074,
    0.3713,
    0.6456,
    1.03905,
    1.3856,
    1.62296,
    1.74706,
    1.7826,
    1.77211,
    1.7441,
    1.6692,
    1.5281,
    1.28764,
    1.0419,
    0.8129501,
    0.6162,
    0.46518,
    0.3533,
    0.272,
    0.2123,
    0.1582,
    0.1117,
    0.07824999,
    0.05725001,
    0.04216,
    0.02984,
    0.0203,
    0.0134,
    0.008749999,
    0.005749999,
    0.0039,
    0.002749999,
    0.0021,
    0.0018,
    0.001650001,
    0.0014,
    0.0011,
    0.001,
    0.0008,
    0.0006,
    0.00034,
    0.00024,
    0.00019,
    0.0001,
    4.999999e-05,
    3e-05,
    2e-05,
    1e-05,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
];
const D65: [f64; SAMPLES] = [
    46.6383, 49.3637, 52.0891, 51.0323, 49.9755, 52.3118, 54.6482, 68.7015, 82.7549, 87.1204,
    91.486, 92.4589, 93.4318, 90.057, 86.6823, 95.7736, 104.865, 110.936, 117.008, 117.41, 117.812,
    116.336, 114.861, 115.392, 115.923, 112.367, 108.811, 109.082, 109.354, 108.578, 107.802,
    106.296, 104.79, 106.239, 107.689, 106.047, 104.405, 104.225, 104.046, 102.023, 100.0, 98.1671,
    96.3342, 96.0611, 95.788, 92.2368, 88.6856, 89.3459, 90.0062, 89.8026, 89.5991, 88.6489,
    87.6987, 85.4936, 83.2886, 83.4939, 83.6992, 81.863, 80.0268, 80.1207, 80.2146, 81.2462,
    82.2778, 80.281, 78.2842, 74.0027, 69.7213, 70.6652, 71.6091, 72.979, 74.349, 67.9765, 61.604,
    65.7448, 69.8856, 72.4863, 75.087, 69.3398, 63.5927, 55.0054, 46.4182, 56.6118, 66.8054,
    65.0941, 63.3828, 63.8434, 64.304, 61.8779, 59.4519, 55.7054, 51.959, 54.6998, 57.4406,
    58.8765, 60.3125,
];

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Vec3, b: [f32; 3], tol: f32) -> bool {
        (a - Vec3::from(b)).abs().max_element() <= tol
    }

    /// A flat reflectance of 1 is (almost) white: D65 is sRGB's white point, and the
    /// tables and normalizations agree.
    #[test]
    fn flat_reflectance_is_white() {
        let c = spectrum_to_srgb(&[(360.0, 1.0), (830.0, 1.0)], SpectrumUse::Reflectance);
        assert!(close(c, [1.0, 1.0, 1.0], 6e-3), "{c}");
    }

    /// Values Mitsuba 3.9.1 `mi.spectrum_list_to_srgb` gives for spectra of the corpus's
    /// Cornell box (`mdata_cbox`): the red wall's reflectance, and the light's radiance
    /// (unbounded, no D65), which is far outside [0, 1].
    #[test]
    fn matches_mitsuba_on_the_cornell_box_spectra() {
        let red = "400:0.04, 404:0.046, 408:0.048, 412:0.053, 416:0.049, 420:0.05, 424:0.053, 428:0.055, 432:0.057, 436:0.056, 440:0.059, 444:0.057, 448:0.061, 452:0.061, 456:0.06, 460:0.062, 464:0.062, 468:0.062, 472:0.061, 476:0.062, 480:0.06, 484:0.059, 488:0.057, 492:0.058, 496:0.058, 500:0.058, 504:0.056, 508:0.055, 512:0.056, 516:0.059, 520:0.057, 524:0.055, 528:0.059, 532:0.059, 536:0.058, 540:0.059, 544:0.061, 548:0.061, 552:0.063, 556:0.063, 560:0.067, 564:0.068, 568:0.072, 572:0.08, 576:0.09, 580:0.099, 584:0.124, 588:0.154, 592:0.192, 596:0.255, 600:0.287, 604:0.349, 608:0.402, 612:0.443, 616:0.487, 620:0.513, 624:0.558, 628:0.584, 632:0.62, 636:0.606, 640:0.609, 644:0.651, 648:0.612, 652:0.61, 656:0.65, 660:0.638, 664:0.627, 668:0.62, 672:0.63, 676:0.628, 680:0.642, 684:0.639, 688:0.657, 692:0.639, 696:0.635, 700:0.642";
        let parse = |s: &str| -> Vec<(f64, f64)> {
            s.split(',')
                .map(|p| {
                    let (w, v) = p.trim().split_once(':').unwrap();
                    (w.parse().unwrap(), v.parse().unwrap())
                })
                .collect()
        };
        let c = spectrum_to_srgb(&parse(red), SpectrumUse::Reflectance);
        assert!(close(c, [0.49132, 0.049228, 0.0509219], 2e-5), "{c}");
        let light = parse("400:0, 500:8, 600:15.6, 700:18.4");
        let c = spectrum_to_srgb(&light, SpectrumUse::Emission);
        assert!(close(c, [20.7108, 10.8546, 2.77115], 2e-4), "{c}");
        // As a reflectance the same spectrum is clipped into [0, 1].
        let c = spectrum_to_srgb(&light, SpectrumUse::Reflectance);
        assert!(close(c, [1.0, 1.0, 1.0], 0.0), "{c}");
    }

    /// A spectrum that lives only where z̄ is large (blue) comes out blue; outside the
    /// tabulated range it is black.
    #[test]
    fn narrow_spectra() {
        let blue = spectrum_to_srgb(&[(440.0, 1.0), (460.0, 1.0)], SpectrumUse::Emission);
        assert!(blue.z > blue.x && blue.z > blue.y && blue.min_element() >= 0.0);
        let none = spectrum_to_srgb(&[(900.0, 1.0), (1000.0, 1.0)], SpectrumUse::Emission);
        assert_eq!(none, Vec3::ZERO);
    }
}
