//! Textures a BSDF parameter may be: a constant, Mitsuba's `checkerboard`
//! (`src/textures/checkerboard.cpp`): with uv' = to_uv · uv and the mask
//! m = frac(uv') > ½ per axis, color0 where m.x = m.y, else color1; or a `bitmap`
//! (`bitmap`).

pub mod bitmap;
pub mod bitmap_file;
pub mod uv;

use std::sync::Arc;

use glam::{Vec2, Vec3};

use bitmap::Bitmap;
pub use uv::apply_to_uv;

#[derive(Clone, Debug, PartialEq)]
pub enum Texture {
    Constant(Vec3),
    Checkerboard {
        color0: Vec3,
        color1: Vec3,
        /// The 2D affine `to_uv`: rows (a, b, tx) and (c, d, ty).
        to_uv: [[f32; 3]; 2],
    },
    /// An image (shared: BSDFs are cloned per use).
    Bitmap(Arc<Bitmap>),
}

impl Texture {
    #[inline]
    pub fn eval(&self, uv: Vec2) -> Vec3 {
        match self {
            Texture::Constant(c) => *c,
            Texture::Checkerboard {
                color0,
                color1,
                to_uv,
            } => {
                let Vec2 { x: u, y: v } = apply_to_uv(to_uv, uv);
                if (u - u.floor() > 0.5) == (v - v.floor() > 0.5) {
                    *color0
                } else {
                    *color1
                }
            }
            Texture::Bitmap(b) => b.eval(uv),
        }
    }

    /// A scalar value at `uv`, as Mitsuba's `Texture::eval_1` gives it to a scalar
    /// parameter (an opacity, a blend weight, a roughness): the channel mean of a
    /// constant (`srgb`'s `mean()`), the luminance of a bitmap's RGB, and for a
    /// checkerboard the *other* colour than `eval` picks (3.9.1's `eval_1` tests
    /// m.x ≠ m.y for color0 where `eval` tests m.x = m.y).
    #[inline]
    pub fn eval_1(&self, uv: Vec2) -> f32 {
        match self {
            Texture::Constant(c) => c.element_sum() / 3.0,
            Texture::Checkerboard {
                color0,
                color1,
                to_uv,
            } => {
                let Vec2 { x: u, y: v } = apply_to_uv(to_uv, uv);
                let c = if (u - u.floor() > 0.5) != (v - v.floor() > 0.5) {
                    color0
                } else {
                    color1
                };
                c.element_sum() / 3.0
            }
            Texture::Bitmap(b) => luminance(b.eval(uv)),
        }
    }

    /// The mean over the texture's domain and the channels (Mitsuba's `Texture::mean`;
    /// a checkerboard covers half its domain with each colour).
    pub fn mean(&self) -> f32 {
        match self {
            Texture::Constant(c) => c.element_sum() / 3.0,
            Texture::Checkerboard { color0, color1, .. } => (*color0 + *color1).element_sum() / 6.0,
            Texture::Bitmap(b) => b.mean(),
        }
    }

    /// The value, when it does not vary.
    pub fn constant(&self) -> Option<Vec3> {
        match self {
            Texture::Constant(c) => Some(*c),
            Texture::Checkerboard { .. } | Texture::Bitmap(_) => None,
        }
    }
}

/// Mitsuba's `luminance` of linear sRGB (the Y row of the sRGB → XYZ matrix).
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.212_671, 0.715_160, 0.072_169))
}

/// Tests compare a constant reflectance with a color directly.
impl PartialEq<Vec3> for Texture {
    fn eq(&self, other: &Vec3) -> bool {
        self.constant() == Some(*other)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checkerboard_squares() {
        let t = Texture::Checkerboard {
            color0: Vec3::ZERO,
            color1: Vec3::ONE,
            to_uv: [[2.0, 0.0, 0.0], [0.0, 2.0, 0.0]],
        };
        assert_eq!(t.eval(Vec2::new(0.1, 0.1)), Vec3::ZERO); // both halves low
        assert_eq!(t.eval(Vec2::new(0.3, 0.1)), Vec3::ONE); // u' 0.6: high, v' low
        assert_eq!(t.eval(Vec2::new(0.3, 0.3)), Vec3::ZERO);
        assert_eq!(t.eval(Vec2::new(0.6, 0.1)), Vec3::ZERO); // u' 1.2: low again
                                                             // eval_1 takes the other colour, as Mitsuba 3.9.1's checkerboard does.
        assert_eq!(t.eval_1(Vec2::new(0.1, 0.1)), 1.0);
        assert_eq!(t.eval_1(Vec2::new(0.3, 0.1)), 0.0);
    }
}
