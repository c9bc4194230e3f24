//! The number type the physics kernels are written over, once: `f32` (one path), `f64`
//! (where a scalar kernel needs the precision) or a register of lanes (`f32x8`, one
//! path a lane), as Mitsuba 3 writes `volpath.cpp` once over its `Float`. A kernel
//! branches by [`Float::select`] on a [`Float::Mask`]: an `if` on one path, a blend
//! across lanes. Each operation rounds as its scalar counterpart does, except the
//! transcendental ones in lanes (`exp`, `ln`, `sin_cos`: `wide`'s polynomials, within a
//! few ulp of libm's).

use std::ops::{Add, BitAnd, BitOr, Div, Mul, Not, Sub};

use wide::{f32x8, CmpEq, CmpGe, CmpGt, CmpLe, CmpLt};

/// A real number per path: `f32`, `f64`, or `f32x8` lanes.
pub trait Float:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self>
{
    /// A truth value per path: `bool`, or a lane mask (all bits set where true).
    type Mask: Copy
        + BitAnd<Output = Self::Mask>
        + BitOr<Output = Self::Mask>
        + Not<Output = Self::Mask>;

    /// A constant, rounded once to this type (an `f64` kernel keeps its digits).
    fn of(x: f64) -> Self;
    /// −x, the sign bit flipped (−0 from +0, as on one path; `wide`'s `-x` is 0 − x,
    /// which gives +0, so the lanes have no `Neg` here).
    fn negate(self) -> Self;
    fn sqrt(self) -> Self;
    fn abs(self) -> Self;
    /// The larger; the other where one is NaN (as `f32::max`).
    fn max(self, o: Self) -> Self;
    /// The smaller; the other where one is NaN (as `f32::min`).
    fn min(self, o: Self) -> Self;
    fn exp(self) -> Self;
    fn ln(self) -> Self;
    fn sin_cos(self) -> (Self, Self);
    /// |self| with the sign of `sign`.
    fn copysign(self, sign: Self) -> Self;
    fn lt(self, o: Self) -> Self::Mask;
    fn le(self, o: Self) -> Self::Mask;
    fn gt(self, o: Self) -> Self::Mask;
    fn ge(self, o: Self) -> Self::Mask;
    fn eq(self, o: Self) -> Self::Mask;
    fn is_finite(self) -> Self::Mask;
    /// `t` where `m`, else `f`.
    fn select(m: Self::Mask, t: Self, f: Self) -> Self;
    /// Whether `m` holds on any path (a loop over lanes goes on while one is live).
    fn any(m: Self::Mask) -> bool;
    /// `b` on every path.
    fn mask(b: bool) -> Self::Mask;

    #[inline(always)]
    fn zero() -> Self {
        Self::of(0.0)
    }

    #[inline(always)]
    fn one() -> Self {
        Self::of(1.0)
    }
}

macro_rules! scalar {
    ($t:ty) => {
        impl Float for $t {
            type Mask = bool;

            #[inline(always)]
            fn of(x: f64) -> Self {
                x as $t
            }
            #[inline(always)]
            fn negate(self) -> Self {
                -self
            }
            #[inline(always)]
            fn sqrt(self) -> Self {
                <$t>::sqrt(self)
            }
            #[inline(always)]
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            #[inline(always)]
            fn max(self, o: Self) -> Self {
                <$t>::max(self, o)
            }
            #[inline(always)]
            fn min(self, o: Self) -> Self {
                <$t>::min(self, o)
            }
            #[inline(always)]
            fn exp(self) -> Self {
                <$t>::exp(self)
            }
            #[inline(always)]
            fn ln(self) -> Self {
                <$t>::ln(self)
            }
            #[inline(always)]
            fn sin_cos(self) -> (Self, Self) {
                <$t>::sin_cos(self)
            }
            #[inline(always)]
            fn copysign(self, sign: Self) -> Self {
                <$t>::copysign(self, sign)
            }
            #[inline(always)]
            fn lt(self, o: Self) -> bool {
                self < o
            }
            #[inline(always)]
            fn le(self, o: Self) -> bool {
                self <= o
            }
            #[inline(always)]
            fn gt(self, o: Self) -> bool {
                self > o
            }
            #[inline(always)]
            fn ge(self, o: Self) -> bool {
                self >= o
            }
            #[inline(always)]
            fn eq(self, o: Self) -> bool {
                self == o
            }
            #[inline(always)]
            fn is_finite(self) -> bool {
                <$t>::is_finite(self)
            }
            #[inline(always)]
            fn select(m: bool, t: Self, f: Self) -> Self {
                if m {
                    t
                } else {
                    f
                }
            }
            #[inline(always)]
            fn any(m: bool) -> bool {
                m
            }
            #[inline(always)]
            fn mask(b: bool) -> bool {
                b
            }
        }
    };
}
scalar!(f32);
scalar!(f64);

impl Float for f32x8 {
    type Mask = f32x8;

    #[inline(always)]
    fn of(x: f64) -> Self {
        f32x8::splat(x as f32)
    }
    #[inline(always)]
    fn negate(self) -> Self {
        self ^ f32x8::splat(-0.0)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f32x8::sqrt(self)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32x8::abs(self)
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        f32x8::max(self, o)
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        f32x8::min(self, o)
    }
    #[inline(always)]
    fn exp(self) -> Self {
        f32x8::exp(self)
    }
    #[inline(always)]
    fn ln(self) -> Self {
        f32x8::ln(self)
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        f32x8::sin_cos(self)
    }
    #[inline(always)]
    fn copysign(self, sign: Self) -> Self {
        f32x8::copysign(self, sign)
    }
    #[inline(always)]
    fn lt(self, o: Self) -> Self {
        self.cmp_lt(o)
    }
    #[inline(always)]
    fn le(self, o: Self) -> Self {
        self.cmp_le(o)
    }
    #[inline(always)]
    fn gt(self, o: Self) -> Self {
        self.cmp_gt(o)
    }
    #[inline(always)]
    fn ge(self, o: Self) -> Self {
        self.cmp_ge(o)
    }
    #[inline(always)]
    fn eq(self, o: Self) -> Self {
        self.cmp_eq(o)
    }
    #[inline(always)]
    fn is_finite(self) -> Self {
        f32x8::is_finite(self)
    }
    #[inline(always)]
    fn select(m: Self, t: Self, f: Self) -> Self {
        m.blend(t, f)
    }
    #[inline(always)]
    fn any(m: Self) -> bool {
        m.any()
    }
    #[inline(always)]
    fn mask(b: bool) -> Self {
        // A lane mask is all bits set where true.
        f32x8::splat(f32::from_bits(if b { u32::MAX } else { 0 }))
    }
}

/// A three-component vector (a position, a direction or an RGB value) per path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vector3<F> {
    pub x: F,
    pub y: F,
    pub z: F,
}

// `add`, `sub`, `mul` and `div` are methods (a kernel reads as a chain of them, as the
// lane code always did), not the operator traits.
#[allow(clippy::should_implement_trait)]
impl<F: Float> Vector3<F> {
    #[inline(always)]
    pub fn new(x: F, y: F, z: F) -> Self {
        Vector3 { x, y, z }
    }

    /// The same (f32) vector in every path.
    #[inline(always)]
    pub fn splat(v: glam::Vec3) -> Self {
        Vector3::new(F::of(v.x as f64), F::of(v.y as f64), F::of(v.z as f64))
    }

    #[inline(always)]
    pub fn all(s: F) -> Self {
        Vector3::new(s, s, s)
    }

    #[inline(always)]
    pub fn add(self, o: Self) -> Self {
        Vector3::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }

    #[inline(always)]
    pub fn sub(self, o: Self) -> Self {
        Vector3::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }

    /// Componentwise product.
    #[inline(always)]
    pub fn mul(self, o: Self) -> Self {
        Vector3::new(self.x * o.x, self.y * o.y, self.z * o.z)
    }

    /// Componentwise quotient.
    #[inline(always)]
    pub fn div_each(self, o: Self) -> Self {
        Vector3::new(self.x / o.x, self.y / o.y, self.z / o.z)
    }

    #[inline(always)]
    pub fn scale(self, s: F) -> Self {
        Vector3::new(self.x * s, self.y * s, self.z * s)
    }

    #[inline(always)]
    pub fn div(self, s: F) -> Self {
        Vector3::new(self.x / s, self.y / s, self.z / s)
    }

    /// (x₀y₀ + x₁y₁) + x₂y₂, in glam's order.
    #[inline(always)]
    pub fn dot(self, o: Self) -> F {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    #[inline(always)]
    pub fn max_element(self) -> F {
        self.x.max(self.y).max(self.z)
    }

    #[inline(always)]
    pub fn abs(self) -> Self {
        Vector3::new(self.x.abs(), self.y.abs(), self.z.abs())
    }

    /// (x + y + z) / 3, as the scalar paths' `mean` rounds it.
    #[inline(always)]
    pub fn mean(self) -> F {
        (self.x + self.y + self.z) * F::of((1.0f32 / 3.0) as f64)
    }

    /// Paths where every component is 0.
    #[inline(always)]
    pub fn is_zero(self) -> F::Mask {
        let z = F::zero();
        self.x.eq(z) & self.y.eq(z) & self.z.eq(z)
    }

    #[inline(always)]
    pub fn is_finite(self) -> F::Mask {
        self.x.is_finite() & self.y.is_finite() & self.z.is_finite()
    }

    /// `t` where `mask` is set, else `self`.
    #[inline(always)]
    pub fn select(self, mask: F::Mask, t: Self) -> Self {
        Vector3::new(
            F::select(mask, t.x, self.x),
            F::select(mask, t.y, self.y),
            F::select(mask, t.z, self.z),
        )
    }

    /// The `c`-th component (0, 1, 2).
    #[inline(always)]
    pub fn component(self, c: usize) -> F {
        match c {
            0 => self.x,
            1 => self.y,
            _ => self.z,
        }
    }
}

impl Vector3<f32x8> {
    /// Lane k from `f(k)`.
    #[inline(always)]
    pub fn from_fn(f: impl Fn(usize) -> glam::Vec3) -> Self {
        let v: [glam::Vec3; 8] = std::array::from_fn(f);
        Vector3 {
            x: f32x8::from(std::array::from_fn::<f32, 8, _>(|k| v[k].x)),
            y: f32x8::from(std::array::from_fn::<f32, 8, _>(|k| v[k].y)),
            z: f32x8::from(std::array::from_fn::<f32, 8, _>(|k| v[k].z)),
        }
    }

    /// Lane k.
    #[inline(always)]
    pub fn lane(&self, k: usize) -> glam::Vec3 {
        glam::Vec3::new(
            self.x.as_array_ref()[k],
            self.y.as_array_ref()[k],
            self.z.as_array_ref()[k],
        )
    }

    #[inline(always)]
    pub fn lane_a(&self, k: usize) -> glam::Vec3A {
        glam::Vec3A::from(self.lane(k))
    }
}

impl From<glam::Vec3A> for Vector3<f32> {
    #[inline(always)]
    fn from(v: glam::Vec3A) -> Self {
        Vector3::new(v.x, v.y, v.z)
    }
}

impl From<glam::Vec3> for Vector3<f32> {
    #[inline(always)]
    fn from(v: glam::Vec3) -> Self {
        Vector3::new(v.x, v.y, v.z)
    }
}

impl From<Vector3<f32>> for glam::Vec3A {
    #[inline(always)]
    fn from(v: Vector3<f32>) -> Self {
        glam::Vec3A::new(v.x, v.y, v.z)
    }
}

impl From<Vector3<f32>> for glam::Vec3 {
    #[inline(always)]
    fn from(v: Vector3<f32>) -> Self {
        glam::Vec3::new(v.x, v.y, v.z)
    }
}
