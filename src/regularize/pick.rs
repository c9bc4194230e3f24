//! Which pipeline a sequence's target frame comes from, chosen without a reference
//! (issue 56). With OIDN on every frame, the method's frames hold R_s and D in the same
//! paths, and R_s + D is plain volpath's estimate path by path. So the same frames give
//! four images of the target frame:
//!
//! * `Split`: OIDN(R_s) + the blend (Eq. 10) of each frame's OIDN(D_k) — the method;
//! * `Control`: the blend of each frame's OIDN(R_s,k + D_k) — plain radiance through
//!   the same reuse (`--predict plain`), which smears what changes between frames;
//! * `PlainOidn`: OIDN(R_s + D) of the target frame alone;
//! * `Plain`: R_s + D, no denoiser at all.
//!
//! Which is best depends on the scene and the budget (docs/paper.md, the sweep). Two
//! held-out plain renders A and B of the target view at α_t (p spp each, seeds of their
//! own) are independent of all four, so for each candidate Y
//!
//!   E ½[(Y − A)² + (Y − B)²] − E ½(A − B)² = MSE(Y)                                 (K1)
//!
//! (A's variance cancels, `fallback`'s (F1) idea with Y in place of OIDN(M)). The check
//! evaluates (K1) on a window of the image, the central quarter, so that each frame is
//! denoised by both pipelines only there (a crop of the frame around where the window's
//! pixels reproject, with a margin for OIDN's context), and A and B render only the
//! window. The least (K1) wins; the rule takes no margin (a wrong choice happens where
//! the errors are within the estimate's noise, where it costs little). The chosen
//! pipeline then runs on the whole frames; where it denoises less than the split, the
//! time it saves buys more samples first (`DenoiseSeconds`: a frame of an animation
//! made with that pipeline would have spent its budget on them).

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
    PlainOidn,
    Plain,
}

impl Pipeline {
    pub const ALL: [Pipeline; 4] = [
        Pipeline::Split,
        Pipeline::Control,
        Pipeline::PlainOidn,
        Pipeline::Plain,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            Pipeline::Split => "split",
            Pipeline::Control => "control",
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
    /// The window: offset and size in the shot's image, pixels.
    pub window: Window,
    /// Per candidate (`Pipeline::ALL`'s order): (K1) on the window, and the standard
    /// error of its excess over the chosen one's (0 for the chosen).
    pub errors: [(f64, f64); 4],
    pub chosen: Pipeline,
    /// A and B, the crops' denoising, the blends and (K1).
    pub seconds: f64,
    /// OIDN's seconds on a whole frame, estimated from the crops' (scaled by their
    /// pixels): what each pipeline's denoising of a frame costs.
    pub denoise_seconds: DenoiseSeconds,
}

/// OIDN's seconds on one whole frame, per image the pipelines denoise.
#[derive(Clone, Copy, Debug, Default)]
pub struct DenoiseSeconds {
    /// D (signed: two runs), per frame.
    pub difference: f64,
    /// R_s + D, per frame.
    pub plain: f64,
    /// R_s of the target frame.
    pub source: f64,
}

impl DenoiseSeconds {
    /// Seconds the target frame's denoising saves with `p` instead of the split.
    pub fn saved_on_target(&self, p: Pipeline) -> f64 {
        let split = self.difference + self.source;
        match p {
            Pipeline::Split => 0.0,
            Pipeline::Control | Pipeline::PlainOidn => split - self.plain,
            Pipeline::Plain => split,
        }
    }

    /// Seconds an earlier frame's denoising saves with `p` (only the sequence
    /// pipelines denoise earlier frames; the single-frame ones need none).
    pub fn saved_on_earlier(&self, p: Pipeline) -> f64 {
        match p {
            Pipeline::Control => self.difference - self.plain,
            _ => 0.0,
        }
    }
}

/// A rectangle of an image: offset and size in pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Window {
    pub x: usize,
    pub y: usize,
    pub width: usize,
    pub height: usize,
}

impl Window {
    /// The central quarter of a `width` × `height` image (all of a tiny one).
    pub fn central(width: usize, height: usize) -> Window {
        let (w, h) = ((width / 2).max(1), (height / 2).max(1));
        Window {
            x: (width - w) / 2,
            y: (height - h) / 2,
            width: w,
            height: h,
        }
    }

    /// This window of `img`.
    pub fn cut(&self, img: &Image) -> Image {
        let pixels = (0..self.height)
            .flat_map(|j| {
                let start = (self.y + j) * img.width + self.x;
                img.pixels[start..start + self.width].iter().copied()
            })
            .collect();
        Image {
            width: self.width,
            height: self.height,
            pixels,
        }
    }

    /// A `width` × `height` image, zero but for `part` pasted at this window.
    fn paste(&self, part: &Image, width: usize, height: usize) -> Image {
        let mut pixels = vec![[0.0; 3]; width * height];
        for j in 0..self.height {
            let start = (self.y + j) * width + self.x;
            pixels[start..start + self.width]
                .copy_from_slice(&part.pixels[j * self.width..(j + 1) * self.width]);
        }
        Image {
            width,
            height,
            pixels,
        }
    }

    /// The smallest window of a `width` × `height` image holding `MARGIN` pixels around
    /// every position of `points` (None: the whole image).
    fn around(points: impl Iterator<Item = (f32, f32)>, width: usize, height: usize) -> Window {
        let (mut x0, mut y0, mut x1, mut y1) = (f32::MAX, f32::MAX, f32::MIN, f32::MIN);
        for (x, y) in points {
            (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
        }
        if x0 > x1 {
            return Window {
                x: 0,
                y: 0,
                width: 1.min(width),
                height: 1.min(height),
            };
        }
        let lo = |v: f32| (v.floor() as i64 - MARGIN).max(0) as usize;
        let hi = |v: f32, n: usize| ((v.ceil() as i64 + MARGIN).max(1) as usize).min(n);
        let (x, y) = (lo(x0), lo(y0));
        Window {
            x,
            y,
            width: hi(x1, width) - x,
            height: hi(y1, height) - y,
        }
    }
}

/// Pixels of context around a crop OIDN sees (its receptive field is wide; the error of
/// a crop's border pixels decays within a few pixels).
const MARGIN: i64 = 8;

/// The share of the target frame's samples A and B take together (as `fallback`'s).
pub const CHECK_SHARE: f64 = 0.1;

/// One frame of the sequence as rendered, before any denoising.
pub struct RawFrame {
    /// R_s,k: the radiance at the source albedo.
    pub source: Image,
    /// D_k = R(α_t) − R(α_s) in R_s,k's paths.
    pub difference: Image,
    /// The directly seen emission, sharpened (`aovs`).
    pub seen: Image,
    /// The render's seconds (for the time per spp).
    pub render_seconds: f64,
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

/// (K1) on the window for candidate `y` against held-out `a` and `b` (all the window's
/// size), summed per 8×8-pixel block (OIDN's output is correlated between neighbours,
/// blocks nearly are not), and divided by the values' count: the blocks sum to (K1).
fn held_out_blocks(y: &Image, a: &Image, b: &Image) -> Vec<f64> {
    const BLOCK: usize = 8;
    let (w, h) = (y.width, y.height);
    let bw = w.div_ceil(BLOCK);
    let n = (w * h * 3) as f64;
    let mut blocks = vec![0.0f64; bw * h.div_ceil(BLOCK)];
    for j in 0..h {
        for i in 0..w {
            let k = j * w + i;
            for c in 0..3 {
                let [y, a, b] = [y, a, b].map(|img| img.pixels[k][c] as f64);
                // ½[(y − a)² + (y − b)² − (a − b)²] = (y − a)(y − b)
                blocks[(j / BLOCK) * bw + i / BLOCK] += (y - a) * (y - b) / n;
            }
        }
    }
    blocks
}

/// The sum of `blocks` and its standard error (the blocks taken as independent).
fn sum_and_se(blocks: impl ExactSizeIterator<Item = f64> + Clone) -> (f64, f64) {
    let k = blocks.len() as f64;
    let mean = blocks.clone().sum::<f64>() / k;
    let var = blocks.map(|s| (s - mean).powi(2)).sum::<f64>() / (k - 1.0).max(1.0);
    (mean * k, (k * var).sqrt())
}

/// (K1) on the window for candidate `y` against held-out `a` and `b`, and its
/// standard error.
pub fn held_out_error(y: &Image, a: &Image, b: &Image) -> (f64, f64) {
    let blocks = held_out_blocks(y, a, b);
    sum_and_se(blocks.iter().copied())
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

/// (K1) for every candidate on the central window; the least is chosen.
pub fn check(input: &CheckInput) -> Result<PipelineCheck, OidnError> {
    let started = Instant::now();
    let CheckInput {
        scene,
        shot,
        frames,
        maps,
        w_a,
    } = *input;
    let (w, h) = (frames[0].source.width, frames[0].source.height);
    let window = Window::central(w, h);
    // Held-out plain renders of the window, far from every frame's seed (32 bits, as
    // Mitsuba's seeds).
    let p = ((CHECK_SHARE / 2.0 * shot.spp as f64).round() as u32).max(1);
    let held_out = |k: u64| {
        let mut s = shot.with(p, shot.seed.wrapping_add(k * 0x6a09_e667) & 0xffff_ffff);
        let (ox, oy) = s.film.crop_offset;
        s.film.crop_offset = (ox + window.x, oy + window.y);
        s.film.crop_size = (window.width, window.height);
        render(scene, &s, &RenderOptions::default()).image
    };
    let (a, b) = (held_out(7), held_out(8));
    // Per frame, the crop whose denoised pixels the window's blend reads.
    let window_pixels = || {
        (0..window.height)
            .flat_map(move |j| (0..window.width).map(move |i| (window.y + j) * w + window.x + i))
    };
    let crops: Vec<Window> = (0..frames.len())
        .map(|k| match k {
            0 => Window::around(
                [
                    (window.x as f32, window.y as f32),
                    (
                        (window.x + window.width) as f32,
                        (window.y + window.height) as f32,
                    ),
                ]
                .into_iter(),
                w,
                h,
            ),
            _ => Window::around(window_pixels().filter_map(|i| maps[k - 1][i]), w, h),
        })
        .collect();
    // Each pipeline's frames, denoised on their crops only (zero elsewhere), timed
    // per whole frame's worth of pixels.
    let mut differences = Vec::with_capacity(frames.len());
    let mut controls = Vec::with_capacity(frames.len());
    let mut per_pixel = [0.0f64; 3];
    let mut timed = |slot: usize, c: &Window, run: &mut dyn FnMut() -> Result<Image, OidnError>| {
        let start = Instant::now();
        let out = run()?;
        per_pixel[slot] += start.elapsed().as_secs_f64() / (c.width * c.height) as f64;
        Ok::<_, OidnError>(c.paste(&out, w, h))
    };
    for (f, c) in frames.iter().zip(&crops) {
        differences.push(timed(0, c, &mut || {
            denoise::oidn_signed(&c.cut(&f.difference), None, AuxUse::None)
        })?);
        controls.push(timed(1, c, &mut || {
            denoise::oidn(
                &c.cut(&f.plain()),
                Some(&c.cut(&f.seen)),
                None,
                AuxUse::None,
            )
        })?);
    }
    let (f0, c0) = (&frames[0], &crops[0]);
    let source0 = timed(2, c0, &mut || {
        denoise::oidn(
            &c0.cut(&f0.source),
            Some(&c0.cut(&f0.seen)),
            None,
            AuxUse::None,
        )
    })?;
    let n = frames.len() as f64;
    let pixels = (w * h) as f64;
    let denoise_seconds = DenoiseSeconds {
        difference: per_pixel[0] / n * pixels,
        plain: per_pixel[1] / n * pixels,
        source: per_pixel[2] * pixels,
    };
    let blend = |images: &[Image]| {
        let refs: Vec<&[[f32; 3]]> = images.iter().map(|i| i.pixels.as_slice()).collect();
        Image {
            width: w,
            height: h,
            pixels: temporal::blend(&refs, maps, w, h, w_a),
        }
    };
    let candidates = [
        window.cut(&sum(&source0, &blend(&differences))),
        window.cut(&blend(&controls)),
        window.cut(&controls[0]),
        window.cut(&frames[0].plain()),
    ];
    let blocks = candidates.map(|y| held_out_blocks(&y, &a, &b));
    let totals = blocks.each_ref().map(|b| b.iter().sum::<f64>());
    let best = (0..4)
        .min_by(|&i, &j| totals[i].total_cmp(&totals[j]))
        .expect("four candidates");
    // Each candidate against the chosen one, block by block: A's and B's own noise,
    // which dominates each estimate, cancels in the difference.
    let errors = std::array::from_fn(|i| {
        let diff = blocks[i].iter().zip(&blocks[best]).map(|(x, y)| x - y);
        (totals[i], sum_and_se(diff).1)
    });
    Ok(PipelineCheck {
        spp_each: p,
        window,
        errors,
        chosen: Pipeline::ALL[best],
        seconds: started.elapsed().as_secs_f64(),
        denoise_seconds,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Pcg32;

    /// (K1) on images with a known answer: a truth T, held-out A and B = T + noise of
    /// variance σ², and candidates T + b_i (squared errors b_i²). Each estimate must come
    /// out b_i² within 4 of its standard errors, and the least must be the one with the
    /// least b². Seen failing with the ½(A − B)² term left out (every estimate σ² high).
    #[test]
    fn the_held_out_error_measures_a_known_error() {
        let (w, h) = (96, 64);
        let mut rng = Pcg32::new(56, 1);
        let mut gauss = || {
            let (u, v) = (rng.next_1d().max(1e-7), rng.next_1d());
            (-2.0 * u.ln()).sqrt() * (std::f32::consts::TAU * v).cos()
        };
        let truth: Vec<[f32; 3]> = (0..w * h)
            .map(|i| {
                [
                    0.1 + (i % w) as f32 / w as f32,
                    0.5,
                    0.3 + (i / w) as f32 / h as f32,
                ]
            })
            .collect();
        let sigma = 0.05f32;
        let mut noisy = || Image {
            width: w,
            height: h,
            pixels: truth
                .iter()
                .map(|t| t.map(|c| c + sigma * gauss()))
                .collect(),
        };
        let (a, b) = (noisy(), noisy());
        let shifted = |by: f32| Image {
            width: w,
            height: h,
            pixels: truth.iter().map(|t| t.map(|c| c + by)).collect(),
        };
        let biases = [0.02f32, 0.01, 0.03];
        let errors: Vec<(f64, f64)> = biases
            .iter()
            .map(|&b_i| held_out_error(&shifted(b_i), &a, &b))
            .collect();
        for (&b_i, &(e, se)) in biases.iter().zip(&errors) {
            let want = (b_i as f64).powi(2);
            assert!(
                se > 0.0 && (e - want).abs() < 4.0 * se,
                "{e} ± {se} against {want}"
            );
        }
        let least = (0..3).min_by(|&i, &j| errors[i].0.total_cmp(&errors[j].0));
        assert_eq!(least, Some(1));
    }

    #[test]
    fn windows_cut_and_paste_back() {
        let img = Image {
            width: 10,
            height: 6,
            pixels: (0..60).map(|i| [i as f32, 0.0, 1.0]).collect(),
        };
        let win = Window::central(10, 6);
        assert_eq!(
            win,
            Window {
                x: 2,
                y: 1,
                width: 5,
                height: 3
            }
        );
        let part = win.cut(&img);
        assert_eq!(part.pixels[0][0], 12.0);
        assert_eq!(part.pixels[14][0], 36.0);
        let back = win.paste(&part, 10, 6);
        assert_eq!(back.pixels[12], img.pixels[12]);
        assert_eq!(back.pixels[36], img.pixels[36]);
        assert_eq!(back.pixels[0], [0.0; 3]);
        let around = Window::around([(4.5, 3.5)].into_iter(), 10, 6);
        assert_eq!(
            (around.x, around.y, around.width, around.height),
            (0, 0, 10, 6)
        );
    }
}
