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
    }
}
