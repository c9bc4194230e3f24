//! Mitsuba 3's `hdrfilm` and its reconstruction filters (`src/films/hdrfilm.cpp`,
//! `src/render/imageblock.cpp`, `src/rfilters/`).
//!
//! A sample at continuous film position `pos` (pixel `i` covers [i, i+1)) adds
//! `w(x)·w(y)·L` and `w(x)·w(y)` to every pixel whose center lies within the filter
//! radius; the developed pixel is Σ w L / Σ w. The box filter takes Mitsuba's fast path:
//! the sample goes to pixel ⌊pos⌋ with weight 1.

use glam::{Vec3, Vec4};

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Rfilter {
    /// radius 0.5
    Box,
    /// max(0, 1 − |x| / radius), default radius 1
    Tent { radius: f32 },
    /// max(0, exp(−x²/2σ²) − exp(−r²/2σ²)), r = 4σ, default σ = 0.5
    Gaussian { stddev: f32 },
}

impl Rfilter {
    pub fn radius(&self) -> f32 {
        match self {
            Rfilter::Box => 0.5,
            Rfilter::Tent { radius } => *radius,
            Rfilter::Gaussian { stddev } => 4.0 * stddev,
        }
    }

    #[inline]
    pub fn eval(&self, x: f32) -> f32 {
        self.evaluator().eval(x)
    }

    /// The filter with its constants worked out once, for the many weights of a splat.
    #[inline]
    fn evaluator(&self) -> FilterEval {
        match *self {
            Rfilter::Gaussian { stddev } => {
                let alpha = -1.0 / (2.0 * stddev * stddev);
                let r = 4.0 * stddev;
                FilterEval::Gaussian {
                    alpha,
                    floor: (alpha * r * r).exp(),
                }
            }
            Rfilter::Tent { radius } => FilterEval::Tent { radius },
            Rfilter::Box => FilterEval::Box,
        }
    }

    /// How many pixels beyond a block's edge a sample can reach.
    pub fn border(&self) -> usize {
        match self {
            Rfilter::Box => 0,
            _ => (self.radius() - 0.5).ceil().max(0.0) as usize,
        }
    }
}

/// [`Rfilter`] ready to evaluate: a Gaussian's constants computed (Mitsuba's
/// `gaussian`: e^{−x²/(2σ²)} − e^{−r²/(2σ²)}, clamped at 0, radius r = 4σ).
#[derive(Clone, Copy)]
enum FilterEval {
    Box,
    Tent { radius: f32 },
    Gaussian { alpha: f32, floor: f32 },
}

impl FilterEval {
    #[inline]
    fn eval(&self, x: f32) -> f32 {
        match *self {
            FilterEval::Gaussian { alpha, floor } => ((alpha * x * x).exp() - floor).max(0.0),
            FilterEval::Box => {
                if (-0.5..0.5).contains(&x) {
                    1.0
                } else {
                    0.0
                }
            }
            FilterEval::Tent { radius } => (1.0 - (x / radius).abs()).max(0.0),
        }
    }
}

/// What `hdrfilm` writes (its `pixel_format`): the colour as RGB or as luminance, with or
/// without alpha (Mitsuba's `valid_ray`: 1 where a sample's path met something).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PixelFormat {
    #[default]
    Rgb,
    Rgba,
    Luminance,
    LuminanceAlpha,
}

impl PixelFormat {
    pub const ALL: [PixelFormat; 4] = [
        PixelFormat::Rgb,
        PixelFormat::Rgba,
        PixelFormat::Luminance,
        PixelFormat::LuminanceAlpha,
    ];

    pub fn name(self) -> &'static str {
        match self {
            PixelFormat::Rgb => "rgb",
            PixelFormat::Rgba => "rgba",
            PixelFormat::Luminance => "luminance",
            PixelFormat::LuminanceAlpha => "luminance_alpha",
        }
    }

    pub fn has_alpha(self) -> bool {
        matches!(self, PixelFormat::Rgba | PixelFormat::LuminanceAlpha)
    }

    pub fn is_luminance(self) -> bool {
        matches!(self, PixelFormat::Luminance | PixelFormat::LuminanceAlpha)
    }
}

pub use crate::image::component_format::{
    dequantize_uint32, quantize_uint32, ComponentFormat, UINT32_CLAMP,
};

/// Mitsuba's `luminance`: Y of a linear sRGB colour.
pub fn luminance(c: [f32; 3]) -> f32 {
    c[0] * 0.212671 + c[1] * 0.715160 + c[2] * 0.072169
}

#[derive(Clone, Debug)]
pub struct Film {
    /// Full film size.
    pub width: usize,
    pub height: usize,
    /// The crop window (the output image): offset and size in pixels.
    pub crop_offset: (usize, usize),
    pub crop_size: (usize, usize),
    pub rfilter: Rfilter,
    pub pixel_format: PixelFormat,
    pub component_format: ComponentFormat,
}

/// A rectangle of accumulated samples (Σ w·L and Σ w per pixel), with a border wide
/// enough for the filter. Coordinates are in crop-window pixels.
pub struct ImageBlock {
    pub offset: (i64, i64),
    pub size: (usize, usize),
    pub border: usize,
    /// Per pixel: (Σ wL).rgb, Σ w
    pub data: Vec<[f32; 4]>,
}

impl ImageBlock {
    pub fn new(offset: (i64, i64), size: (usize, usize), border: usize) -> Self {
        let w = size.0 + 2 * border;
        let h = size.1 + 2 * border;
        ImageBlock {
            offset,
            size,
            border,
            data: vec![[0.0; 4]; w * h],
        }
    }

    pub fn clear(&mut self) {
        self.data.fill([0.0; 4]);
    }

    fn full_width(&self) -> usize {
        self.size.0 + 2 * self.border
    }

    /// Splats radiance `l` at crop-relative position `pos`.
    #[inline]
    pub fn put(&mut self, pos: (f32, f32), l: Vec3, filter: &Rfilter) {
        let b = self.border as f32;
        let fw = self.full_width();
        let fh = self.size.1 + 2 * self.border;
        let px = pos.0 - self.offset.0 as f32 + b;
        let py = pos.1 - self.offset.1 as f32 + b;
        if let Rfilter::Box = filter {
            let (ix, iy) = (px.floor(), py.floor());
            if ix >= 0.0 && iy >= 0.0 && (ix as usize) < fw && (iy as usize) < fh {
                let p = &mut self.data[iy as usize * fw + ix as usize];
                p[0] += l.x;
                p[1] += l.y;
                p[2] += l.z;
                p[3] += 1.0;
            }
            return;
        }
        let r = filter.radius();
        let filter = filter.evaluator();
        // Pixel centers at i + 0.5.
        let cx = px - 0.5;
        let cy = py - 0.5;
        let x0 = (cx - r).ceil().max(0.0) as usize;
        let x1 = ((cx + r).floor() as i64).min(fw as i64 - 1);
        let y0 = (cy - r).ceil().max(0.0) as usize;
        let y1 = ((cy + r).floor() as i64).min(fh as i64 - 1);
        if x1 < x0 as i64 || y1 < y0 as i64 {
            return;
        }
        // The filter is separable: a pixel's weight is w(x)·w(y), so each w(x) and
        // w(y) is evaluated once, not once per pixel (a Gaussian's exp dominated the
        // splat); a Gaussian's eight at a time in SIMD lanes where they fit.
        const MAX_COLUMNS: usize = 16;
        let columns = x1 as usize + 1 - x0;
        let rows = y1 as usize + 1 - y0;
        let mut wx = [0.0f32; MAX_COLUMNS];
        let mut wy = [0.0f32; MAX_COLUMNS];
        let l1 = Vec4::new(l.x, l.y, l.z, 1.0);
        if columns > MAX_COLUMNS || rows > MAX_COLUMNS {
            return self.put_weights_unbounded(
                filter,
                (x0, x1 as usize, cx),
                (y0, y1 as usize, cy),
                l1,
            );
        }
        match filter {
            FilterEval::Gaussian { alpha, floor } if columns <= 8 && rows <= 8 => {
                let g = |start: f32| {
                    let x = wide::f32x8::splat(start)
                        + wide::f32x8::from([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);
                    ((x * x * alpha).exp() - floor)
                        .max(wide::f32x8::ZERO)
                        .to_array()
                };
                wx[..8].copy_from_slice(&g(x0 as f32 - cx));
                wy[..8].copy_from_slice(&g(y0 as f32 - cy));
            }
            _ => {
                for (i, w) in wx[..columns].iter_mut().enumerate() {
                    *w = filter.eval((x0 + i) as f32 - cx);
                }
                for (i, w) in wy[..rows].iter_mut().enumerate() {
                    *w = filter.eval((y0 + i) as f32 - cy);
                }
            }
        }
        for (y, &wy) in (y0..=y1 as usize).zip(&wy[..rows]) {
            if wy == 0.0 {
                continue;
            }
            let row = &mut self.data[y * fw + x0..y * fw + x0 + columns];
            for (p, &wx) in row.iter_mut().zip(&wx[..columns]) {
                add_weighted(p, l1, wy * wx);
            }
        }
    }

    /// [`ImageBlock::put`]'s splat for a filter wider than its weight arrays: every
    /// weight evaluated where it is used.
    #[cold]
    fn put_weights_unbounded(
        &mut self,
        filter: FilterEval,
        (x0, x1, cx): (usize, usize, f32),
        (y0, y1, cy): (usize, usize, f32),
        l1: Vec4,
    ) {
        let fw = self.full_width();
        for y in y0..=y1 {
            let wy = filter.eval(y as f32 - cy);
            if wy == 0.0 {
                continue;
            }
            for x in x0..=x1 {
                add_weighted(
                    &mut self.data[y * fw + x],
                    l1,
                    wy * filter.eval(x as f32 - cx),
                );
            }
        }
    }

    /// Adds this block into `target` (a block covering the whole crop, border included).
    pub fn accumulate_into(&self, target: &mut ImageBlock) {
        let fw = self.full_width();
        let tw = target.full_width();
        let th = (target.size.1 + 2 * target.border) as i64;
        for (i, v) in self.data.iter().enumerate() {
            let x = (i % fw) as i64 + self.offset.0 - self.border as i64 + target.border as i64
                - target.offset.0;
            let y = (i / fw) as i64 + self.offset.1 - self.border as i64 + target.border as i64
                - target.offset.1;
            if x < 0 || y < 0 || x >= tw as i64 || y >= th {
                continue;
            }
            let t = &mut target.data[y as usize * tw + x as usize];
            for k in 0..4 {
                t[k] += v[k];
            }
        }
    }

    /// The developed image (interior only): Σ w L / Σ w, row-major RGB.
    pub fn develop(&self) -> Vec<[f32; 3]> {
        self.develop_by(self)
    }

    /// The weight sums Σ w of the interior, row-major: with `develop`'s image, what
    /// joins renders of one film into the render of all their samples
    /// (`image::merge::mean_by_weights`).
    pub fn weight_sums(&self) -> Vec<f32> {
        let fw = self.full_width();
        (0..self.size.1)
            .flat_map(|y| (0..self.size.0).map(move |x| (y + self.border) * fw + x + self.border))
            .map(|i| self.data[i][3])
            .collect()
    }

    /// Σ wL over the weight sums Σ w of `weights`, a block of the same shape that
    /// received every sample this one received (and others of value zero).
    pub fn develop_by(&self, weights: &ImageBlock) -> Vec<[f32; 3]> {
        assert_eq!((self.size, self.border), (weights.size, weights.border));
        let fw = self.full_width();
        let mut out = Vec::with_capacity(self.size.0 * self.size.1);
        for y in 0..self.size.1 {
            for x in 0..self.size.0 {
                let i = (y + self.border) * fw + x + self.border;
                let (p, w) = (self.data[i], weights.data[i][3]);
                out.push(if w > 0.0 {
                    [p[0] / w, p[1] / w, p[2] / w]
                } else {
                    [0.0; 3]
                });
            }
        }
        out
    }
}

/// Adds `w · (L, 1)` to a pixel's (Σ wL, Σ w), as one 4-wide vector: the same products
/// and sums as channel by channel.
#[inline(always)]
fn add_weighted(pixel: &mut [f32; 4], l1: Vec4, w: f32) {
    *pixel = (Vec4::from_array(*pixel) + l1 * w).to_array();
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Mitsuba 3's uint32 quantization at values worked by hand: v · 2^32 rounded to
    /// nearest even, negative values 0, 1 and above the largest f32 under 2^32; read
    /// back as v to f32 precision.
    #[test]
    fn gaussian_filter_vanishes_at_radius() {
        let g = Rfilter::Gaussian { stddev: 0.5 };
        assert_eq!(g.radius(), 2.0);
        assert!(g.eval(2.0).abs() < 1e-7 && g.eval(0.0) > 0.99);
    }

    #[test]
    fn splat_normalizes_to_the_sample_value() {
        for f in [
            Rfilter::Box,
            Rfilter::Tent { radius: 1.0 },
            Rfilter::Gaussian { stddev: 0.5 },
        ] {
            let mut b = ImageBlock::new((0, 0), (4, 4), f.border());
            b.put((1.3, 2.7), Vec3::splat(2.0), &f);
            let img = b.develop();
            let covered: Vec<_> = img.iter().filter(|p| p[0] > 0.0).collect();
            assert!(!covered.is_empty());
            for p in covered {
                assert!((p[0] - 2.0).abs() < 1e-5, "{f:?}: {p:?}");
            }
        }
    }

    /// A block that skipped its zero-valued samples, developed by the weights of one
    /// that took them all, is the block that took them all, to the bit (what
    /// `render`'s optional images rely on); a block missing a nonzero sample is not.
    #[test]
    fn developing_by_anothers_weights_skips_zero_samples_exactly() {
        let mut rng = crate::sampling::Pcg32::new(9, 2);
        let f = Rfilter::Gaussian { stddev: 0.5 };
        let (mut all, mut nonzero, mut short) = (
            ImageBlock::new((0, 0), (8, 6), f.border()),
            ImageBlock::new((0, 0), (8, 6), f.border()),
            ImageBlock::new((0, 0), (8, 6), f.border()),
        );
        for i in 0..500 {
            let pos = (rng.next_1d() * 8.0, rng.next_1d() * 6.0);
            let v = match rng.next_1d() < 0.7 {
                true => Vec3::ZERO,
                false => Vec3::new(rng.next_1d(), 2.0, rng.next_1d()),
            };
            all.put(pos, v, &f);
            if v != Vec3::ZERO {
                nonzero.put(pos, v, &f);
                if i % 7 != 0 {
                    short.put(pos, v, &f); // misses some nonzero samples
                }
            }
        }
        assert_eq!(nonzero.develop_by(&all), all.develop());
        assert_ne!(short.develop_by(&all), all.develop());
        assert_ne!(nonzero.develop(), all.develop(), "its own weights differ");
    }

    /// Every pixel's weight in a splat is w(x)·w(y) of its centre's offsets, to f32
    /// rounding (the Gaussian's weights come from a SIMD exp, the rest from `eval`),
    /// for filters of every width the splat handles, near the block's edges too.
    #[test]
    fn splat_weights_are_the_filters() {
        let mut rng = crate::sampling::Pcg32::new(5, 1);
        for f in [
            Rfilter::Tent { radius: 1.0 },
            Rfilter::Tent { radius: 2.5 },
            Rfilter::Gaussian { stddev: 0.5 },
            Rfilter::Gaussian { stddev: 0.3 },
            Rfilter::Gaussian { stddev: 1.0 },
            Rfilter::Gaussian { stddev: 2.5 },
        ] {
            let size = (12, 9);
            for _ in 0..200 {
                let pos = (rng.next_1d() * 12.0, rng.next_1d() * 9.0);
                let mut b = ImageBlock::new((0, 0), size, f.border());
                b.put(pos, Vec3::ONE, &f);
                let fw = b.full_width();
                let border = b.border as f32;
                for (i, p) in b.data.iter().enumerate() {
                    let (x, y) = ((i % fw) as f32, (i / fw) as f32);
                    let dx = x + 0.5 - (pos.0 + border);
                    let dy = y + 0.5 - (pos.1 + border);
                    let inside = dx.abs() <= f.radius() && dy.abs() <= f.radius();
                    let want = if inside { f.eval(dx) * f.eval(dy) } else { 0.0 };
                    assert!(
                        (p[3] - want).abs() <= 1e-6 * want.max(1e-3),
                        "{f:?} at {pos:?}, pixel ({x}, {y}): {} vs {want}",
                        p[3]
                    );
                }
            }
        }
    }
}
