use super::*;
use crate::medium::grid::{parse_vol, write_vol, Filter, Source, Volume, Wrap};
use glam::Affine3A;
use wide::{f32x8, CmpEq};

fn medium(v: Vec3) -> HeterogeneousMedium {
    let sigma_t = Volume::new(Source::Const(v), Affine3A::IDENTITY);
    HeterogeneousMedium {
        majorant: 2.0 * sigma_t.max,
        sigma_t,
        albedo: Volume::new(Source::Const(Vec3::splat(0.5)), Affine3A::IDENTITY),
        scale: 1.0,
        bounded: true,
        majorants: None,
        bounds: None,
    }
}

#[test]
fn ratio_and_delta_tracking_give_beer_lambert() {
    // Chromatic σ_t in the unit box, ray through it along x from outside.
    let m = medium(Vec3::new(1.0, 2.0, 0.5));
    let o = Vec3A::new(-1.0, 0.5, 0.5);
    let d = Vec3A::X;
    let want = (-Vec3::new(1.0, 2.0, 0.5)).exp();
    let mut rng = Pcg32::new(7, 1);
    let n = 200_000;
    let mut tr = Vec3::ZERO;
    let mut pass = Vec3::ZERO;
    for _ in 0..n {
        tr += m.transmittance(o, d, 3.0, &mut rng);
        let (c, w) = m.sample_flight(o, d, 3.0, &mut rng);
        if c.is_none() {
            pass += w;
        }
    }
    for (name, got) in [("ratio", tr / n as f32), ("delta", pass / n as f32)] {
        let err = (got - want).abs().max_element();
        assert!(err < 6e-3, "{name}: {got} vs {want}");
    }
}

/// A sparse 3-channel grid, turned and stretched, with local majorants or without.
fn grid_medium(scale: f32, local: bool) -> HeterogeneousMedium {
    let res = [12, 9, 7];
    let data: Vec<f32> = (0..12 * 9 * 7)
        .flat_map(|i| {
            let v = if i % 5 == 0 || i % 12 < 3 {
                1.0 + (i % 7) as f32
            } else {
                0.0
            };
            [v, 0.5 * v, 1.5 * v]
        })
        .collect();
    let grid = parse_vol(&write_vol(res, 3, &data)).unwrap();
    let to_world = Affine3A::from_scale_rotation_translation(
        Vec3::new(1.0, 1.5, 0.8),
        glam::Quat::from_rotation_z(0.3),
        Vec3::ZERO,
    );
    let sigma_t = Volume::new(
        Source::Grid {
            grid,
            filter: Filter::Trilinear,
            wrap: Wrap::Clamp,
        },
        to_world,
    );
    let majorants = local
        .then(|| crate::medium::majorant::MajorantGrid::new(&sigma_t, scale))
        .flatten();
    HeterogeneousMedium {
        majorant: sigma_t.max * scale,
        majorants,
        sigma_t,
        albedo: Volume::new(Source::Const(Vec3::splat(0.5)), Affine3A::IDENTITY),
        scale,
        bounded: true,
        bounds: None,
    }
}

/// Tracking by local majorants has the global majorant's expectation: transmittance
/// (ratio tracking, and delta tracking's pass weight) and the mean collision
/// distance, per channel, within 5 standard errors over rays through and beside the
/// box. Power: against the medium 10% denser, some of them are off by more.
#[test]
fn local_majorants_track_the_same_medium() {
    let global = grid_medium(1.0, false);
    let local = grid_medium(1.0, true);
    let denser = grid_medium(1.1, false);
    assert!(local.majorants.is_some());
    let rays = [
        (Vec3A::new(-1.0, 0.7, 0.4), Vec3A::new(1.0, 0.1, 0.05)),
        (Vec3A::new(0.3, -1.0, 0.3), Vec3A::new(0.2, 1.0, 0.1)),
        (Vec3A::new(1.5, 1.9, 0.9), Vec3A::new(-1.0, -0.7, -0.3)),
    ];
    let n = 40_000;
    let mut worst_off = 0f64;
    for (r, (o, d)) in rays.into_iter().enumerate() {
        let d = d.normalize();
        let mut rng = Pcg32::new(17, r as u64);
        let mut estimates = |m: &HeterogeneousMedium| {
            let mut v: [Vec<f64>; 7] = Default::default();
            for _ in 0..n {
                let tr = m.transmittance(o, d, 4.0, &mut rng);
                let (c, w) = m.sample_flight(o, d, 4.0, &mut rng);
                for ch in 0..3 {
                    v[ch].push(tr[ch] as f64);
                    v[3 + ch].push(if c.is_some() { 0.0 } else { w[ch] as f64 });
                }
                v[6].push(c.map_or(0.0, |c| c.t as f64));
            }
            v.map(|x| {
                let mean = x.iter().sum::<f64>() / n as f64;
                let var = x.iter().map(|y| (y - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
                (mean, var / n as f64)
            })
        };
        let (a, b, c) = (estimates(&global), estimates(&local), estimates(&denser));
        for i in 0..7 {
            let z = |x: (f64, f64), y: (f64, f64)| (x.0 - y.0) / (x.1 + y.1).sqrt().max(1e-30);
            let same = z(a[i], b[i]);
            assert!(same.abs() < 5.0, "ray {r}, estimate {i}: z = {same}");
            worst_off = worst_off.max(z(b[i], c[i]).abs());
        }
    }
    assert!(
        worst_off >= 5.0,
        "10% denser undetected: largest |z| {worst_off}"
    );
}

// The lanes' instances of the trackings, along each ray's one segment at the global σ̄
// (the walk the lane path gives them), against the one path's.

type L = f32x8;
type V3 = Vector3<L>;
const WIDTH: usize = 8;

fn lanes_flight(
    h: &HeterogeneousMedium,
    o: V3,
    d: V3,
    tmax: L,
    mask: L,
    rngs: &mut [Pcg32],
) -> FlightEnd<L> {
    let walk = h.global_segment(o, d, (L::ZERO, tmax));
    h.delta_tracking(o, d, walk, mask, rngs)
}

fn lanes_transmittance(
    h: &HeterogeneousMedium,
    o: V3,
    d: V3,
    span: (L, L),
    mask: L,
    rngs: &mut [Pcg32],
) -> V3 {
    h.ratio_tracking(o, d, h.global_segment(o, d, span), mask, rngs)
}

/// A 2×2×2 grey grid, thin and dense in turn along x, in the unit box.
fn two_by_two() -> HeterogeneousMedium {
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

/// The lanes' instances of the trackings (at the global majorant) have the one path's
/// means (by local majorants where the grid has them): ratio tracking's and delta
/// tracking's pass weights both estimate the transmittance, and the collisions'
/// mean distance matches; each within 5 standard errors of the scalar mean. Power:
/// against a scalar medium 10% denser, every one of them is off by more.
#[test]
fn lanes_estimate_what_the_scalar_code_does() {
    let h = two_by_two();
    let mut denser = two_by_two();
    denser.scale = 1.1;
    denser.majorant *= 1.1;
    let o = Vec3A::new(-0.5, 0.3, 0.6);
    let d = Vec3A::new(1.0, 0.2, -0.1).normalize();
    let n = 20_000;
    let mut rngs: Vec<Pcg32> = (0..WIDTH as u64).map(|k| Pcg32::new(11, k)).collect();
    let mut rng = Pcg32::new(5, 99);
    let ol = V3::splat(Vec3::from(o));
    let dl = V3::splat(Vec3::from(d));
    let all = L::mask(true);
    let mut lanes: [Vec<f64>; 3] = Default::default();
    let mut scalar: [[Vec<f64>; 3]; 2] = Default::default();
    for _ in 0..n / WIDTH {
        let tr = lanes_transmittance(&h, ol, dl, (L::ZERO, L::splat(3.0)), all, &mut rngs);
        let f = lanes_flight(&h, ol, dl, L::splat(3.0), all, &mut rngs);
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
    let f = lanes_flight(&h, ol, dl, L::splat(3.0), all, &mut rngs);
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
    let all = L::mask(true);
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
            let f = lanes_flight(h, o, d, L::splat(6.0), all, &mut rngs);
            let tr = lanes_transmittance(h, o, d, (L::ZERO, L::splat(6.0)), all, &mut rngs);
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
