//! A register of f32 lanes, as wide as the CPU the build targets has: 16 with AVX-512
//! (`std::arch`), else 8 (the `wide` crate's `f32x8`, AVX2 where compiled in, else
//! two SSE registers). Comparisons answer a bit mask, lane k in bit k, so code that
//! tests many things at once branches once per register, on whether any bit is set.
//!
//! [`Float`] is the number type the physics kernels are written over once (f32, f64 or
//! lanes), [`Vector3`] a vector of it, [`Gather`] its index and table reads.
//!
//! Only what the lane kernels use is here; each operation is one instruction (or two
//! on the narrow path) and rounds as its scalar counterpart does.
//!
//! Two widths, on purpose. [`Lanes`] is the widest register the CPU has: the triangle
//! tests (`geometry::accel::lanes`) test as many triangles at once as fit, and gain
//! from 16. The path packet (`integrator::packet::lanes::L`) is `wide`'s `f32x8` at
//! every width: eight paths is the packet's fixed size (its masks, per-path random
//! streams and kernels are written for it), and it implements [`Float`], with the
//! transcendental functions (`exp`, `ln`, `sin_cos`) the physics kernels need, which
//! `Lanes` does not have. Both are vectors over [`Vector3`].

mod float;
mod gather;

pub use float::{Float, Vector3};
pub use gather::Gather;
pub use imp::{Lanes, Mask, WIDTH};

#[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
mod imp {
    use std::arch::x86_64::*;

    /// Lanes in a register.
    pub const WIDTH: usize = 16;

    /// A mask of lanes: bit k for lane k.
    pub type Mask = u32;

    /// Sixteen f32 lanes (one AVX-512 register).
    #[derive(Clone, Copy, Debug)]
    pub struct Lanes(pub(super) __m512);

    // SAFETY (every `unsafe` block below): AVX-512F is enabled at compile time (the
    // module's cfg), and the loads and stores touch exactly one [f32; 16].
    impl Lanes {
        #[inline(always)]
        pub fn splat(x: f32) -> Lanes {
            Lanes(unsafe { _mm512_set1_ps(x) })
        }

        #[inline(always)]
        pub fn load(a: &[f32; WIDTH]) -> Lanes {
            Lanes(unsafe { _mm512_loadu_ps(a.as_ptr()) })
        }

        #[inline(always)]
        pub fn to_array(self) -> [f32; WIDTH] {
            let mut a = [0f32; WIDTH];
            unsafe { _mm512_storeu_ps(a.as_mut_ptr(), self.0) };
            a
        }

        /// |x| (the sign bit cleared).
        #[inline(always)]
        pub fn abs(self) -> Lanes {
            Lanes(unsafe { _mm512_abs_ps(self.0) })
        }

        /// a − x · m, rounded once (fused), as glam's vector products round it where
        /// FMA is compiled in (AVX-512F has it).
        #[inline(always)]
        pub fn mul_neg_add(self, m: Lanes, a: Lanes) -> Lanes {
            Lanes(unsafe { _mm512_fnmadd_ps(self.0, m.0, a.0) })
        }

        /// x with its sign flipped where `s`'s sign bit is set: x · sign(s), exactly.
        #[inline(always)]
        pub fn times_sign_of(self, s: Lanes) -> Lanes {
            unsafe {
                let sign = _mm512_and_si512(_mm512_castps_si512(s.0), _mm512_set1_epi32(i32::MIN));
                Lanes(_mm512_castsi512_ps(_mm512_xor_si512(
                    _mm512_castps_si512(self.0),
                    sign,
                )))
            }
        }

        /// Lanes where x < y (false where either is NaN).
        #[inline(always)]
        pub fn lt(self, y: Lanes) -> Mask {
            unsafe { _mm512_cmp_ps_mask::<_CMP_LT_OQ>(self.0, y.0) as Mask }
        }

        #[inline(always)]
        pub fn le(self, y: Lanes) -> Mask {
            unsafe { _mm512_cmp_ps_mask::<_CMP_LE_OQ>(self.0, y.0) as Mask }
        }

        #[inline(always)]
        pub fn gt(self, y: Lanes) -> Mask {
            unsafe { _mm512_cmp_ps_mask::<_CMP_GT_OQ>(self.0, y.0) as Mask }
        }

        #[inline(always)]
        pub fn ge(self, y: Lanes) -> Mask {
            unsafe { _mm512_cmp_ps_mask::<_CMP_GE_OQ>(self.0, y.0) as Mask }
        }
    }

    macro_rules! binary {
        ($trait:ident, $method:ident, $intrinsic:ident) => {
            impl std::ops::$trait for Lanes {
                type Output = Lanes;
                #[inline(always)]
                fn $method(self, y: Lanes) -> Lanes {
                    Lanes(unsafe { $intrinsic(self.0, y.0) })
                }
            }
        };
    }
    binary!(Add, add, _mm512_add_ps);
    binary!(Sub, sub, _mm512_sub_ps);
    binary!(Mul, mul, _mm512_mul_ps);
    binary!(Div, div, _mm512_div_ps);
}

#[cfg(not(all(target_arch = "x86_64", target_feature = "avx512f")))]
mod imp {
    use wide::{f32x8, CmpGe, CmpGt, CmpLe, CmpLt};

    /// Lanes in a register.
    pub const WIDTH: usize = 8;

    /// A mask of lanes: bit k for lane k.
    pub type Mask = u32;

    /// Eight f32 lanes (`wide`'s f32x8).
    #[derive(Clone, Copy, Debug)]
    pub struct Lanes(pub(super) f32x8);

    impl Lanes {
        #[inline(always)]
        pub fn splat(x: f32) -> Lanes {
            Lanes(f32x8::splat(x))
        }

        #[inline(always)]
        pub fn load(a: &[f32; WIDTH]) -> Lanes {
            Lanes(f32x8::from(*a))
        }

        #[inline(always)]
        pub fn to_array(self) -> [f32; WIDTH] {
            self.0.to_array()
        }

        /// |x| (the sign bit cleared).
        #[inline(always)]
        pub fn abs(self) -> Lanes {
            Lanes(self.0.abs())
        }

        /// a − x · m, fused where FMA is compiled in, as glam's vector products are.
        #[inline(always)]
        pub fn mul_neg_add(self, m: Lanes, a: Lanes) -> Lanes {
            Lanes(self.0.mul_neg_add(m.0, a.0))
        }

        /// x with its sign flipped where `s`'s sign bit is set: x · sign(s), exactly.
        #[inline(always)]
        pub fn times_sign_of(self, s: Lanes) -> Lanes {
            Lanes(self.0 ^ (s.0 & f32x8::splat(-0.0)))
        }

        /// Lanes where x < y (false where either is NaN).
        #[inline(always)]
        pub fn lt(self, y: Lanes) -> Mask {
            self.0.cmp_lt(y.0).move_mask() as Mask
        }

        #[inline(always)]
        pub fn le(self, y: Lanes) -> Mask {
            self.0.cmp_le(y.0).move_mask() as Mask
        }

        #[inline(always)]
        pub fn gt(self, y: Lanes) -> Mask {
            self.0.cmp_gt(y.0).move_mask() as Mask
        }

        #[inline(always)]
        pub fn ge(self, y: Lanes) -> Mask {
            self.0.cmp_ge(y.0).move_mask() as Mask
        }
    }

    macro_rules! binary {
        ($trait:ident, $method:ident) => {
            impl std::ops::$trait for Lanes {
                type Output = Lanes;
                #[inline(always)]
                fn $method(self, y: Lanes) -> Lanes {
                    Lanes(std::ops::$trait::$method(self.0, y.0))
                }
            }
        };
    }
    binary!(Add, add);
    binary!(Sub, sub);
    binary!(Mul, mul);
    binary!(Div, div);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The width this build runs, where the test command says which it built for
    /// (`MEDIAREG_EXPECT_LANES`: scripts/test builds the other width too, and this
    /// fails if that build did not get it).
    #[test]
    fn the_build_has_the_width_asked_for() {
        if let Ok(w) = std::env::var("MEDIAREG_EXPECT_LANES") {
            assert_eq!(WIDTH.to_string(), w, "this build's lanes");
        }
    }

    fn lanes(f: impl Fn(usize) -> f32) -> Lanes {
        Lanes::load(&std::array::from_fn(f))
    }

    /// Every operation against its scalar counterpart, lane by lane, NaN and signed
    /// zeros among the inputs.
    #[test]
    fn lanes_compute_what_scalars_do() {
        let xs: [f32; WIDTH] = std::array::from_fn(|k| (k as f32 - 5.5) * 0.75);
        let mut ys: [f32; WIDTH] = std::array::from_fn(|k| 3.0 - k as f32 * 0.5);
        ys[1] = f32::NAN;
        ys[2] = -0.0;
        let (x, y) = (Lanes::load(&xs), Lanes::load(&ys));
        let each = |v: Lanes, f: &dyn Fn(f32, f32) -> f32| {
            let got = v.to_array();
            for k in 0..WIDTH {
                let want = f(xs[k], ys[k]);
                assert!(
                    got[k].to_bits() == want.to_bits(),
                    "lane {k}: {} vs {want}",
                    got[k]
                );
            }
        };
        each(x + y, &|a, b| a + b);
        each(x - y, &|a, b| a - b);
        each(x * y, &|a, b| a * b);
        each(x / y, &|a, b| a / b);
        each(x.abs(), &|a, _| a.abs());
        let fused = cfg!(target_feature = "fma");
        each(x.mul_neg_add(y, y * y), &|a, b| {
            if fused {
                (-a).mul_add(b, b * b)
            } else {
                b * b - a * b
            }
        });
        each(x.times_sign_of(y), &|a, b| {
            if b.is_sign_negative() {
                -a
            } else {
                a
            }
        });
        let mask = |m: Mask, f: &dyn Fn(f32, f32) -> bool| {
            for k in 0..WIDTH {
                assert_eq!(m >> k & 1 == 1, f(xs[k], ys[k]), "lane {k}");
            }
            assert_eq!(m >> WIDTH, 0);
        };
        mask(x.lt(y), &|a, b| a < b);
        mask(x.le(y), &|a, b| a <= b);
        mask(x.gt(y), &|a, b| a > b);
        mask(x.ge(y), &|a, b| a >= b);
        assert_eq!(Lanes::splat(2.5).to_array(), [2.5; WIDTH]);
        assert_eq!(
            lanes(|k| k as f32).to_array()[WIDTH - 1],
            (WIDTH - 1) as f32
        );
    }
}
