//! Mitsuba 3's `bitmap` texture (`src/textures/bitmap.cpp`, Dr.Jit's `Texture2f`) in
//! RGB mode: an image looked up at uv' = to_uv · uv, where u runs along the image's
//! columns and v down its rows (v = 0 is the first row of the file).
//!
//! * `bilinear` (default): with p = uv' · (W, H) − ½, the four texels around p are
//!   blended by the fractional parts; `nearest`: the texel ⌊uv' · (W, H)⌋.
//! * Texel indices outside the image wrap (`repeat`, the default), reflect (`mirror`,
//!   the edge texel repeated) or clamp (`clamp`).
//! * 8-bit images are sRGB-encoded: each texel is decoded to linear before the blend
//!   (as Mitsuba decodes stored bytes per texel on lookup), unless `raw` is true.
//!   16-bit PNGs are decoded the same way; float data (EXR, RGBE, PFM) is linear.
//!   Which files are read and how: `bitmap_file`.

use glam::{Vec2, Vec3};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FilterType {
    Bilinear,
    Nearest,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WrapMode {
    Repeat,
    Mirror,
    Clamp,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Bitmap {
    pub width: usize,
    pub height: usize,
    /// Linear RGB, row-major from the first row of the file.
    pub texels: Vec<Vec3>,
    pub filter: FilterType,
    pub wrap: WrapMode,
    /// The 2D affine `to_uv`: rows (a, b, tx) and (c, d, ty).
    pub to_uv: [[f32; 3]; 2],
}

impl WrapMode {
    /// The texel index for integer coordinate `i` along an axis of `n` texels.
    #[inline]
    fn wrap(self, i: i64, n: usize) -> usize {
        let n = n as i64;
        let j = match self {
            WrapMode::Repeat => i.rem_euclid(n),
            WrapMode::Clamp => i.clamp(0, n - 1),
            WrapMode::Mirror => {
                // Period 2n: 0 … n−1, then n−1 … 0.
                let k = i.rem_euclid(2 * n);
                if k < n {
                    k
                } else {
                    2 * n - 1 - k
                }
            }
        };
        j as usize
    }
}

impl Bitmap {
    #[inline]
    fn texel(&self, x: i64, y: i64) -> Vec3 {
        let x = self.wrap.wrap(x, self.width);
        let y = self.wrap.wrap(y, self.height);
        self.texels[y * self.width + x]
    }

    #[inline]
    pub fn eval(&self, uv: Vec2) -> Vec3 {
        let Vec2 { x: u, y: v } = super::uv::apply_to_uv(&self.to_uv, uv);
        let (px, py) = (u * self.width as f32, v * self.height as f32);
        match self.filter {
            FilterType::Nearest => self.texel(px.floor() as i64, py.floor() as i64),
            FilterType::Bilinear => {
                let (px, py) = (px - 0.5, py - 0.5);
                let (x0, y0) = (px.floor(), py.floor());
                let (wx, wy) = (px - x0, py - y0);
                let (x0, y0) = (x0 as i64, y0 as i64);
                let row0 = self.texel(x0, y0) * (1.0 - wx) + self.texel(x0 + 1, y0) * wx;
                let row1 = self.texel(x0, y0 + 1) * (1.0 - wx) + self.texel(x0 + 1, y0 + 1) * wx;
                row0 * (1.0 - wy) + row1 * wy
            }
        }
    }

    /// The mean luminance of the texels (Mitsuba's `Texture::mean` of a bitmap in RGB
    /// mode, with its Rec. 709 weights).
    pub fn mean(&self) -> f32 {
        let weights = Vec3::new(0.212_671, 0.715_160, 0.072_169);
        let sum: f32 = self.texels.iter().map(|t| t.dot(weights)).sum();
        sum / self.texels.len() as f32
    }

    pub fn max_value(&self) -> f32 {
        self.texels
            .iter()
            .fold(0.0f32, |m, t| m.max(t.max_element()))
    }
}

#[cfg(test)]
mod tests {
    use super::super::bitmap_file::{read_texels, srgb_to_linear};
    use super::*;
    use std::path::Path;

    fn bitmap(filter: FilterType, wrap: WrapMode) -> Bitmap {
        // 2 × 2: black, red / green, white.
        Bitmap {
            width: 2,
            height: 2,
            texels: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::ONE],
            filter,
            wrap,
            to_uv: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        }
    }

    #[test]
    fn bilinear_blends_texel_centres() {
        let b = bitmap(FilterType::Bilinear, WrapMode::Clamp);
        // Texel centres sit at (i + ½)/n.
        assert_eq!(b.eval(Vec2::new(0.25, 0.25)), Vec3::ZERO);
        assert_eq!(b.eval(Vec2::new(0.75, 0.25)), Vec3::X);
        assert_eq!(b.eval(Vec2::new(0.25, 0.75)), Vec3::Y);
        let mid = b.eval(Vec2::new(0.5, 0.5));
        assert!(
            (mid - Vec3::new(0.5, 0.5, 0.25)).abs().max_element() < 1e-6,
            "{mid}"
        );
    }

    #[test]
    fn wrap_modes() {
        // Half a texel left of u = 0, at the first row's centre: repeat blends the last
        // column in, clamp and mirror repeat the first.
        let uv = Vec2::new(-0.25, 0.25);
        assert_eq!(
            bitmap(FilterType::Bilinear, WrapMode::Repeat).eval(uv),
            Vec3::X
        );
        assert_eq!(
            bitmap(FilterType::Bilinear, WrapMode::Clamp).eval(uv),
            Vec3::ZERO
        );
        assert_eq!(
            bitmap(FilterType::Bilinear, WrapMode::Mirror).eval(uv),
            Vec3::ZERO
        );
        // Mirror reflects: u in (1, 1.5) reads the second column, then the first.
        let m = bitmap(FilterType::Nearest, WrapMode::Mirror);
        assert_eq!(m.eval(Vec2::new(1.25, 0.25)), Vec3::X);
        assert_eq!(m.eval(Vec2::new(1.75, 0.25)), Vec3::ZERO);
        let r = bitmap(FilterType::Nearest, WrapMode::Repeat);
        assert_eq!(r.eval(Vec2::new(1.25, 0.25)), Vec3::ZERO);
    }

    #[test]
    fn srgb_decoding() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
        // 0.5 encoded is about 0.214 linear.
        assert!((srgb_to_linear(0.5) - 0.214_041).abs() < 1e-5);
    }

    /// Lookups of `mitsuba_scenes/textures/tiles.png` against Mitsuba 3.9.1 (`bitmap`
    /// plugin made by `mi.load_dict`, `Texture::eval` at the same uv): texel centre,
    /// between texels, and across the left and right edges, with the sRGB decoding and
    /// `raw`, `repeat` and `mirror`; and the mean.
    #[test]
    fn matches_mitsuba_lookups() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("mitsuba_scenes/textures/tiles.png");
        let uvs = [
            Vec2::new(0.5 / 24.0 + 5.0 / 24.0, 0.5 / 16.0 + 6.0 / 16.0),
            Vec2::new(0.3, 0.41),
            Vec2::new(-0.013, 0.7),
            Vec2::new(1.02, 0.99),
        ];
        let cases: [(bool, WrapMode, [[f32; 3]; 4], f32); 4] = [
            (
                false,
                WrapMode::Repeat,
                [
                    [0.08022, 0.090842, 0.072272],
                    [0.087372, 0.098521, 0.07901],
                    [0.276218, 0.736412, 0.241779],
                    [0.019689, 0.019733, 0.008515],
                ],
                0.14444041,
            ),
            (
                false,
                WrapMode::Mirror,
                [
                    [0.08022, 0.090842, 0.072272],
                    [0.087372, 0.098521, 0.07901],
                    [0.012983, 0.009721, 0.006995],
                    [0.520996, 0.768151, 0.122139],
                ],
                0.14444041,
            ),
            (
                true,
                WrapMode::Repeat,
                [
                    [0.313726, 0.333333, 0.298039],
                    [0.327059, 0.346667, 0.311373],
                    [0.522055, 0.795404, 0.486024],
                    [0.125981, 0.108496, 0.082469],
                ],
                0.31676984,
            ),
            (
                true,
                WrapMode::Mirror,
                [
                    [0.313726, 0.333333, 0.298039],
                    [0.327059, 0.346667, 0.311373],
                    [0.117647, 0.098039, 0.078431],
                    [0.74902, 0.890196, 0.384314],
                ],
                0.31676984,
            ),
        ];
        for (raw, wrap, want, mean) in cases {
            let (width, height, texels) = read_texels(&path, raw).unwrap();
            let b = Bitmap {
                width,
                height,
                texels,
                filter: FilterType::Bilinear,
                wrap,
                to_uv: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            };
            for (uv, w) in uvs.iter().zip(want) {
                let got = b.eval(*uv);
                assert!(
                    (got - Vec3::from(w)).abs().max_element() < 2e-5,
                    "raw {raw} {wrap:?} at {uv}: {got} vs Mitsuba {w:?}"
                );
            }
            assert!(
                (b.mean() - mean).abs() < 1e-5,
                "mean {} vs {mean}",
                b.mean()
            );
        }
    }
}
