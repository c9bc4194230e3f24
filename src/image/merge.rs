//! Merging renders of one shot made in chunks (distinct seeds, spp each), on one
//! machine or many: the mean weighted by samples, and the variance of that mean from
//! the chunks' spread, as `scripts/mitsuba_reference.py` writes a reference's.
//!
//! Chunk k holds the mean x_k of n_k independent samples of per-sample variance σ²
//! (per pixel and channel), so Var(x_k) = σ²/n_k. With N = Σ n_k:
//!
//! * (M1) the merged mean x̄ = Σ n_k x_k / N, of variance σ²/N;
//! * (M2) σ̂² = Σ n_k (x_k − x̄)² / (K − 1) is unbiased for σ² (each term has
//!   expectation n_k Var(x_k − x̄) = σ² (1 − n_k/N), summing to (K − 1) σ²);
//! * (M3) the variance of the merged mean, σ̂²/N, with K − 1 degrees of freedom.

use std::path::{Path, PathBuf};

use anyhow::{bail, Result};

use super::{read_exr, read_exr_int_attribute, Image};

/// The merged image of several chunks.
#[derive(Clone, Debug)]
pub struct Merged {
    /// (M1): the mean over every chunk's samples.
    pub mean: Image,
    /// (M3): the variance of `mean`, per pixel and channel; `None` for one chunk.
    pub var: Option<Image>,
    /// N, the samples per pixel of all chunks together.
    pub spp: u64,
    /// K, the number of chunks.
    pub chunks: usize,
}

/// Merges chunk images with their samples per pixel (Eq. M1–M3).
pub fn merge(chunks: &[(Image, u64)]) -> Result<Merged> {
    let Some((first, _)) = chunks.first() else {
        bail!("no chunks to merge");
    };
    let (w, h) = (first.width, first.height);
    let spp: u64 = chunks.iter().map(|(_, n)| n).sum();
    if spp == 0 {
        bail!("the chunks hold no samples");
    }
    let total = spp as f64;
    let mean = weighted_mean(chunks.iter().map(|(img, n)| (img, *n)), w * h, total);
    let var = (chunks.len() > 1).then(|| {
        let mut ss = vec![[0f64; 3]; w * h];
        for (img, n) in chunks {
            for ((s, m), p) in ss.iter_mut().zip(&mean).zip(&img.pixels) {
                for c in 0..3 {
                    let d = p[c] as f64 - m[c];
                    s[c] += *n as f64 * d * d;
                }
            }
        }
        let scale = 1.0 / ((chunks.len() - 1) as f64 * total);
        to_image(w, h, ss.iter().map(|s| s.map(|v| v * scale)))
    });
    Ok(Merged {
        mean: to_image(w, h, mean.into_iter()),
        var,
        spp,
        chunks: chunks.len(),
    })
}

/// (M1): Σ n_k x_k / N over `chunks` of `len` pixels, N = `total`.
fn weighted_mean<'a>(
    chunks: impl Iterator<Item = (&'a Image, u64)>,
    len: usize,
    total: f64,
) -> Vec<[f64; 3]> {
    let mut mean = vec![[0f64; 3]; len];
    for (img, n) in chunks {
        for (m, p) in mean.iter_mut().zip(&img.pixels) {
            for c in 0..3 {
                m[c] += n as f64 * p[c] as f64 / total;
            }
        }
    }
    mean
}

/// Renders of one film joined as one: per pixel Σ_r W_r L_r / Σ_r W_r, W_r the sum of
/// the filter weights render r gave the pixel. For renders of disjoint sample ranges of
/// one seed this is the render of all their samples, up to rounding (a pixel's image is
/// Σ wL / Σ w over its samples); (M1) is that only for a box filter.
pub fn mean_by_weights(renders: &[(&Image, &[f32])]) -> Image {
    let first = renders[0].0;
    let pixels = (0..first.pixels.len()).map(|i| {
        let (mut sum, mut weight) = ([0f64; 3], 0f64);
        for (img, w) in renders {
            let w = w[i] as f64;
            weight += w;
            for (s, v) in sum.iter_mut().zip(img.pixels[i]) {
                *s += w * v as f64;
            }
        }
        match weight > 0.0 {
            true => sum.map(|v| v / weight),
            false => [0.0; 3],
        }
    });
    to_image(first.width, first.height, pixels)
}

/// (M1) alone, for images of one size already in memory: the mean of renders of one
/// shot weighted by their samples per pixel (no variance, no checks of the headers).
pub fn mean_by_spp(chunks: &[(&Image, u64)]) -> Image {
    let first = chunks[0].0;
    let total = chunks.iter().map(|(_, n)| *n).sum::<u64>() as f64;
    let mean = weighted_mean(chunks.iter().copied(), first.pixels.len(), total);
    to_image(first.width, first.height, mean.into_iter())
}

fn to_image(width: usize, height: usize, px: impl Iterator<Item = [f64; 3]>) -> Image {
    Image {
        width,
        height,
        pixels: px.map(|p| p.map(|v| v as f32)).collect(),
    }
}

/// Writes a merge: `out` (the mean, its header's spp the chunks' total) and, with two
/// chunks or more, `out`_var.exr (the variance of the mean). Returns the files written.
pub fn write_merged(out: &Path, merged: &Merged) -> Result<Vec<PathBuf>> {
    super::write_render_exr(out, &merged.mean, Some(merged.spp))?;
    let mut written = vec![out.to_path_buf()];
    if let Some(var) = &merged.var {
        let out_var = super::sibling(out, "_var");
        super::write_render_exr(&out_var, var, Some(merged.spp))?;
        written.push(out_var);
    }
    Ok(written)
}

/// Reads chunk EXRs written by `mediareg render` (their header's `spp` says how many
/// samples each holds) and merges them. Each file must have the first's size, an spp,
/// and only finite values.
pub fn merge_files(paths: &[PathBuf]) -> Result<Merged> {
    let mut chunks = Vec::with_capacity(paths.len());
    for path in paths {
        chunks.push(read_chunk(path)?);
        let (first, this) = (&chunks[0].0, &chunks.last().expect("just pushed").0);
        if (this.width, this.height) != (first.width, first.height) {
            bail!(
                "{}: {}x{}, but {} is {}x{}: the chunks of one merge must be renders of one shot",
                path.display(),
                this.width,
                this.height,
                paths[0].display(),
                first.width,
                first.height
            );
        }
    }
    merge(&chunks)
}

fn read_chunk(path: &Path) -> Result<(Image, u64)> {
    let img = read_exr(path)?;
    if let Some(i) = img
        .pixels
        .iter()
        .position(|p| p.iter().any(|v| !v.is_finite()))
    {
        bail!(
            "{}: pixel ({}, {}) is not finite; a chunk with NaN or Inf cannot be merged",
            path.display(),
            i % img.width.max(1),
            i / img.width.max(1)
        );
    }
    let spp = match read_exr_int_attribute(path, "spp")? {
        Some(n) if n > 0 => n as u64,
        Some(n) => bail!("{}: the header's spp is {n}; a chunk needs at least one sample", path.display()),
        None => bail!(
            "{}: no \"spp\" in the EXR header, so its weight is unknown: merge the EXRs `mediareg render` writes (or `mediareg merge` itself)",
            path.display()
        ),
    };
    Ok((img, spp))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn img(px: &[[f32; 3]]) -> Image {
        Image {
            width: px.len(),
            height: 1,
            pixels: px.to_vec(),
        }
    }

    /// M1–M3 by hand for two pixels and three chunks of unequal spp.
    #[test]
    fn weighted_mean_and_variance_of_the_mean() {
        let chunks = [
            (img(&[[1.0, 2.0, 3.0], [0.0; 3]]), 1),
            (img(&[[3.0, 2.0, 1.0], [0.0; 3]]), 3),
            (img(&[[2.0, 2.0, 2.0], [4.0; 3]]), 4),
        ];
        let m = merge(&chunks).unwrap();
        assert_eq!(m.spp, 8);
        let mean_r = (1.0 + 9.0 + 8.0) / 8.0;
        assert!((m.mean.pixels[0][0] - mean_r).abs() < 1e-6);
        assert_eq!(m.mean.pixels[0][1], 2.0);
        let ss = 1.0 * (1.0 - mean_r).powi(2)
            + 3.0 * (3.0 - mean_r).powi(2)
            + 4.0 * (2.0 - mean_r).powi(2);
        let var = m.var.unwrap();
        assert!((var.pixels[0][0] - ss / (2.0 * 8.0)).abs() < 1e-6);
        assert_eq!(var.pixels[0][1], 0.0);
        // Pixel 1: mean 2, deviations -2, -2, 2.
        assert!((var.pixels[1][2] - (4.0 + 12.0 + 16.0) / 16.0).abs() < 1e-6);
    }

    /// With equal spp, M3 is the chunks' sample variance over K (what the references
    /// write), and one chunk has no variance.
    #[test]
    fn equal_chunks_give_the_sample_variance_over_k() {
        let xs = [0.5f32, 1.5, 0.25, 2.0];
        let chunks: Vec<_> = xs.iter().map(|&x| (img(&[[x; 3]]), 16)).collect();
        let m = merge(&chunks).unwrap();
        let mu = xs.iter().sum::<f32>() / 4.0;
        let s2 = xs.iter().map(|x| (x - mu).powi(2)).sum::<f32>() / 3.0;
        assert!((m.var.unwrap().pixels[0][0] - s2 / 4.0).abs() < 1e-6);
        assert!(merge(&chunks[..1]).unwrap().var.is_none());
        assert!(merge(&[]).is_err());
    }
}
