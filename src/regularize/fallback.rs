//! One frame of plain volpath through Open Image Denoise, or not: what the method falls
//! back to for a single frame when OIDN is there. Plain volpath is then the only
//! estimator (the split R_s + D is plain volpath's estimate on every path), and the one
//! question is whether OIDN lowers its error. A denoiser can raise it (measured: a camera
//! inside a medium, a furnace, a converged image), so where asked (`--oidn-check`) it is
//! checked without a reference; else the frame is [`through_oidn`]'s (the check's own
//! OIDN run cost more than it won on held-out scenes: docs/regularize.md, "One frame").
//! The frame's N samples per pixel are rendered as three ranges of the shot's own
//! streams: M (samples 0..N − 2p), A and B (p each, the last 2p). For X = A or B,
//! unbiased and independent of M (nearly: below), E (O − X)² − E (M − X)² =
//! MSE(O) − Var(M) for O = OIDN(M): X's own variance cancels, so
//!
//!   Δ = mean ½ Σ_{X = A, B} [(O − X)² − (M − X)²]  ≈  MSE(OIDN(M)) − Var(M)       (F1)
//!
//! whose noise per value is about √(Var(M) Var(A)), far below Var(A). With Var(M) from
//! Var(A) ≈ ½ mean (A − B)² (F2) scaled by p / (N − 2p), OIDN is used where its error on
//! M is at most plain volpath's variance with all N spp:
//!
//!   Δ + Var(M) ≤ Var(M) (N − 2p) / N,                                              (F3)
//!
//! and then on all N spp (one OIDN run more than plain + OIDN; more samples only lower
//! its error); otherwise the image is plain volpath. Δ's standard error (over 8×8-pixel
//! blocks, as OIDN's output is correlated between neighbouring pixels) is reported
//! beside it.
//!
//! Why ranges of one stream and not renders with seeds of their own: the three ranges
//! together are `render`'s N spp, stratified as one (`sampling::padded`), so the plain
//! image is the plain render and OIDN's image `render --denoise oidn`'s, up to rounding.
//! Three seeds of their own stratify less together, which cost the Candle's flame edges
//! about a fifth more error than `render --denoise oidn` at the same spp
//! (docs/regularize.md). The price is that A and B are not quite independent of M: the
//! stratification across a pixel's samples correlates them negatively, which lowers Δ by
//! about 2 |Cov(X, M)| and so leans the check towards OIDN. Samples spent on A and B are
//! no longer lost to the image, so they are a larger share (`CHECK_SHARE`): M's fewer
//! samples make (F3) stricter on OIDN, which offsets the lean. The rule takes no margin:
//! a wrong choice happens where the two errors are within the estimate's noise of each
//! other, which is where it costs little.

use std::time::Instant;

use crate::denoise::{self, AuxUse, OidnError};
use crate::image::merge::mean_by_weights;
use crate::image::Image;
use crate::integrator::{aovs, render, RenderOptions, Rendered};
use crate::scene::shot::Shot;
use crate::scene::Scene;

/// The share of a render's samples A and B take together. They stay in the image; at a
/// tenth, the near tie of the chromatic sphere (OIDN 1.2× plain volpath's error at
/// about 3000 spp) chose OIDN on 3 of 8 seeds, at a fifth on none of 8.
pub const CHECK_SHARE: f64 = 0.2;

/// Below this many spp there is no check: OIDN is used (at a few spp it is by far the
/// better, docs/denoise.md).
pub const MIN_CHECK_SPP: u32 = 20;

/// What the check measured (per value: pixels × channels).
#[derive(Clone, Debug)]
pub struct OidnCheck {
    /// p: each of A and B.
    pub spp_each: u32,
    /// Plain volpath's variance at N spp, from (F2).
    pub plain_variance: f64,
    /// Δ + Var(M) (F1): OIDN's squared error on M, and its standard error.
    pub oidn_error: f64,
    pub oidn_error_se: f64,
    pub chose_oidn: bool,
}

pub struct Fallback {
    /// The image: OIDN where the check said so, else plain volpath (all N spp).
    pub image: Image,
    /// Plain volpath's image (all N spp).
    pub plain: Image,
    /// The directly seen emission, sharpened (`aovs`).
    pub seen_emission: Image,
    pub check: Option<OidnCheck>,
    /// Rendering (all N spp).
    pub render_seconds: f64,
    /// Sharpening, OIDN and the check.
    pub denoise_seconds: f64,
    pub invalid_samples: u64,
}

fn seen(r: &Rendered) -> &Image {
    r.seen_emission.as_ref().expect("asked for")
}

/// The side of the pixel blocks Δ's standard error is taken over: OIDN's output is
/// correlated between nearby pixels, so values are not independent, blocks nearly are.
const BLOCK: usize = 8;

/// (F2) Var(A), and (F1) Δ with its standard error (over blocks).
fn measure(o: &Image, m: &Image, a: &Image, b: &Image) -> (f64, f64, f64) {
    let (w, h) = (o.width, o.height);
    let (bw, bh) = (w.div_ceil(BLOCK), h.div_ceil(BLOCK));
    let mut blocks = vec![0.0f64; bw * bh];
    let mut var_sum = 0.0;
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            for c in 0..3 {
                let [o, m, a, b] = [o, m, a, b].map(|img| img.pixels[i][c] as f64);
                var_sum += 0.5 * (a - b).powi(2);
                blocks[(y / BLOCK) * bw + x / BLOCK] +=
                    0.5 * ((o - a).powi(2) - (m - a).powi(2) + (o - b).powi(2) - (m - b).powi(2));
            }
        }
    }
    let n = (w * h * 3) as f64;
    let k = blocks.len() as f64;
    // Δ = Σ blocks / n; its variance is k · Var(block sum) / n².
    let mean_block = blocks.iter().sum::<f64>() / k;
    let var_block =
        blocks.iter().map(|s| (s - mean_block).powi(2)).sum::<f64>() / (k - 1.0).max(1.0);
    (var_sum / n, mean_block * k / n, (k * var_block).sqrt() / n)
}

/// `shot` rendered plain and through OIDN, without a check: `render --denoise oidn`'s
/// image, bit for bit, at its cost.
pub fn through_oidn(scene: &Scene, shot: &Shot) -> Result<Fallback, OidnError> {
    let options = RenderOptions {
        seen_emission: true,
        ..Default::default()
    };
    let r = render(scene, shot, &options);
    let started = Instant::now();
    let mut e = seen(&r).clone();
    aovs::sharpen_seen_emission(scene, shot, &mut e);
    let image = denoise::oidn(&r.image, Some(&e), None, AuxUse::None)?;
    Ok(Fallback {
        image,
        plain: r.image,
        seen_emission: e,
        check: None,
        render_seconds: r.stats.seconds,
        denoise_seconds: started.elapsed().as_secs_f64(),
        invalid_samples: r.stats.invalid_samples,
    })
}

/// `shot` (N = `shot.spp`) rendered plain and through OIDN where (F3) holds (always
/// through OIDN below `MIN_CHECK_SPP`).
pub fn plain_or_oidn(scene: &Scene, shot: &Shot) -> Result<Fallback, OidnError> {
    let n = shot.spp;
    let options = RenderOptions {
        seen_emission: true,
        ..Default::default()
    };
    let p = (CHECK_SHARE / 2.0 * n as f64).floor() as u32;
    let sharpened = |mut e: Image| {
        aovs::sharpen_seen_emission(scene, shot, &mut e);
        e
    };
    if n < MIN_CHECK_SPP || p == 0 {
        return through_oidn(scene, shot);
    }
    // M, A and B are the samples 0..N − 2p, N − 2p..N − p and N − p..N of the shot's
    // own streams: together they are `render`'s N spp, stratified as one.
    let range = |first: u32, spp: u32| {
        let opts = RenderOptions {
            first_sample: first,
            ..options.clone()
        };
        render(scene, &shot.with(spp, shot.seed), &opts)
    };
    let m = range(0, n - 2 * p);
    let a = range(n - 2 * p, p);
    let b = range(n - p, p);
    let started = Instant::now();
    let joined = |image: &dyn Fn(&Rendered) -> &Image| {
        mean_by_weights(&[&m, &a, &b].map(|r| (image(r), r.weights.as_slice())))
    };
    let plain = joined(&|r| &r.image);
    // One sharpened seen emission serves both OIDN runs: it differs from M's own only
    // where the samples disagree, at edges, which sharpening replaces in both alike.
    let seen_emission = sharpened(joined(&seen));
    let oidn_m = denoise::oidn(&m.image, Some(&seen_emission), None, AuxUse::None)?;
    let (var_a, delta, delta_se) = measure(&oidn_m, &m.image, &a.image, &b.image);
    let var_m = var_a * p as f64 / (n - 2 * p) as f64;
    let oidn_error = delta + var_m;
    let plain_variance = var_m * (n - 2 * p) as f64 / n as f64;
    let chose_oidn = oidn_error <= plain_variance;
    let image = match chose_oidn {
        true => denoise::oidn(&plain, Some(&seen_emission), None, AuxUse::None)?,
        false => plain.clone(),
    };
    let renders = [&a, &b, &m];
    Ok(Fallback {
        image,
        plain,
        seen_emission,
        check: Some(OidnCheck {
            spp_each: p,
            plain_variance,
            oidn_error,
            oidn_error_se: delta_se,
            chose_oidn,
        }),
        render_seconds: renders.iter().map(|r| r.stats.seconds).sum(),
        denoise_seconds: started.elapsed().as_secs_f64(),
        invalid_samples: renders.iter().map(|r| r.stats.invalid_samples).sum(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Pcg32;

    /// (F1)–(F2) on images with a known answer: a truth T, M = T + noise of variance
    /// σ_M², A and B = T + independent noise of variance σ_A², and a "denoiser" O = T + b
    /// (its squared error b²). Var(A) must come out σ_A² and Δ = b² − σ_M², each within 4
    /// of its own standard errors; Δ with O = T + 2b (3b² more) must not. Seen failing
    /// with (F1)'s ½ left out (Δ doubled).
    #[test]
    fn the_check_measures_a_known_error_and_variance() {
        let (w, h) = (128, 96);
        let mut rng = Pcg32::new(57, 3);
        let mut gauss = || {
            let (u, v) = (rng.next_1d().max(1e-7), rng.next_1d());
            (-2.0 * u.ln()).sqrt() * (std::f32::consts::TAU * v).cos()
        };
        let (sigma_m, sigma_a, b) = (0.02f32, 0.05f32, 0.03f32);
        let n = w * h;
        let truth: Vec<[f32; 3]> = (0..n)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                [0.2 + 0.5 * (x / w as f32), 0.4 + 0.3 * (y / h as f32), 0.6]
            })
            .collect();
        let mut noisy = |sigma: f32| Image {
            width: w,
            height: h,
            pixels: truth
                .iter()
                .map(|t| t.map(|c| c + sigma * gauss()))
                .collect(),
        };
        let (m, a, bb) = (noisy(sigma_m), noisy(sigma_a), noisy(sigma_a));
        let shifted = |by: f32| Image {
            width: w,
            height: h,
            pixels: truth.iter().map(|t| t.map(|c| c + by)).collect(),
        };
        let (var_a, delta, delta_se) = measure(&shifted(b), &m, &a, &bb);
        // Var of a variance estimate from n·3 normal values: 2σ⁴ / (3n).
        let var_se = (2.0 / (3.0 * n as f64)).sqrt() * (sigma_a as f64).powi(2);
        let want_var = (sigma_a as f64).powi(2);
        assert!(
            (var_a - want_var).abs() < 4.0 * var_se,
            "Var(A) {var_a} against {want_var}"
        );
        let want = (b as f64).powi(2) - (sigma_m as f64).powi(2);
        assert!(
            delta_se > 0.0 && delta_se < 0.1 * want,
            "Δ's standard error {delta_se}"
        );
        assert!(
            (delta - want).abs() < 4.0 * delta_se,
            "Δ {delta} ± {delta_se} against {want}"
        );
        let (_, worse, _) = measure(&shifted(2.0 * b), &m, &a, &bb);
        assert!(
            (worse - want).abs() > 4.0 * delta_se,
            "a denoiser with 4× the squared error went unseen: Δ {worse}"
        );
    }
}
