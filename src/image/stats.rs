//! Statistical comparison of two Monte Carlo estimates of the same image.
//!
//! Each side gives, per pixel and channel, a mean and the variance of that mean (from
//! independent chunks: `var_mean = s² / k` with `k − 1` degrees of freedom). Under the
//! hypothesis that both estimate the same image:
//!
//! * per value, `z = (m_a − m_b) / √(v_a + v_b)` is approximately Student-t distributed;
//!   we use ν = min(dof_a, dof_b), below Welch's ν, so the tails we assume are heavier
//!   than the true ones (conservative);
//! * a pixel is an outlier when any of its three channels has |z| beyond the two-sided
//!   t quantile at α/3: by the union bound at most α per pixel, however R, G and B move
//!   together (on a grey scene they move as one). Outlier pixels among independent
//!   pixels are Binomial(N, ≤ α), and the test allows the count whose upper tail is below
//!   its share of `false_alarm`;
//! * the same on the means of square blocks of pixels (at α = 1e-2: there are few), which
//!   catches regional differences too small for one pixel that cancel in the image mean;
//! * the image mean per channel, with a t quantile at its share of `false_alarm` split
//!   over the three channels, at the Welch–Satterthwaite degrees of freedom of its
//!   summed variance (a normal quantile where that is exact).
//!
//! Pixels are independent with the box filter (each sample lands in one pixel). A wider
//! reconstruction filter (radius r) splats each sample into every pixel within r, so
//! pixels closer than 2r along x or y share samples ([`PixelLayout::spacing`]):
//! * the pixel test runs on the s × s interleaved lattices of pixels s = ⌈2r⌉ apart,
//!   each a set of independent pixels with its share of the false-alarm budget;
//! * blocks keep a gap of s − 1 pixels between them (only their inner part is used), so
//!   blocks are independent too;
//! * the variance of a sum of pixels is not the sum of their variances: it is
//!   `κ · Σ v`, with the variance inflation `κ = 1 + Σ_i Σ_{j ≠ i, within reach} Cov(i, j)
//!   / Σ_i Var(i)` estimated from the chunks of a side that has them (pooled over the
//!   image: many pairs, so a precise estimate) and used for both sides (same filter, same
//!   sampling). A block loses the covariances across its edge, so the image's κ bounds
//!   its own from above (conservative).

use serde::Serialize;
use statrs::distribution::{Binomial, ContinuousCDF, DiscreteCDF, Normal, StudentsT};

/// How an image's pixels depend on each other: its width and the reconstruction
/// filter's radius in pixels (0.5 for the box filter).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelLayout {
    pub width: usize,
    pub filter_radius: f32,
}

impl PixelLayout {
    /// Independent pixels (the box filter).
    pub fn independent(width: usize) -> PixelLayout {
        PixelLayout {
            width,
            filter_radius: 0.5,
        }
    }

    /// Pixels this many apart along x or y (or more) share no sample: a sample reaches
    /// the pixels within r of it, so two pixels 2r apart have no sample in common. 1 for
    /// the box filter.
    pub fn spacing(&self) -> usize {
        ((2.0 * self.filter_radius - 1e-4).ceil() as usize).max(1)
    }
}

/// Per-value mean and variance of the mean, with its degrees of freedom.
#[derive(Clone, Debug)]
pub struct Estimate {
    pub mean: Vec<[f64; 3]>,
    pub var_mean: Vec<[f64; 3]>,
    pub dof: f64,
    /// Per channel, the variance of a sum of pixels over the sum of their variances
    /// (see the module comment), measured from the chunks; None where the estimate has
    /// no chunks (a reference stores the mean and variance only).
    pub inflation: Option<[f64; 3]>,
}

impl Estimate {
    /// From `k ≥ 2` independent renders of equal sample count, laid out as `layout`.
    pub fn from_chunks(chunks: &[Vec<[f32; 3]>], layout: PixelLayout) -> Estimate {
        let k = chunks.len();
        assert!(k >= 2, "need at least two independent chunks");
        let n = chunks[0].len();
        let mut mean = vec![[0.0; 3]; n];
        let mut var_mean = vec![[0.0; 3]; n];
        for i in 0..n {
            for c in 0..3 {
                let m = chunks.iter().map(|img| img[i][c] as f64).sum::<f64>() / k as f64;
                let s2 = chunks
                    .iter()
                    .map(|img| (img[i][c] as f64 - m).powi(2))
                    .sum::<f64>()
                    / (k - 1) as f64;
                mean[i][c] = m;
                var_mean[i][c] = s2 / k as f64;
            }
        }
        let inflation = Some(inflation(chunks, &mean, &var_mean, layout));
        Estimate {
            mean,
            var_mean,
            dof: (k - 1) as f64,
            inflation,
        }
    }

    /// From a mean and a variance of the mean with `dof` degrees of freedom, without
    /// chunks (a stored reference, or an exact image with zero variance).
    pub fn from_moments(mean: Vec<[f64; 3]>, var_mean: Vec<[f64; 3]>, dof: f64) -> Estimate {
        Estimate {
            mean,
            var_mean,
            dof,
            inflation: None,
        }
    }
}

/// κ per channel: 1 + Σ_i Σ_{j ≠ i within reach} Ĉov(i, j) / Σ_i v̂_i, the pairwise
/// sample covariances of the chunks (bilinear, so the sum over the pairs is the sample
/// variance of the sum without the pairs that share no sample and only add noise).
fn inflation(
    chunks: &[Vec<[f32; 3]>],
    mean: &[[f64; 3]],
    var_mean: &[[f64; 3]],
    layout: PixelLayout,
) -> [f64; 3] {
    let reach = layout.spacing() as isize - 1;
    if reach == 0 {
        return [1.0; 3];
    }
    let (w, n, k) = (layout.width, mean.len(), chunks.len());
    let h = n / w;
    let mut cross = [0.0f64; 3];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            for dy in -reach..=reach {
                for dx in -reach..=reach {
                    let (xj, yj) = (x as isize + dx, y as isize + dy);
                    if (dx, dy) == (0, 0)
                        || xj < 0
                        || yj < 0
                        || xj >= w as isize
                        || yj >= h as isize
                    {
                        continue;
                    }
                    let j = yj as usize * w + xj as usize;
                    for (c, sum) in cross.iter_mut().enumerate() {
                        let cov: f64 = chunks
                            .iter()
                            .map(|img| {
                                (img[i][c] as f64 - mean[i][c]) * (img[j][c] as f64 - mean[j][c])
                            })
                            .sum();
                        // Sample covariance of one chunk, over k for the mean's.
                        *sum += cov / (k - 1) as f64 / k as f64;
                    }
                }
            }
        }
    }
    [0, 1, 2].map(|c| {
        let var: f64 = var_mean.iter().map(|v| v[c]).sum();
        if var > 0.0 {
            // Never below the independent case's 1 by noise alone (conservative).
            (1.0 + cross[c] / var).max(1.0)
        } else {
            1.0
        }
    })
}

/// Outliers among one family of independent values (pixels of one lattice, or blocks):
/// a value is an outlier when any channel's |z| passes the threshold.
#[derive(Clone, Debug, Serialize)]
pub struct OutlierTest {
    /// Values compared (pixels or blocks, each with three channels).
    pub values: usize,
    /// The per-value outlier level (union over the three channels).
    pub alpha: f64,
    /// |z| beyond this is an outlier: the two-sided t quantile at α/3.
    pub threshold: f64,
    pub outliers: usize,
    /// The most outliers Binomial(values, α) allows at the test's share of the
    /// false-alarm probability (summed over the lattices of a filtered image).
    pub allowed: usize,
    pub max_abs_z: f64,
    /// Whether every lattice stayed within its allowance.
    pub passed: bool,
}

#[derive(Clone, Debug, Serialize)]
pub struct Comparison {
    /// z of the image mean, per channel.
    pub global_z: [f64; 3],
    pub global_threshold: f64,
    /// Per pixel (on the independent lattices).
    pub pixels: OutlierTest,
    /// Per `block`×`block` tile of pixels (regional differences too small to stand out
    /// in one pixel, which may cancel in the global mean).
    pub blocks: OutlierTest,
    pub block: usize,
    /// The variance inflation κ used for sums of pixels (1 with independent pixels).
    pub inflation: [f64; 3],
    pub passed: bool,
}

impl std::fmt::Display for Comparison {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (p, b) = (&self.pixels, &self.blocks);
        write!(
            f,
            "{}: global z = [{:.2}, {:.2}, {:.2}] (limit {:.2}); pixel outliers {} of {} with |z| > {:.2} (allowed {}, max |z| {:.2}); {}x{} block outliers {} of {} with |z| > {:.2} (allowed {}, max |z| {:.2})",
            if self.passed { "PASS" } else { "FAIL" },
            self.global_z[0],
            self.global_z[1],
            self.global_z[2],
            self.global_threshold,
            p.outliers,
            p.values,
            p.threshold,
            p.allowed,
            p.max_abs_z,
            self.block,
            self.block,
            b.outliers,
            b.values,
            b.threshold,
            b.allowed,
            b.max_abs_z
        )?;
        if self.inflation != [1.0; 3] {
            write!(
                f,
                "; variance inflation [{:.2}, {:.2}, {:.2}]",
                self.inflation[0], self.inflation[1], self.inflation[2]
            )?;
        }
        Ok(())
    }
}

/// Per-value outlier level of the block test: blocks are few (a 64×64 image has 64 of
/// 8×8), so a larger α keeps the test sensitive while the Binomial allowance keeps the
/// false-alarm probability where it is asked to be.
pub const BLOCK_ALPHA: f64 = 1e-2;
/// Side of the blocks of the regional test with independent pixels, in pixels. With a
/// filter the side is at least 4 spacings, so that the gap between blocks costs little.
pub const BLOCK: usize = 8;

/// z of a difference `d` with variance `v`; a value with zero variance on both sides is
/// deterministic (e.g. a constant environment seen directly): equal up to float32
/// rounding of the same arithmetic done in another order (1e-5 relative, ~100 ulp).
/// A standard deviation below 1e-6 of the value is float32 rounding between chunks
/// (chunk means of a constant that differ in the last bit), not noise: also
/// deterministic. Monte Carlo noise of a chunk mean is orders of magnitude above it.
fn z_of(d: f64, v: f64, a: f64, b: f64) -> f64 {
    let rounding = 1e-6 * a.abs().max(b.abs());
    if v > rounding * rounding {
        d / v.sqrt()
    } else if d.abs() <= 1e-5 * a.abs().max(b.abs()).max(1e-6) {
        0.0
    } else {
        f64::INFINITY
    }
}

/// The most outliers among `n` values with P(outlier) ≤ α: the smallest k with
/// P(Binomial(n, α) > k) < budget.
fn allowance(n: usize, alpha: f64, budget: f64) -> usize {
    if n == 0 {
        return 0;
    }
    let binom = Binomial::new(alpha, n as u64).expect("valid binomial");
    let mut allowed = 0u64;
    while binom.sf(allowed) >= budget {
        allowed += 1;
    }
    allowed as usize
}

/// Above this many degrees of freedom the t quantile is the normal's: statrs' t
/// quantile inverts a regularized incomplete beta whose iteration does not finish at ν
/// near 1e9 (a side's degrees of freedom can be that large), and from here on the two
/// differ by about (z² + 1) / (4ν) of z: 2e-3 even 8σ out.
pub const NORMAL_ABOVE_DOF: f64 = 1e4;

/// The quantile at `p` of Student's t with `nu` degrees of freedom (the normal's above
/// [`NORMAL_ABOVE_DOF`], and where ν is infinite).
pub fn t_quantile(nu: f64, p: f64) -> f64 {
    if nu > NORMAL_ABOVE_DOF {
        Normal::new(0.0, 1.0).expect("valid normal").inverse_cdf(p)
    } else {
        StudentsT::new(0.0, 1.0, nu)
            .expect("valid t distribution")
            .inverse_cdf(p)
    }
}

/// Counts, in each family of independent values (each value's three channel z's), the
/// values with a channel beyond the t quantile at α/3, against Binomial(n, α) at an
/// equal share of `budget` per family.
fn outlier_test(families: &[Vec<[f64; 3]>], alpha: f64, nu: f64, budget: f64) -> OutlierTest {
    let threshold = t_quantile(nu, 1.0 - alpha / 3.0 / 2.0);
    let share = budget / families.len().max(1) as f64;
    let mut test = OutlierTest {
        values: 0,
        alpha,
        threshold,
        outliers: 0,
        allowed: 0,
        max_abs_z: 0.0,
        passed: true,
    };
    for zs in families {
        let max_z = |z: &[f64; 3]| z.iter().fold(0.0f64, |m, z| m.max(z.abs()));
        let outliers = zs.iter().filter(|z| max_z(z) > threshold).count();
        let allowed = allowance(zs.len(), alpha, share);
        test.values += zs.len();
        test.outliers += outliers;
        test.allowed += allowed;
        test.passed &= outliers <= allowed;
        test.max_abs_z = zs.iter().fold(test.max_abs_z, |m, z| m.max(max_z(z)));
    }
    test
}

/// Compares two estimates of an image laid out as `layout`; `alpha` is the per-pixel
/// outlier level, `false_alarm` the probability that two estimates of the same image
/// fail any of the three checks (a third each: pixels, blocks, global mean).
///
/// With a filter wider than a pixel, at least one side must come from chunks
/// ([`Estimate::from_chunks`]), to measure how neighbouring pixels covary.
pub fn compare(
    a: &Estimate,
    b: &Estimate,
    layout: PixelLayout,
    alpha: f64,
    false_alarm: f64,
) -> Comparison {
    assert_eq!(a.mean.len(), b.mean.len(), "images differ in size");
    let width = layout.width;
    assert!(
        width > 0 && a.mean.len().is_multiple_of(width),
        "width does not divide the image"
    );
    let height = a.mean.len() / width;
    let s = layout.spacing();
    let inflation = if s == 1 {
        [1.0; 3]
    } else {
        match (a.inflation, b.inflation) {
            // Both measured: the larger (conservative).
            (Some(ka), Some(kb)) => [0, 1, 2].map(|c| ka[c].max(kb[c])),
            (Some(k), None) | (None, Some(k)) => k,
            (None, None) => panic!(
                "a filtered image's comparison needs one side's chunks to measure how \
                 neighbouring pixels covary (Estimate::from_chunks)"
            ),
        }
    };
    let nu = a.dof.min(b.dof);
    let budget = false_alarm / 3.0;
    // Global: two-sided, split over the 3 channels, at the Welch–Satterthwaite degrees
    // of freedom of the summed variances, ν = (Σ v)² / Σ (v_a² / ν_a + v_b² / ν_b): a few
    // bright, noisy pixels can dominate the sum, and then its estimate is far less sure
    // than the pixel count suggests (the tails of z are heavier than normal).
    let global_nu = (0..3)
        .map(|c| {
            let (mut sum, mut sq) = (0.0f64, 0.0f64);
            for (va, vb) in a.var_mean.iter().zip(&b.var_mean) {
                sum += va[c] + vb[c];
                sq += va[c] * va[c] / a.dof + vb[c] * vb[c] / b.dof;
            }
            if sq > 0.0 {
                sum * sum / sq
            } else {
                f64::INFINITY
            }
        })
        .fold(f64::INFINITY, f64::min);
    let global_p = 1.0 - budget / 3.0 / 2.0;
    let global_threshold = t_quantile(global_nu.max(nu), global_p);

    // z of the mean difference over a set of pixels; Var of a sum = κ Σ v.
    let region_z = |pixels: &mut dyn Iterator<Item = usize>| -> [f64; 3] {
        let (mut d, mut v, mut ma, mut mb, mut n) = ([0.0; 3], [0.0; 3], [0.0; 3], [0.0; 3], 0.0);
        for i in pixels {
            for c in 0..3 {
                d[c] += a.mean[i][c] - b.mean[i][c];
                v[c] += a.var_mean[i][c] + b.var_mean[i][c];
                ma[c] += a.mean[i][c];
                mb[c] += b.mean[i][c];
            }
            n += 1.0;
        }
        [0, 1, 2].map(|c| {
            z_of(
                d[c] / n,
                inflation[c] * v[c] / (n * n),
                ma[c] / n,
                mb[c] / n,
            )
        })
    };

    // Pixels: one family per lattice of pixels `s` apart.
    let mut lattices = vec![Vec::new(); s * s];
    for y in 0..height {
        for x in 0..width {
            let i = y * width + x;
            let z = [0, 1, 2].map(|c| {
                z_of(
                    a.mean[i][c] - b.mean[i][c],
                    a.var_mean[i][c] + b.var_mean[i][c],
                    a.mean[i][c],
                    b.mean[i][c],
                )
            });
            lattices[(y % s) * s + x % s].push(z);
        }
    }
    // Blocks: tiles of side `block`, of which the inner `block − (s − 1)` pixels are used,
    // so that no two blocks share a sample.
    let block = BLOCK.max(4 * s);
    let inner = block - (s - 1);
    let mut blocks = Vec::new();
    for by in (0..height).step_by(block) {
        for bx in (0..width).step_by(block) {
            let (y1, x1) = ((by + inner).min(height), (bx + inner).min(width));
            blocks.push(region_z(
                &mut (by..y1).flat_map(|y| (bx..x1).map(move |x| y * width + x)),
            ));
        }
    }
    let global_z = region_z(&mut (0..a.mean.len()));
    let pixels = outlier_test(&lattices, alpha, nu, budget);
    let blocks = outlier_test(&[blocks], BLOCK_ALPHA.max(alpha), nu, budget);
    let passed =
        global_z.iter().all(|z| z.abs() <= global_threshold) && pixels.passed && blocks.passed;
    Comparison {
        global_z,
        global_threshold,
        pixels,
        blocks,
        block,
        inflation,
        passed,
    }
}

#[cfg(test)]
mod tests;
