//! Error of an image against a Monte Carlo reference.
//!
//! With the reference R = I + e_R (e_R its noise, variance v_R per pixel and channel,
//! estimated from its chunks) and an independent estimate X of the same image I,
//!   E[(X − R)²] = E[(X − I)²] + v_R,
//! so the MSE against the true image is estimated by the raw MSE minus the mean of v_R
//! ("corrected"). Both are means over every pixel and channel.

use crate::image::Image;

/// Mean of (a − b)² over pixels and channels (f64 accumulation).
pub fn mse(a: &Image, b: &Image) -> f64 {
    assert_eq!(
        (a.width, a.height),
        (b.width, b.height),
        "image sizes differ"
    );
    let sum: f64 = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .map(|(p, q)| {
            (0..3)
                .map(|c| {
                    let d = p[c] as f64 - q[c] as f64;
                    d * d
                })
                .sum::<f64>()
        })
        .sum();
    sum / (3 * a.pixels.len()) as f64
}

/// Mean over pixels and channels.
pub fn mean(img: &Image) -> f64 {
    img.pixels
        .iter()
        .map(|p| p.iter().map(|&c| c as f64).sum::<f64>())
        .sum::<f64>()
        / (3 * img.pixels.len()) as f64
}

/// The raw MSE, and the MSE with the reference's own variance (`reference_var`, per
/// pixel and channel, of the reference's mean) subtracted.
pub fn mse_against(img: &Image, reference: &Image, reference_var: &Image) -> (f64, f64) {
    let raw = mse(img, reference);
    (raw, raw - mean(reference_var))
}

/// The standard error of the correction (the reference's own variance, subtracted from
/// every MSE), from the reference's per-value variances v_j estimated over its K chunks:
/// Var((μ_j − r_j)² − v̂_j) ≈ 2 v_j² (1 + 1/(K − 1)) for Gaussian noise, so
///
///   SE(correction) ≈ √(Σ_j 2 v_j² (1 + 1/(K − 1))) / N,  N values.
pub fn correction_se(var: &Image, chunks: u32) -> f64 {
    let k = chunks.max(2) as f64;
    let sum: f64 = var
        .pixels
        .iter()
        .flatten()
        .map(|&v| 2.0 * (v as f64).powi(2) * (1.0 + 1.0 / (k - 1.0)))
        .sum();
    sum.sqrt() / (var.pixels.len() * 3) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    fn img(pixels: Vec<[f32; 3]>) -> Image {
        Image {
            width: pixels.len(),
            height: 1,
            pixels,
        }
    }

    #[test]
    fn mse_is_the_mean_squared_difference_over_pixels_and_channels() {
        let a = img(vec![[1.0, 2.0, 3.0], [0.0, 0.0, 0.0]]);
        let b = img(vec![[1.0, 2.0, 5.0], [1.0, 0.0, 0.0]]);
        assert!((mse(&a, &b) - 5.0 / 6.0).abs() < 1e-12);
    }

    #[test]
    fn correction_removes_the_reference_variance_in_expectation() {
        // X exact, R = I + noise of variance v: raw MSE ≈ v, corrected ≈ 0.
        let n = 200_000;
        let v = 0.01f64;
        let mut state = 12345u64;
        let mut gauss = || {
            // Sum of 12 uniforms − 6: unit variance.
            (0..12)
                .map(|_| {
                    state = state
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    (state >> 40) as f64 / (1u64 << 24) as f64
                })
                .sum::<f64>()
                - 6.0
        };
        let truth = img(vec![[0.5; 3]; n]);
        let noisy = img((0..n)
            .map(|_| {
                let mut p = [0.0; 3];
                for c in &mut p {
                    *c = (0.5 + v.sqrt() * gauss()) as f32;
                }
                p
            })
            .collect());
        let var = img(vec![[v as f32; 3]; n]);
        let (raw, corrected) = mse_against(&truth, &noisy, &var);
        // The raw MSE's standard error is v·sqrt(2/(3n)) ≈ 2.6e-5.
        assert!((raw - v).abs() < 1.5e-4, "raw {raw}");
        assert!(corrected.abs() < 1.5e-4, "corrected {corrected}");
    }
}
