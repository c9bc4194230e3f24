//! A heterogeneous medium in lanes (`medium::heterogeneous`'s estimators): free flights
//! by delta tracking and shadow rays' transmittance by ratio tracking, each lane with
//! its own draws in the scalar code's order. The tentative collisions of all lanes step
//! together until the last lane's flight ends; the volume and its lookup bounds are
//! read by the scalar path's lookups, run in lanes (`Volume::eval_at`, a gather of
//! the voxels), everything else in lanes.
//!
//! The lanes track at the medium's one global majorant, where the scalar code walks its
//! local ones (`medium::majorant`): the same expectation by another estimator (the
//! tests hold them equal). Walking the cells in lanes was tried and was slower: the
//! lanes that cross many cells hold up the packet. Each lane calling the scalar walk
//! instead ran as fast as the global majorant in lanes, on the cloud.

use glam::Vec3;
use wide::{CmpGe, CmpGt, CmpLe, CmpLt};

use super::lanes::{draw_1d, lanes_of, L, V3, WIDTH};
use crate::medium::heterogeneous::{
    null_weight, ratio_roulette, ratio_weight, real_probability, real_weight, HeterogeneousMedium,
    RATIO_SURVIVAL,
};
use crate::medium::tracking::{optical_depth, MajorantSegment};
use crate::sampling::Pcg32;

/// Where the lanes' free flights ended: a real collision (`collided`, at `t`, the
/// volume's albedo there) or none, and each flight's weight (the product of the null
/// collisions' σ_n / mean(σ_n), times σ_t / mean(σ_t) at the real one).
pub struct Flight {
    pub collided: L,
    pub t: L,
    pub weight: V3,
    /// The albedo volume's value at the collision (1 where none).
    pub albedo: V3,
}

/// The stretch [t0, t1] ⊂ [tmin, tmax] of each ray where the extinction can be non-zero
/// (within the σ_t volume's box, `HeterogeneousMedium::span`), and the lanes where it is
/// not empty.
#[inline(always)]
fn span(h: &HeterogeneousMedium, o: V3, d: V3, tmin: L, tmax: L) -> (L, L, L) {
    if !h.bounded {
        return (tmin, tmax, tmin.cmp_le(tmax));
    }
    let [lo, hi] = h.sigma_t.bbox;
    let mut near = tmin;
    let mut far = tmax;
    for (o, d, lo, hi) in [
        (o.x, d.x, lo.x, hi.x),
        (o.y, d.y, lo.y, hi.y),
        (o.z, d.z, lo.z, hi.z),
    ] {
        let inv = L::ONE / d;
        let a = (L::splat(lo) - o) * inv;
        let b = (L::splat(hi) - o) * inv;
        // On a slab's plane with d = 0, 0 · ∞ is NaN: min and max then keep the bound.
        near = near.max(a.min(b));
        far = far.min(a.max(b));
    }
    (near, far, near.cmp_le(far))
}

/// Tentative collisions along the lanes' rays within the medium's span, each lane's
/// one majorant segment at the global σ̄ (`medium::tracking`'s step (1) in lanes): the
/// part delta and ratio tracking share.
struct Tracker {
    t: L,
    active: L,
    segment: MajorantSegment<L>,
    scale: L,
}

impl Tracker {
    fn new(h: &HeterogeneousMedium, (o, d): (V3, V3), (tmin, tmax): (L, L), mask: L) -> Self {
        let (t, t1, some) = span(h, o, d, tmin, tmax);
        Tracker {
            t,
            active: if h.majorant > 0.0 {
                mask & some
            } else {
                L::ZERO
            },
            segment: MajorantSegment {
                t_min: t,
                t_max: t1,
                sigma_maj: L::splat(h.majorant),
            },
            scale: L::splat(h.scale),
        }
    }

    /// σ̄.
    #[inline(always)]
    fn majorant(&self) -> L {
        self.segment.sigma_maj
    }

    /// Steps the active lanes to their next tentative collision, an optical depth
    /// −ln(1 − u) on (one draw each), and drops those past the segment: whether any is
    /// left.
    #[inline(always)]
    fn step(&mut self, rngs: &mut [Pcg32]) -> bool {
        let u = draw_1d(self.active, rngs);
        let (t, inside) = self.segment.next_collision(self.t, optical_depth(u));
        self.t = self.active.blend(t, self.t);
        self.active &= inside;
        self.active.any()
    }
}

/// Delta tracking from `o` along unit `d` up to `tmax` for the lanes of `mask`
/// (`HeterogeneousMedium::sample_flight`).
#[inline(always)]
pub fn sample_flight(
    h: &HeterogeneousMedium,
    o: V3,
    d: V3,
    tmax: L,
    mask: L,
    rngs: &mut [Pcg32],
) -> Flight {
    let mut weight = V3::splat(Vec3::ONE);
    let mut albedo = V3::splat(Vec3::ONE);
    let mut collided = L::ZERO;
    let mut tracker = Tracker::new(h, (o, d), (L::ZERO, tmax), mask);
    // Grey σ_t: both weights are 1 (exactly, where rounding would make them 1 ± ulp).
    let grey = h.sigma_t.is_grey();
    while tracker.step(rngs) {
        let active = tracker.active;
        let p = o.add(d.scale(tracker.t));
        let q = h.sigma_t.local_point(p);
        // Real with probability P = mean(σ_t) / σ̄, else null; the grid read only where
        // its bounds leave the answer open.
        let u = draw_1d(active, rngs);
        let (sure_real, sure_null) = h
            .decided_by_bounds_at(q, u, tracker.majorant(), active)
            .unwrap_or((L::ZERO, L::ZERO));
        let look = active & !(sure_real | sure_null);
        let sigma_t = match look.any() {
            true => h.sigma_t.eval_local(q, look).scale(tracker.scale),
            false => V3::splat(Vec3::ZERO),
        };
        let real = sure_real | (look & u.cmp_lt(real_probability(sigma_t, tracker.majorant())));
        if real.any() {
            if !grey {
                weight = weight.select(real, weight.mul(real_weight(sigma_t)));
            }
            albedo = albedo.select(real, h.albedo.eval_at(p, real));
            collided |= real;
        }
        let null = active & !real;
        // No null collision can happen where σ_n is 0 in every channel (σ_t at the
        // majorant): the flight passes with weight 0 there. (A null the bounds decide
        // has σ_t below σ̄.)
        let (null_w, stuck) = null_weight(sigma_t, tracker.majorant());
        let stuck = null & look & stuck;
        weight = weight.select(stuck, V3::splat(Vec3::ZERO));
        tracker.active = null & !stuck;
        if !grey {
            weight = weight.select(tracker.active, weight.mul(null_w));
        }
    }
    Flight {
        collided,
        t: tracker.t,
        weight,
        albedo,
    }
}

/// Ratio tracking over [tmin, tmax] of the rays from `o` along unit `d`, for the lanes
/// of `mask` (1 elsewhere): an unbiased estimate of e^{−∫σ_t}
/// (`HeterogeneousMedium::transmittance`, with its Russian roulette).
pub fn transmittance(
    h: &HeterogeneousMedium,
    o: V3,
    d: V3,
    (tmin, tmax): (L, L),
    mask: L,
    rngs: &mut [Pcg32],
) -> V3 {
    let mut tr = V3::splat(Vec3::ONE);
    let mut tracker = Tracker::new(h, (o, d), (tmin, tmax), mask);
    while tracker.step(rngs) {
        let active = tracker.active;
        let q = h.sigma_t.local_point(o.add(d.scale(tracker.t)));
        // Where the bounds say the cell is empty σ_t is 0 and the factor exactly 1: no read.
        let look = match &h.bounds {
            Some(b) => active & b.at_lanes(q, active)[1].cmp_gt(L::ZERO),
            None => active,
        };
        let sigma_t = match look.any() {
            true => h.sigma_t.eval_local(q, look).scale(tracker.scale),
            false => V3::splat(Vec3::ZERO),
        };
        tr = tr.select(active, ratio_weight(sigma_t, tracker.majorant()).mul(tr));
        // Russian roulette once little is left (survivors weigh 1/q); a draw only where
        // something is left.
        let (play, end) = ratio_roulette(tr.max_element());
        let (play, end) = (active & play, active & end);
        if (play | end).any() {
            let u = draw_1d(play, rngs);
            let ended = end | (play & u.cmp_ge(L::splat(RATIO_SURVIVAL)));
            tr = tr.select(ended, V3::splat(Vec3::ZERO));
            tr = tr.select(play & !ended, tr.scale(L::splat(1.0 / RATIO_SURVIVAL)));
            tracker.active &= !ended;
        }
    }
    tr
}

/// `HeterogeneousMedium::depth_estimate` (an unbiased estimate of ∫σ, σ_t before the
/// scale) over the stretches [tmin, tmax] of the rays from `o` along unit `d`, for the
/// lanes of `mask` (0 elsewhere), lane by lane: one lookup a segment, for the
/// derivative in the scale.
pub fn depth_estimate(h: &HeterogeneousMedium, o: V3, d: V3, (tmin, tmax): (L, L), mask: L) -> V3 {
    let (t0, t1) = (tmin.to_array(), tmax.to_array());
    let mut out = [Vec3::ZERO; WIDTH];
    for k in lanes_of(mask.move_mask()) {
        let dk = d.lane_a(k);
        out[k] = h.depth_estimate(o.lane_a(k) + dk * t0[k], dk, t1[k] - t0[k]);
    }
    V3::from_fn(|k| out[k])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::packet::lanes::mask_of;
    use crate::medium::grid::{parse_vol, write_vol, Filter, Source, Volume, Wrap};
    use glam::{Affine3A, Vec3A};
    use wide::CmpEq;

    /// A 2×2×2 grey grid, thin and dense in turn along x, in the unit box.
    fn medium() -> HeterogeneousMedium {
        let data = [0.2, 3.0, 0.2, 3.0, 0.5, 2.0, 0.5, 2.0];
        let grid = parse_vol(&write_vol([2, 2, 2], 1, &data)).unwrap();
        let sigma_t = Volume::new(
            Source::Grid {
                grid,
                filter: Filter::Trilinear,
                wrap: Wrap::Clamp,
            },
            Affine3A::IDENTITY,
        );
        HeterogeneousMedium {
            majorant: 1.5 * sigma_t.max,
            // Bounded lookups, so that the lanes' delta tracking decides by them.
            bounds: crate::medium::lookup_bounds::LookupBounds::new(&sigma_t),
            sigma_t,
            albedo: Volume::new(Source::Const(Vec3::splat(0.7)), Affine3A::IDENTITY),
            scale: 1.0,
            bounded: true,
            majorants: None,
        }
    }

    /// The lanes' estimators have the scalar ones' means: ratio tracking's and delta
    /// tracking's pass weights both estimate the transmittance, and the collisions'
    /// mean distance matches; each within 5 standard errors of the scalar mean. Power:
    /// against a scalar medium 10% denser, every one of them is off by more.
    #[test]
    fn lanes_estimate_what_the_scalar_code_does() {
        let h = medium();
        let mut denser = medium();
        denser.scale = 1.1;
        denser.majorant *= 1.1;
        let o = Vec3A::new(-0.5, 0.3, 0.6);
        let d = Vec3A::new(1.0, 0.2, -0.1).normalize();
        let n = 20_000;
        let mut rngs: Vec<Pcg32> = (0..WIDTH as u64).map(|k| Pcg32::new(11, k)).collect();
        let mut rng = Pcg32::new(5, 99);
        let ol = V3::splat(Vec3::from(o));
        let dl = V3::splat(Vec3::from(d));
        let all = mask_of(|_| true);
        let mut lanes: [Vec<f64>; 3] = Default::default();
        let mut scalar: [[Vec<f64>; 3]; 2] = Default::default();
        for _ in 0..n / WIDTH {
            let tr = transmittance(&h, ol, dl, (L::ZERO, L::splat(3.0)), all, &mut rngs);
            let f = sample_flight(&h, ol, dl, L::splat(3.0), all, &mut rngs);
            for k in 0..WIDTH {
                lanes[0].push(tr.lane(k).x as f64);
                let c = f.collided.move_mask() >> k & 1 == 1;
                lanes[1].push(if c { 0.0 } else { f.weight.lane(k).x as f64 });
                lanes[2].push(if c { f.t.as_array_ref()[k] as f64 } else { 0.0 });
            }
            for (m, out) in [&h, &denser].into_iter().zip(&mut scalar) {
                for _ in 0..WIDTH {
                    out[0].push(m.transmittance(o, d, 3.0, &mut rng).x as f64);
                    let (c, w) = m.sample_flight(o, d, 3.0, &mut rng);
                    out[1].push(if c.is_some() { 0.0 } else { w.x as f64 });
                    out[2].push(c.map_or(0.0, |c| c.t as f64));
                }
            }
        }
        let stats = |v: &[f64]| {
            let m = v.iter().sum::<f64>() / v.len() as f64;
            let var = v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (v.len() - 1) as f64;
            (m, var / v.len() as f64)
        };
        for (i, name) in [
            "ratio tracking",
            "delta tracking's pass",
            "collision distance",
        ]
        .iter()
        .enumerate()
        {
            let (a, va) = stats(&lanes[i]);
            let [same, off] = [0, 1].map(|j| {
                let (b, vb) = stats(&scalar[j][i]);
                (a - b) / (va + vb).sqrt()
            });
            assert!(
                same.abs() < 5.0,
                "{name}: lanes {a} against scalar, z = {same}"
            );
            assert!(off.abs() >= 5.0, "{name}: 10% denser undetected, z = {off}");
        }
        // And the collisions carry the albedo volume's value.
        let f = sample_flight(&h, ol, dl, L::splat(3.0), all, &mut rngs);
        let hit = f.collided & f.albedo.x.cmp_eq(L::splat(0.7));
        assert_eq!(hit.move_mask(), f.collided.move_mask());
    }

    /// A turned 40 × 24 × 32 grey grid: a ramp along x, empty where it is below 0.
    fn large_medium() -> HeterogeneousMedium {
        let res = [40, 24, 32];
        let data: Vec<f32> = (0..res[0] * res[1] * res[2])
            .map(|i| {
                let (x, y) = (i % res[0], i / res[0] % res[1]);
                (x as f32 / 8.0 - 1.0 + (y % 5) as f32 * 0.1).max(0.0)
            })
            .collect();
        let grid = parse_vol(&write_vol(res, 1, &data)).unwrap();
        let sigma_t = Volume::new(
            Source::Grid {
                grid,
                filter: Filter::Trilinear,
                wrap: Wrap::Clamp,
            },
            Affine3A::from_rotation_y(0.5),
        );
        let albedo = Volume::new(Source::Const(Vec3::splat(0.8)), Affine3A::IDENTITY);
        let mut h = HeterogeneousMedium::new(sigma_t, albedo, 0.6, true);
        // The lanes track at the global majorant, the scalar code by local ones.
        h.bounds = crate::medium::lookup_bounds::LookupBounds::new(&h.sigma_t);
        h
    }

    /// The lookup bounds change no decision: delta tracking (lanes and scalar) and
    /// the lanes' ratio tracking give the same flights and transmittances with them as
    /// without, to the bit. Power: with bounds whose hi is 20% low, some flights differ;
    /// with every cell called empty, some transmittances.
    #[test]
    fn lookup_bounds_change_no_flight() {
        let bounded = large_medium();
        assert!(bounded.bounds.is_some());
        let mut plain = bounded.clone();
        plain.bounds = None;
        let mut wrong = bounded.clone();
        wrong.bounds = bounded.bounds.as_ref().map(|b| b.with_hi_times(0.8));
        let mut empty = bounded.clone();
        empty.bounds = bounded.bounds.as_ref().map(|b| b.with_hi_times(0.0));
        let all = mask_of(|_| true);
        let mut dir = Pcg32::new(2, 3);
        let mut differ = [0usize; 3];
        for i in 0..400u64 {
            // Rays from around the box through it, in every direction.
            let lane_ray = |_| {
                let o = Vec3::new(dir.next_1d(), dir.next_1d(), dir.next_1d()) * 3.0 - 1.0;
                let target = Vec3::new(dir.next_1d(), dir.next_1d(), dir.next_1d()) * 0.6;
                (o, (target - o).normalize())
            };
            let rays: Vec<(Vec3, Vec3)> = (0..WIDTH).map(lane_ray).collect();
            let o = V3::from_fn(|k| rays[k].0);
            let d = V3::from_fn(|k| rays[k].1);
            let streams: Vec<Pcg32> = (0..WIDTH as u64).map(|k| Pcg32::new(i, k)).collect();
            let run = |h: &HeterogeneousMedium| {
                let mut rngs = streams.clone();
                let f = sample_flight(h, o, d, L::splat(6.0), all, &mut rngs);
                let tr = transmittance(h, o, d, (L::ZERO, L::splat(6.0)), all, &mut rngs);
                let scalar: Vec<_> = (0..WIDTH)
                    .map(|k| {
                        let mut rng = streams[k].clone();
                        let (ro, rd) = (Vec3A::from(rays[k].0), Vec3A::from(rays[k].1));
                        let (c, w) = h.sample_flight(ro, rd, 6.0, &mut rng);
                        (c.map(|c| (c.t.to_bits(), c.albedo)), w)
                    })
                    .collect();
                let bits = |v: V3| {
                    (0..WIDTH)
                        .map(|k| v.lane(k).to_array().map(f32::to_bits))
                        .collect::<Vec<_>>()
                };
                let lanes = (
                    f.collided.move_mask(),
                    f.t.to_array().map(f32::to_bits),
                    bits(f.weight),
                    bits(tr),
                );
                (lanes, scalar)
            };
            let want = run(&plain);
            assert_eq!(run(&bounded), want, "ray batch {i}");
            let got = run(&wrong);
            differ[0] += (got.0 != want.0) as usize;
            differ[1] += (got.1 != want.1) as usize;
            differ[2] += (run(&empty).0 .3 != want.0 .3) as usize;
        }
        assert!(!differ.contains(&0), "wrong bounds unnoticed: {differ:?}");
    }
}
