//! Which pipeline a sequence's target frame comes from, chosen without a reference
//! (issue 56). With OIDN on every frame, the method's frames hold R_s and D in the same
//! paths, and R_s + D is plain volpath's estimate path by path. So the same frames give
//! five images of the target frame:
//!
//! * `Split`: OIDN(R_s) + the blend (Eq. 10) of each frame's OIDN(D_k) — the method;
//! * `Control`: the blend of each frame's OIDN(R_s,k + D_k) — plain radiance through
//!   the same reuse (`--predict plain`), which smears what changes between frames;
//! * `GuardedControl`: the control where it agrees with the split, the split where the
//!   two disagree far more than they typically do (K3) — the control without its smears;
//! * `PlainOidn`: OIDN(R_s + D) of the target frame alone;
//! * `Plain`: R_s + D, no denoiser at all.
//!
//! Which is best depends on the scene and the budget (docs/paper.md, the sweep). Two
//! held-out plain renders A and B of the target view at α_t (p spp each, seeds of their
//! own) are independent of all five, so for each candidate Y
//!
//!   E ½[(Y − A)² + (Y − B)²] − E ½(A − B)² = E (Y − A)(Y − B) = MSE(Y)              (K1)
//!
//! (A's variance cancels, `fallback`'s (F1) idea with Y in place of OIDN(M)). The noise
//! of each estimate is mostly A's and B's own, which is common to all five and cancels
//! in their differences, so each candidate is judged against the split by their
//! difference: the check leaves the split only for a candidate whose (K1) is below the
//! split's by `SWITCH_Z` standard errors (K2) of that difference (`choose`), and then
//! takes the least (K1) among those.
//!
//! The whole image is checked: a window was tried and missed the Candle's flame, where
//! the control's error lives (a few pixels at its outline, 800× plain + OIDN's there).
//! So both sequence pipelines denoise every frame; the check's cost is the pipeline not
//! chosen, A and B, and (K1).

use std::time::Instant;

use crate::denoise::{self, AuxUse, OidnError};
use crate::image::Image;
use crate::integrator::{render, RenderOptions};
use crate::scene::shot::Shot;
use crate::scene::Scene;

use super::temporal::{self, Reprojection};

/// The candidates, in the order of `PipelineCheck::errors`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pipeline {
    Split,
    Control,
    GuardedControl,
    PlainOidn,
    Plain,
}

impl Pipeline {
    pub const ALL: [Pipeline; 5] = [
        Pipeline::Split,
        Pipeline::Control,
        Pipeline::GuardedControl,
        Pipeline::PlainOidn,
        Pipeline::Plain,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            Pipeline::Split => "split",
            Pipeline::Control => "control",
            Pipeline::GuardedControl => "guarded_control",
            Pipeline::PlainOidn => "plain_oidn",
            Pipeline::Plain => "plain",
        }
    }
}

/// What the check measured.
#[derive(Clone, Debug)]
pub struct PipelineCheck {
    /// p: each of A and B.
    pub spp_each: u32,
    /// Per candidate (`Pipeline::ALL`'s order): (K1), and the standard error (K2) of its
    /// excess over the chosen one's (0 for the chosen).
    pub errors: [(f64, f64); 5],
    pub chosen: Pipeline,
    /// What the check cost beyond the chosen pipeline's own denoising: A and B, the
    /// other pipelines' denoising and blends, and (K1).
    pub seconds: f64,
}

impl PipelineCheck {
    /// Each candidate's (K1) and its (K2) against the chosen one, by name:
    /// "split 1.234e-5 ± 2.0e-6, control …".
    pub fn errors_by_name(&self) -> String {
        Pipeline::ALL
            .iter()
            .zip(&self.errors)
            .map(|(p, (e, se))| format!("{} {e:.3e} ± {se:.1e}", p.as_str()))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// A and B together, as a share of one frame's samples. The check runs once per
/// sequence, so this costs a twenty-second of the sequence's rendering; `fallback`'s
/// 0.1 (p = 1 at 22 spp) let the Candle's flame, whose pixels are the noisiest of A
/// and B, hide the control's smear on one seed in three (the sweep, docs/paper.md).
pub const CHECK_SHARE: f64 = 0.5;

/// One frame of the sequence as rendered, before any denoising.
pub struct RawFrame {
    /// R_s,k: the radiance at the source albedo.
    pub source: Image,
    /// D_k = R(α_t) − R(α_s) in R_s,k's paths.
    pub difference: Image,
    /// The directly seen emission, sharpened (`aovs`).
    pub seen: Image,
}

impl RawFrame {
    /// R_s + D: plain volpath's estimate at α_t.
    pub fn plain(&self) -> Image {
        sum(&self.source, &self.difference)
    }
}

/// a + b, pixel by pixel.
pub fn sum(a: &Image, b: &Image) -> Image {
    Image {
        pixels: a
            .pixels
            .iter()
            .zip(&b.pixels)
            .map(|(x, y)| [x[0] + y[0], x[1] + y[1], x[2] + y[2]])
            .collect(),
        ..a.clone()
    }
}

/// Side of the square pixel blocks the check sums over: wider than the reach of the
/// reconstruction filter, so held-out noise in one block is nearly independent of the
/// next one's.
const BLOCK: usize = 8;

/// Sums `per_value(pixel, channel)` per `BLOCK`×`BLOCK`-pixel block of a `w`×`h` image,
/// divided by the values' count: the blocks sum to the image's mean.
fn block_means(w: usize, h: usize, per_value: impl Fn(usize, usize) -> f64) -> Vec<f64> {
    let bw = w.div_ceil(BLOCK);
    let n = (w * h * 3) as f64;
    let mut blocks = vec![0.0f64; bw * h.div_ceil(BLOCK)];
    for j in 0..h {
        for i in 0..w {
            let k = j * w + i;
            blocks[(j / BLOCK) * bw + i / BLOCK] +=
                (0..3).map(|c| per_value(k, c)).sum::<f64>() / n;
        }
    }
    blocks
}

/// (K1) for candidate `y` against held-out `a` and `b`: the mean of (y − a)(y − b).
pub fn held_out_error(y: &Image, a: &Image, b: &Image) -> f64 {
    let v = |img: &Image, k: usize, c: usize| img.pixels[k][c] as f64;
    block_means(y.width, y.height, |k, c| {
        (v(y, k, c) - v(a, k, c)) * (v(y, k, c) - v(b, k, c))
    })
    .iter()
    .sum()
}

/// The standard error of (K1)(y) − (K1)(x), the candidates given. Per value the excess
/// is (y − x)(y + x − a − b): given the candidates its only noise is −(y − x)(a + b),
/// whose variance (y − x)² Var(a + b) has the unbiased estimate (y − x)² (a − b)²
/// (a and b independent and alike; summed per block before squaring, so that noise
/// shared by neighbouring pixels and a pixel's channels is counted):
///
///   SE² = Σ_blocks [Σ_block (y − x)(a − b) / n]²                                     (K2)
///
/// This is the error of judging *these* images, which is what the check decides. The
/// spread of the excess over blocks would also count how unevenly the error lies over
/// the image: the Candle's control errs in a few blocks at its flame, and by that
/// spread its large excess never looked certain (docs/regularize.md).
pub fn excess_standard_error(y: &Image, x: &Image, a: &Image, b: &Image) -> f64 {
    let v = |img: &Image, k: usize, c: usize| img.pixels[k][c] as f64;
    block_means(y.width, y.height, |k, c| {
        (v(y, k, c) - v(x, k, c)) * (v(a, k, c) - v(b, k, c))
    })
    .iter()
    .map(|s| s * s)
    .sum::<f64>()
    .sqrt()
}

/// Standard errors (K2) by which a candidate's (K1) must undercut the split's for the
/// check to leave the method: about a one-in-six chance of leaving it on a tie, where
/// leaving costs nothing, and a wrong leave is as far off as (K2) makes it unlikely.
pub const SWITCH_Z: f64 = 1.0;

/// The candidate of least (K1) among the split (index 0) and those whose (K1) is below
/// the split's by more than `SWITCH_Z` standard errors (K2) of their difference.
/// `errors[i]`: candidate i's (K1); `excess_se[i]`: (K2) of candidate i against the
/// split. Its picks on the table's scenes, scored against the references, are in
/// docs/regularize.md ("Which standard error").
fn choose<const N: usize>(errors: &[f64; N], excess_se: &[f64; N]) -> usize {
    (1..N)
        .filter(|&i| errors[i] - errors[0] + SWITCH_Z * excess_se[i] < 0.0)
        .chain([0])
        .min_by(|&i, &j| errors[i].total_cmp(&errors[j]))
        .expect("the split is a candidate")
}

/// How far, in multiples of the split's and the control's median disagreement per
/// pixel, the two may disagree before a pixel leaves the control: far beyond their
/// typical difference in noise and blur, so that only smears (a flickering emitter
/// reprojected, the Candle's flame) fall back to the split.
pub const GUARD_SPREAD: f32 = 256.0;

/// (K3): per pixel, w · control + (1 − w) · split with w = exp(−½ (d / s)²), d the sum
/// over channels of |control − split| and s = `GUARD_SPREAD` times d's median over the
/// image. Both images are already made, so the candidate costs no denoising.
pub fn guarded_control(split: &Image, control: &Image) -> Image {
    let d: Vec<f32> = split
        .pixels
        .iter()
        .zip(&control.pixels)
        .map(|(x, y)| (0..3).map(|c| (y[c] - x[c]).abs()).sum())
        .collect();
    let mut sorted = d.clone();
    let mid = sorted.len() / 2;
    let s = match sorted.is_empty() {
        true => 0.0,
        false => GUARD_SPREAD * *sorted.select_nth_unstable_by(mid, f32::total_cmp).1,
    };
    let pixels = split
        .pixels
        .iter()
        .zip(&control.pixels)
        .zip(&d)
        .map(|((x, y), &d)| {
            let w = match s > 0.0 {
                true => (-0.5 * (d / s).powi(2)).exp(),
                false => f32::from(d == 0.0),
            };
            [0, 1, 2].map(|c| w * y[c] + (1.0 - w) * x[c])
        })
        .collect();
    Image {
        pixels,
        ..split.clone()
    }
}

/// What the check needs of the run: the scene, the target frame's shot, the frames as
/// rendered (the target first), each earlier frame's reprojection into the target frame
/// and Eq. 10's w_a.
pub struct CheckInput<'a> {
    pub scene: &'a Scene,
    pub shot: &'a Shot,
    pub frames: &'a [RawFrame],
    pub maps: &'a [Reprojection],
    pub w_a: f64,
}

/// The check's outcome: the chosen image, and what went into it.
pub struct Checked {
    pub check: PipelineCheck,
    /// The chosen candidate.
    pub image: Image,
    /// The split's OIDN(R_s) of the target frame, and the blend its pipeline made (the
    /// denoised differences', or the control's radiance), where it is a sequence one.
    pub source: Image,
    pub blended: Option<Image>,
    /// The chosen pipeline's denoising of the target frame, and of all frames.
    pub own_target_seconds: f64,
    pub own_seconds: f64,
}

/// (K1) for every candidate; the least is chosen.
pub fn check(input: &CheckInput) -> Result<Checked, OidnError> {
    let started = Instant::now();
    let CheckInput {
        scene,
        shot,
        frames,
        maps,
        w_a,
    } = *input;
    let (w, h) = (frames[0].source.width, frames[0].source.height);
    // Held-out plain renders, far from every frame's seed (32 bits, as Mitsuba's).
    let p = ((CHECK_SHARE / 2.0 * shot.spp as f64).round() as u32).max(1);
    let held_out = |k: u64| {
        let s = shot.with(p, shot.seed.wrapping_add(k * 0x6a09_e667) & 0xffff_ffff);
        render(scene, &s, &RenderOptions::default()).image
    };
    let (a, b) = (held_out(7), held_out(8));
    // Each sequence pipeline's frames, timed: [per frame, of which the target's].
    let mut seconds = [[0.0f64; 2]; 2];
    let mut timed = |slot: usize, k: usize, run: &dyn Fn() -> Result<Image, OidnError>| {
        let start = Instant::now();
        let out = run()?;
        let t = start.elapsed().as_secs_f64();
        seconds[slot][0] += t;
        if k == 0 {
            seconds[slot][1] += t;
        }
        Ok::<_, OidnError>(out)
    };
    let mut differences = Vec::with_capacity(frames.len());
    let mut controls = Vec::with_capacity(frames.len());
    for (k, f) in frames.iter().enumerate() {
        differences.push(timed(0, k, &|| {
            denoise::oidn_signed(&f.difference, None, AuxUse::None)
        })?);
        controls.push(timed(1, k, &|| {
            denoise::oidn(&f.plain(), Some(&f.seen), None, AuxUse::None)
        })?);
    }
    let f0 = &frames[0];
    let source = timed(0, 0, &|| {
        denoise::oidn(&f0.source, Some(&f0.seen), None, AuxUse::None)
    })?;
    let blend = |images: &[Image]| {
        let refs: Vec<&[[f32; 3]]> = images.iter().map(|i| i.pixels.as_slice()).collect();
        Image {
            width: w,
            height: h,
            pixels: temporal::blend(&refs, maps, w, h, w_a),
        }
    };
    let blended_difference = blend(&differences);
    let blended_control = blend(&controls);
    let split = sum(&source, &blended_difference);
    let guarded = guarded_control(&split, &blended_control);
    let mut candidates = [
        split,
        blended_control.clone(),
        guarded,
        controls.swap_remove(0),
        f0.plain(),
    ];
    let totals = candidates.each_ref().map(|y| held_out_error(y, &a, &b));
    let against_split =
        std::array::from_fn(|i| excess_standard_error(&candidates[i], &candidates[0], &a, &b));
    let best = choose(&totals, &against_split);
    let errors = std::array::from_fn(|i| {
        let se = excess_standard_error(&candidates[i], &candidates[best], &a, &b);
        (totals[i], se)
    });
    let chosen = Pipeline::ALL[best];
    // The chosen pipeline's own denoising: what a frame made with it pays anyway.
    let (own_seconds, own_target_seconds) = match chosen {
        Pipeline::Split => (seconds[0][0], seconds[0][1]),
        Pipeline::Control => (seconds[1][0], seconds[1][1]),
        Pipeline::GuardedControl => (seconds[0][0] + seconds[1][0], seconds[0][1] + seconds[1][1]),
        Pipeline::PlainOidn => (seconds[1][1], seconds[1][1]),
        Pipeline::Plain => (0.0, 0.0),
    };
    let blended = match chosen {
        Pipeline::Split => Some(blended_difference),
        Pipeline::Control | Pipeline::GuardedControl => Some(blended_control),
        _ => None,
    };
    let image = std::mem::replace(
        &mut candidates[best],
        Image {
            width: 0,
            height: 0,
            pixels: Vec::new(),
        },
    );
    Ok(Checked {
        check: PipelineCheck {
            spp_each: p,
            errors,
            chosen,
            seconds: started.elapsed().as_secs_f64() - own_seconds,
        },
        image,
        source,
        blended,
        own_target_seconds,
        own_seconds,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Pcg32;

    fn gaussians(seed: u64) -> impl FnMut() -> f32 {
        let mut rng = Pcg32::new(seed, 1);
        move || {
            let (u, v) = (rng.next_1d().max(1e-7), rng.next_1d());
            (-2.0 * u.ln()).sqrt() * (std::f32::consts::TAU * v).cos()
        }
    }

    fn ramp(w: usize, h: usize) -> Image {
        Image {
            width: w,
            height: h,
            pixels: (0..w * h)
                .map(|i| {
                    let (x, y) = ((i % w) as f32 / w as f32, (i / w) as f32 / h as f32);
                    [0.1 + x, 0.5, 0.3 + y]
                })
                .collect(),
        }
    }

    fn map(img: &Image, mut f: impl FnMut(usize, [f32; 3]) -> [f32; 3]) -> Image {
        Image {
            pixels: img
                .pixels
                .iter()
                .enumerate()
                .map(|(k, &p)| f(k, p))
                .collect(),
            ..img.clone()
        }
    }

    /// (K1) on images with a known answer: a truth T, held-out A and B = T + noise of
    /// variance σ², and candidates T + b_i (squared errors b_i²). Each estimate must come
    /// out b_i² within 4 of its standard errors (per value (b − ε_a)(b − ε_b) has
    /// variance 2b²σ² + σ⁴), and the least must be the one with the least b². Seen
    /// failing with the ½(A − B)² term left out (every estimate σ² high).
    #[test]
    fn the_held_out_error_measures_a_known_error() {
        let truth = ramp(96, 64);
        let n = (96 * 64 * 3) as f64;
        let (sigma, mut gauss) = (0.05f32, gaussians(56));
        let mut noisy = || map(&truth, |_, t| t.map(|c| c + sigma * gauss()));
        let (a, b) = (noisy(), noisy());
        let biases = [0.02f32, 0.01, 0.03];
        let errors: Vec<f64> = biases
            .iter()
            .map(|&b_i| held_out_error(&map(&truth, |_, t| t.map(|c| c + b_i)), &a, &b))
            .collect();
        for (&b_i, &e) in biases.iter().zip(&errors) {
            let (b2, s2) = ((b_i as f64).powi(2), (sigma as f64).powi(2));
            let se = ((2.0 * b2 * s2 + s2 * s2) / n).sqrt();
            assert!((e - b2).abs() < 4.0 * se, "{e} against {b2} ± {se}");
        }
        let least = (0..3).min_by(|&i, &j| errors[i].total_cmp(&errors[j]));
        assert_eq!(least, Some(1));
    }

    /// (K2) is the spread of the excess (K1)(y) − (K1)(x) over held-out draws, for fixed
    /// candidates: x off by a little everywhere, y by a lot in short runs of pixels (the
    /// Candle's control at its flame), the held-out noise shared by a pixel's channels
    /// and by horizontal neighbours. Over 400 draws of A and B the root mean square
    /// (K2) must be within 15% of the excesses' standard deviation (measured 0.96 of it
    /// over 3000 draws: the neighbours across a block's edge; 4% is the 400 draws' own
    /// noise). Seen failing with (K2) squared per pixel instead of per block (0.71).
    #[test]
    fn the_excess_standard_error_is_the_spread_of_the_excess_over_held_out_draws() {
        let (w, h) = (48, 32);
        let truth = ramp(w, h);
        let x = map(&truth, |_, t| t.map(|c| c + 0.01));
        let y = map(&truth, |k, t| match k % 97 < 6 {
            true => t.map(|c| c + 0.5),
            false => t,
        });
        let mut gauss = gaussians(7);
        let mut noisy = || {
            let shared: Vec<f32> = (0..w * h + 1).map(|_| gauss()).collect();
            map(&truth, |k, t| {
                let common = 0.05 * (shared[k] + shared[k + 1]);
                t.map(|c| c + common + 0.03 * gauss())
            })
        };
        let draws: Vec<(f64, f64)> = (0..400)
            .map(|_| {
                let (a, b) = (noisy(), noisy());
                let excess = held_out_error(&y, &a, &b) - held_out_error(&x, &a, &b);
                (excess, excess_standard_error(&y, &x, &a, &b))
            })
            .collect();
        let k = draws.len() as f64;
        let mean = draws.iter().map(|d| d.0).sum::<f64>() / k;
        let spread = (draws.iter().map(|d| (d.0 - mean).powi(2)).sum::<f64>() / (k - 1.0)).sqrt();
        let se = (draws.iter().map(|d| d.1 * d.1).sum::<f64>() / k).sqrt();
        assert!(
            (se / spread - 1.0).abs() < 0.15,
            "(K2) {se:.3e} against the excesses' spread {spread:.3e}"
        );
    }

    /// (K3) keeps the control where the two images differ as they typically do and the
    /// split where they differ by far more: split and control alike but for a small
    /// wobble everywhere, and a smear of 100 in four pixels. Seen failing with the
    /// weight turned round (the smeared pixels kept).
    #[test]
    fn the_guarded_control_leaves_the_control_only_where_it_smears() {
        let split = ramp(32, 16);
        let mut wobble = gaussians(11);
        let smeared = [5usize, 77, 300, 301];
        let control = map(&split, |k, t| match smeared.contains(&k) {
            true => t.map(|c| c + 100.0),
            false => t.map(|c| c + 0.01 * wobble()),
        });
        let guarded = guarded_control(&split, &control);
        for (k, ((g, c), s)) in guarded
            .pixels
            .iter()
            .zip(&control.pixels)
            .zip(&split.pixels)
            .enumerate()
        {
            let want = if smeared.contains(&k) { s } else { c };
            for ch in 0..3 {
                assert!(
                    (g[ch] - want[ch]).abs() < 1e-4,
                    "pixel {k}: {g:?}, not {want:?}"
                );
            }
        }
    }

    /// The check leaves the split only for a candidate more than `SWITCH_Z` standard
    /// errors below it, and then for the least (K1) among those that are: candidate 1
    /// lower by half a standard error keeps the split; lower by two leaves it; a
    /// candidate 2 lower still but within its own (wide) error does not take it.
    /// Seen failing with the margin left out (candidate 1 then wins the first case).
    #[test]
    fn the_check_leaves_the_split_only_for_a_clear_gain() {
        let worse = 10.0;
        assert_eq!(choose(&[1.0, 0.95, worse, worse], &[0.0, 0.1, 1.0, 1.0]), 0);
        assert_eq!(choose(&[1.0, 0.8, worse, worse], &[0.0, 0.1, 1.0, 1.0]), 1);
        assert_eq!(choose(&[1.0, 0.8, 0.5, worse], &[0.0, 0.1, 1.0, 1.0]), 1);
        assert_eq!(choose(&[1.0, 0.8, 0.5, worse], &[0.0, 0.1, 0.2, 1.0]), 2);
    }
}
