//! Reads at an index per path: the index type beside a [`Float`] and the gather that
//! loads `data[i]` in each lane, so that table lookups (a volume's voxels, the lookup
//! bounds' cells) are written once over the number type, as the kernels are. On one
//! path an index is a `usize` and a gather one load; in lanes it is `wide`'s `i32x8`
//! and a gather one load per lane that is on.

use std::ops::Add;

use wide::{f32x8, i32x8};

use super::Float;

/// A [`Float`] that can index memory.
pub trait Gather: Float {
    /// An index per path.
    type Index: Copy + Add<Output = Self::Index>;

    /// ⌊x⌋.
    fn floor(self) -> Self;
    /// x mod n for integral x and n: exact where |x| < 2^24, and in [0, n) for every
    /// x, NaN and infinities included (so that it can index a table of n).
    fn rem_euclid(self, n: usize) -> Self;
    /// `stride · x` as an index, for integral x in [0, 2^24) (exact).
    fn index(self, stride: usize) -> Self::Index;
    /// `data[stride · i + offset]` in the lanes of `mask`, 0 in the others. One path is
    /// always read: where it is called, its path is live.
    fn gather(data: &[f32], i: Self::Index, stride: usize, offset: usize, mask: Self::Mask)
        -> Self;
}

impl Gather for f32 {
    type Index = usize;

    #[inline(always)]
    fn floor(self) -> Self {
        f32::floor(self)
    }
    #[inline(always)]
    fn rem_euclid(self, n: usize) -> Self {
        // On integers (saturating at i32's range), as a voxel index wraps.
        (self as i32).rem_euclid(n as i32) as f32
    }
    #[inline(always)]
    fn index(self, stride: usize) -> usize {
        // Through i32, whose conversion is one instruction and a check (usize's is not).
        (self as i32) as usize * stride
    }
    #[inline(always)]
    fn gather(data: &[f32], i: usize, stride: usize, offset: usize, _: bool) -> Self {
        data[stride * i + offset]
    }
}

impl Gather for f32x8 {
    type Index = i32x8;

    #[inline(always)]
    fn floor(self) -> Self {
        f32x8::floor(self)
    }
    #[inline(always)]
    fn rem_euclid(self, n: usize) -> Self {
        // x − n ⌊x / n⌋: for |x| < 2^24 the quotient x/n = q + r/n rounds to q + 1
        // only where 1/n is below half q's ulp, i.e. where q n ≥ 2^24 (it never does
        // here), and the product and difference are exact integers.
        // Beyond 2^24 (and for NaN or ±∞) the clamp keeps r on the table: NaN goes to 0.
        let n = f32x8::splat(n as f32);
        let r = self - n * (self / n).floor();
        r.max(f32x8::ZERO).min(n - f32x8::ONE)
    }
    #[inline(always)]
    fn index(self, stride: usize) -> i32x8 {
        self.fast_round_int() * i32x8::splat(stride as i32)
    }
    #[inline(always)]
    fn gather(data: &[f32], i: i32x8, stride: usize, offset: usize, mask: f32x8) -> Self {
        let index = i.to_array();
        let bits = mask.move_mask();
        let mut out = [0f32; 8];
        for (k, v) in out.iter_mut().enumerate() {
            if bits >> k & 1 == 1 {
                *v = data[stride * index[k] as usize + offset];
            }
        }
        f32x8::from(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use wide::CmpEq;

    /// Each lane indexes and reads what one path reads, and a lane that is off reads
    /// nothing (0, even where its index is out of the table).
    #[test]
    fn lanes_gather_what_one_path_reads() {
        let data: Vec<f32> = (0..60).map(|i| i as f32 * 0.5).collect();
        let x = [0.0, 1.0, 5.0, 9.0, 2.0, 3.0, 7.0, 1e6];
        let lanes = f32x8::from(x);
        let on = f32x8::from([1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.0]).cmp_eq(f32x8::ONE);
        let i = lanes.index(2) + f32x8::splat(1.0).index(1);
        let got = f32x8::gather(&data, i, 3, 2, on).to_array();
        for k in 0..7 {
            let one = f32::gather(&data, x[k].index(2) + 1.0f32.index(1), 3, 2, true);
            assert_eq!(got[k], one, "lane {k}");
        }
        assert_eq!(got[7], 0.0);
        // Wrapping, lane against one path, for every integer near and far from 0
        // (where the quotient rounds) and a few axis lengths.
        for n in [1usize, 3, 5, 64, 1000] {
            for start in [-3000i32, -(1 << 23), (1 << 23) - 3000] {
                for i in (start..start + 3000).step_by(8) {
                    let x: [f32; 8] = std::array::from_fn(|k| (i + k as i32) as f32);
                    let lanes = f32x8::from(x).rem_euclid(n).to_array();
                    for k in 0..8 {
                        assert_eq!(lanes[k], x[k].rem_euclid(n as f32), "{} mod {n}", x[k]);
                    }
                }
            }
            // Far out, NaN and infinities stay on a table of n.
            let odd = [
                3e9,
                -3e9,
                1e30,
                -1e30,
                f32::NAN,
                f32::INFINITY,
                -f32::INFINITY,
                5e7,
            ];
            for r in f32x8::from(odd).rem_euclid(n).to_array() {
                assert!((0.0..n as f32).contains(&r), "{r} off a table of {n}");
            }
            for x in odd {
                let r = Gather::rem_euclid(x, n);
                assert!(
                    (0.0..n as f32).contains(&r),
                    "{x} mod {n} = {r} off the table"
                );
            }
        }
    }
}
