//! Reads at an index per path: the index type beside a [`Float`] and the gather that
//! loads `data[i]` in each lane, so that table lookups (a volume's voxels, the lookup
//! bounds' cells) are written once over the number type, as the kernels are. On one
//! path an index is a `usize` and a gather one load; in lanes it is `wide`'s `i32x8`
//! and a gather one load per lane that is on. Beside them, what a lookup along a ray
//! needs where one path and lanes hold things differently: the point type (glam's
//! `Vec3A` on one path), its transform and the ray–box slab test.

use std::ops::Add;

use glam::{Affine3A, Vec3A};
use wide::{f32x8, i32x8};

use super::{Float, Vector3};

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

    /// A point (or direction) as a loop over one ray holds it: `Vec3A`, one register,
    /// on one path (so that fewer values are saved across a call), `Vector3` in lanes.
    type Point: Copy;

    fn point(v: Vector3<Self>) -> Self::Point;
    /// o + t d.
    fn along(o: Self::Point, d: Self::Point, t: Self) -> Self::Point;
    fn vector(p: Self::Point) -> Vector3<Self>;
    /// `m`'s transform of point `p`, rounded as glam's `Affine3A::transform_point3a`
    /// rounds it (per axis the products summed x, y, z, then the translation).
    fn transform_point(m: &Affine3A, p: Self::Point) -> [Self; 3];
    /// The stretches [t0, t1] ⊂ [tmin, tmax] of the rays `o + t d` within the box
    /// [lo, hi] (the slab test), and the paths where one is not empty. Where d has a 0
    /// and o lies on that slab's plane, 0 · ∞ is NaN there: the other slabs decide.
    fn box_span(
        box_: [Vec3A; 2],
        o: Self::Point,
        d: Self::Point,
        span: (Self, Self),
    ) -> (Self, Self, Self::Mask);

    /// The entry that integral coordinate x reads along a table of n, times `stride`,
    /// as a texture's addressing modes place it, in [0, n) for every x (NaN and
    /// infinities included). Clamped to the ends:
    #[inline(always)]
    fn clamp_index(self, n: usize, stride: usize) -> Self::Index {
        self.max(Self::zero())
            .min(Self::of((n - 1) as f64))
            .index(stride)
    }
    /// Repeated (x mod n):
    #[inline(always)]
    fn repeat_index(self, n: usize, stride: usize) -> Self::Index {
        self.rem_euclid(n).index(stride)
    }
    /// Mirrored at each end (x mod 2n, folded back where it is n or more):
    #[inline(always)]
    fn mirror_index(self, n: usize, stride: usize) -> Self::Index {
        let m = self.rem_euclid(2 * n);
        let folded = Self::of((2 * n - 1) as f64) - m;
        Self::select(m.ge(Self::of(n as f64)), folded, m).index(stride)
    }
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
    type Point = Vec3A;

    #[inline(always)]
    fn point(v: Vector3<f32>) -> Vec3A {
        v.into()
    }
    #[inline(always)]
    fn along(o: Vec3A, d: Vec3A, t: f32) -> Vec3A {
        o + d * t
    }
    #[inline(always)]
    fn vector(p: Vec3A) -> Vector3<f32> {
        p.into()
    }
    #[inline(always)]
    fn transform_point(m: &Affine3A, p: Vec3A) -> [f32; 3] {
        m.transform_point3a(p).to_array()
    }
    // In one register: a slab test per flight and shadow ray is worth its few
    // instructions.
    #[inline(always)]
    fn box_span(
        [lo, hi]: [Vec3A; 2],
        o: Vec3A,
        d: Vec3A,
        (tmin, tmax): (f32, f32),
    ) -> (f32, f32, bool) {
        let inv = d.recip();
        let a = (lo - o) * inv;
        let b = (hi - o) * inv;
        let t0 = a.min(b).max_element().max(tmin);
        let t1 = a.max(b).min_element().min(tmax);
        (t0, t1, t0 <= t1)
    }
    // Repeat and mirror on integers: on one path the round trips through f32 around the
    // integer remainder cost more than the wrap itself.
    #[inline(always)]
    fn repeat_index(self, n: usize, stride: usize) -> usize {
        (self as i32).rem_euclid(n as i32) as usize * stride
    }
    #[inline(always)]
    fn mirror_index(self, n: usize, stride: usize) -> usize {
        let n = n as i32;
        let m = (self as i32).rem_euclid(2 * n);
        (if m >= n { 2 * n - 1 - m } else { m }) as usize * stride
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
    type Point = Vector3<f32x8>;

    #[inline(always)]
    fn point(v: Vector3<f32x8>) -> Vector3<f32x8> {
        v
    }
    #[inline(always)]
    fn along(o: Self::Point, d: Self::Point, t: f32x8) -> Self::Point {
        o.add(d.scale(t))
    }
    #[inline(always)]
    fn vector(p: Self::Point) -> Vector3<f32x8> {
        p
    }
    #[inline(always)]
    fn transform_point(m: &Affine3A, p: Self::Point) -> [f32x8; 3] {
        std::array::from_fn(|k| {
            let (a, b, c) = (
                m.matrix3.x_axis[k],
                m.matrix3.y_axis[k],
                m.matrix3.z_axis[k],
            );
            f32x8::splat(a) * p.x
                + f32x8::splat(b) * p.y
                + f32x8::splat(c) * p.z
                + f32x8::splat(m.translation[k])
        })
    }
    #[inline(always)]
    fn box_span(
        [lo, hi]: [Vec3A; 2],
        o: Self::Point,
        d: Self::Point,
        (tmin, tmax): (f32x8, f32x8),
    ) -> (f32x8, f32x8, f32x8) {
        let (mut near, mut far) = (tmin, tmax);
        for (o, d, lo, hi) in [
            (o.x, d.x, lo.x, hi.x),
            (o.y, d.y, lo.y, hi.y),
            (o.z, d.z, lo.z, hi.z),
        ] {
            let inv = f32x8::ONE / d;
            let a = (f32x8::splat(lo) - o) * inv;
            let b = (f32x8::splat(hi) - o) * inv;
            near = near.max(a.min(b));
            far = far.min(a.max(b));
        }
        (near, far, Float::le(near, far))
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
                    let wrapped = [
                        f32x8::from(x).repeat_index(n, 3).to_array(),
                        f32x8::from(x).mirror_index(n, 3).to_array(),
                    ];
                    for k in 0..8 {
                        assert_eq!(lanes[k], x[k].rem_euclid(n as f32), "{} mod {n}", x[k]);
                        // The one path's integer wraps place it where the lanes do.
                        let one = [x[k].repeat_index(n, 3), x[k].mirror_index(n, 3)];
                        for (mode, (l, o)) in wrapped.iter().zip(one).enumerate() {
                            assert_eq!(l[k] as usize, o, "mode {mode}: {} on {n}", x[k]);
                        }
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
                for i in [
                    x.repeat_index(n, 1),
                    x.mirror_index(n, 1),
                    x.clamp_index(n, 1),
                ] {
                    assert!(i < n, "{x} indexes {i} on a table of {n}");
                }
                let r = Gather::rem_euclid(x, n);
                assert!(
                    (0.0..n as f32).contains(&r),
                    "{x} mod {n} = {r} off the table"
                );
            }
        }
    }

    /// The lanes' point transform and slab test give one path's answers to the bit, on
    /// rays from all around a box (misses included), d with zeros among them. Power:
    /// a box 1% larger changes some answers.
    #[test]
    fn lanes_transform_and_clip_as_one_path() {
        let m = Affine3A::from_scale_rotation_translation(
            glam::Vec3::new(0.5, 2.0, 1.5),
            glam::Quat::from_rotation_y(0.7),
            glam::Vec3::new(0.1, -0.3, 2.0),
        );
        let unit = [Vec3A::ZERO, Vec3A::ONE];
        let larger = [Vec3A::splat(-0.01), Vec3A::splat(1.01)];
        // A small LCG of its own: sampling sits above simd.
        let mut state = 0x9e37_79b9_u32;
        let mut next = move || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 8) as f32 / (1u32 << 24) as f32
        };
        let mut moved = 0;
        for _ in 0..200 {
            let rays: [(Vec3A, Vec3A); 8] = std::array::from_fn(|k| {
                let mut v = || Vec3A::new(next(), next(), next());
                let o = v() * 3.0 - Vec3A::ONE;
                let mut d = v() - Vec3A::splat(0.5);
                if k == 3 {
                    d.x = 0.0;
                }
                (o, d.normalize())
            });
            let lanes = |f: fn(&(Vec3A, Vec3A)) -> Vec3A| {
                let v = rays.map(|r| f(&r));
                Vector3::new(
                    f32x8::from(v.map(|p| p.x)),
                    f32x8::from(v.map(|p| p.y)),
                    f32x8::from(v.map(|p| p.z)),
                )
            };
            let (o, d) = (lanes(|r| r.0), lanes(|r| r.1));
            let q = f32x8::transform_point(&m, o).map(|a| a.to_array());
            let span = (f32x8::splat(0.0), f32x8::splat(4.0));
            let (t0, t1, some) = f32x8::box_span(unit, o, d, span);
            let (a0, a1, _) = f32x8::box_span(larger, o, d, span);
            for (k, &(ok, dk)) in rays.iter().enumerate() {
                let one = f32::transform_point(&m, ok);
                assert_eq!([q[0][k], q[1][k], q[2][k]], one, "ray {k}");
                let (s0, s1, hit) = f32::box_span(unit, ok, dk, (0.0, 4.0));
                assert_eq!(some.move_mask() >> k & 1 == 1, hit, "ray {k}");
                if hit {
                    assert_eq!((t0.to_array()[k], t1.to_array()[k]), (s0, s1), "ray {k}");
                    moved += ((a0.to_array()[k], a1.to_array()[k]) != (s0, s1)) as usize;
                }
            }
        }
        assert!(moved > 0, "a 1% larger box unnoticed");
    }
}
