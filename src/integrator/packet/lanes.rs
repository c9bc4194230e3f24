//! The packet's registers: `wide`'s `f32x8` (one lane per path), a three-component
//! vector of them (a position, a direction or an RGB value per path), masks (all bits
//! set in a lane that is on), and the random draws of the lanes that need them.

use glam::{Vec3, Vec3A};
use wide::{f32x8, CmpEq, CmpGt};

use crate::sampling::Pcg32;

/// Paths in a packet.
pub const WIDTH: usize = 8;

/// One f32 per path.
pub type L = f32x8;

/// Three lanes registers: a vector (or an RGB value) per path.
#[derive(Clone, Copy)]
pub struct V3 {
    pub x: L,
    pub y: L,
    pub z: L,
}

impl V3 {
    #[inline(always)]
    pub fn splat(v: Vec3) -> V3 {
        V3 {
            x: L::splat(v.x),
            y: L::splat(v.y),
            z: L::splat(v.z),
        }
    }

    /// Lane k from `f(k)`.
    #[inline(always)]
    pub fn from_fn(f: impl Fn(usize) -> Vec3) -> V3 {
        let v: [Vec3; WIDTH] = std::array::from_fn(f);
        V3 {
            x: L::from(std::array::from_fn::<f32, WIDTH, _>(|k| v[k].x)),
            y: L::from(std::array::from_fn::<f32, WIDTH, _>(|k| v[k].y)),
            z: L::from(std::array::from_fn::<f32, WIDTH, _>(|k| v[k].z)),
        }
    }

    #[inline(always)]
    pub fn lane(&self, k: usize) -> Vec3 {
        Vec3::new(
            self.x.as_array_ref()[k],
            self.y.as_array_ref()[k],
            self.z.as_array_ref()[k],
        )
    }

    #[inline(always)]
    pub fn lane_a(&self, k: usize) -> Vec3A {
        Vec3A::from(self.lane(k))
    }

    #[inline(always)]
    pub fn add(self, o: V3) -> V3 {
        V3 {
            x: self.x + o.x,
            y: self.y + o.y,
            z: self.z + o.z,
        }
    }

    #[inline(always)]
    pub fn sub(self, o: V3) -> V3 {
        V3 {
            x: self.x - o.x,
            y: self.y - o.y,
            z: self.z - o.z,
        }
    }

    /// Componentwise product.
    #[inline(always)]
    pub fn mul(self, o: V3) -> V3 {
        V3 {
            x: self.x * o.x,
            y: self.y * o.y,
            z: self.z * o.z,
        }
    }

    #[inline(always)]
    pub fn scale(self, s: L) -> V3 {
        V3 {
            x: self.x * s,
            y: self.y * s,
            z: self.z * s,
        }
    }

    #[inline(always)]
    pub fn div(self, s: L) -> V3 {
        V3 {
            x: self.x / s,
            y: self.y / s,
            z: self.z / s,
        }
    }

    #[inline(always)]
    pub fn dot(self, o: V3) -> L {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    #[inline(always)]
    pub fn max_element(self) -> L {
        self.x.max(self.y).max(self.z)
    }

    #[inline(always)]
    pub fn abs(self) -> V3 {
        V3 {
            x: self.x.abs(),
            y: self.y.abs(),
            z: self.z.abs(),
        }
    }

    #[inline(always)]
    pub fn mean(self) -> L {
        (self.x + self.y + self.z) * L::splat(1.0 / 3.0)
    }

    /// Lanes where every component is 0.
    #[inline(always)]
    pub fn is_zero(self) -> L {
        let z = L::ZERO;
        self.x.cmp_eq(z) & self.y.cmp_eq(z) & self.z.cmp_eq(z)
    }

    #[inline(always)]
    pub fn is_finite(self) -> L {
        self.x.is_finite() & self.y.is_finite() & self.z.is_finite()
    }

    /// `t` where `mask` is set, else `self`.
    #[inline(always)]
    pub fn select(self, mask: L, t: V3) -> V3 {
        V3 {
            x: mask.blend(t.x, self.x),
            y: mask.blend(t.y, self.y),
            z: mask.blend(t.z, self.z),
        }
    }

    /// e^{−σ t} per channel (σ = 0: 1 at any t).
    #[inline(always)]
    pub fn transmittance(sigma: V3, t: L) -> V3 {
        let f = |s: L| s.cmp_gt(L::ZERO).blend((-(s * t)).exp(), L::ONE);
        V3 {
            x: f(sigma.x),
            y: f(sigma.y),
            z: f(sigma.z),
        }
    }
}

/// The lanes where bit k of `bits` is set.
#[inline(always)]
pub fn lanes_of(bits: i32) -> impl Iterator<Item = usize> {
    (0..WIDTH).filter(move |k| bits >> k & 1 == 1)
}

/// All-ones where `cond`, per lane.
#[inline(always)]
pub fn mask_of(cond: impl Fn(usize) -> bool) -> L {
    L::from(std::array::from_fn::<f32, WIDTH, _>(|k| {
        if cond(k) {
            f32::from_bits(u32::MAX)
        } else {
            0.0
        }
    }))
}

/// One uniform draw per lane of `mask` from its path's stream (0 elsewhere).
#[inline(always)]
pub fn draw_1d(mask: L, rngs: &mut [Pcg32]) -> L {
    let mut u = [0f32; WIDTH];
    for k in lanes_of(mask.move_mask()) {
        u[k] = rngs[k].next_1d();
    }
    L::from(u)
}

/// Two uniform draws (one `next_2d`) per lane of `mask`.
#[inline(always)]
pub fn draw_2d(mask: L, rngs: &mut [Pcg32]) -> (L, L) {
    let (mut u, mut v) = ([0f32; WIDTH], [0f32; WIDTH]);
    for k in lanes_of(mask.move_mask()) {
        let s = rngs[k].next_2d();
        (u[k], v[k]) = (s.x, s.y);
    }
    (L::from(u), L::from(v))
}
