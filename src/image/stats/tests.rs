//! The comparison's tests: two noisy images statistically, then each part of the
//! filtered-image logic on constructed inputs with answers known by hand (lattice
//! spacing, the per-lattice allowance, block gaps, the variance inflation, the
//! Welch–Satterthwaite degrees of freedom of the global test).

use super::*;

fn noisy(seed: u64, n: usize, k: usize, offset: f32) -> Vec<Vec<[f32; 3]>> {
    let mut rng = crate::sampling::Pcg32::for_pixel(seed, 0);
    (0..k)
        .map(|_| {
            (0..n)
                .map(|i| {
                    let base = 0.5 + 0.3 * ((i % 17) as f32 / 17.0);
                    // Sum of 12 uniforms − 6: approximately N(0, 1).
                    let g = |r: &mut crate::sampling::Pcg32| {
                        (0..12).map(|_| r.next_1d()).sum::<f32>() - 6.0
                    };
                    [
                        base + offset + 0.05 * g(&mut rng),
                        base + 0.05 * g(&mut rng),
                        base + 0.05 * g(&mut rng),
                    ]
                })
                .collect()
        })
        .collect()
}

#[test]
fn same_distribution_passes_and_shift_fails() {
    let layout = PixelLayout::independent(64);
    let a = Estimate::from_chunks(&noisy(1, 4096, 8, 0.0), layout);
    let b = Estimate::from_chunks(&noisy(2, 4096, 8, 0.0), layout);
    let c = compare(&a, &b, layout, 1e-3, 1e-6);
    assert!(c.passed, "{c}");
    let shifted = Estimate::from_chunks(&noisy(3, 4096, 8, 0.01), layout);
    let c = compare(&shifted, &b, layout, 1e-3, 1e-6);
    assert!(!c.passed, "a 2% shift must be detected: {c}");
}

/// An estimate of `n` values from its moments, every channel alike, with a measured κ.
fn moments(mean: Vec<f64>, var: Vec<f64>, dof: f64, kappa: f64) -> Estimate {
    let three = |v: Vec<f64>| v.into_iter().map(|x| [x; 3]).collect();
    Estimate {
        inflation: Some([kappa; 3]),
        ..Estimate::from_moments(three(mean), three(var), dof)
    }
}

fn layout(width: usize, filter_radius: f32) -> PixelLayout {
    PixelLayout {
        width,
        filter_radius,
    }
}

/// Quantiles from tables: the standard normal's and Student's t's at 0.975.
const Z_975: f64 = 1.959_963_984_540_054;
const T7_975: f64 = 2.364_624_251_592_785;
const T14_975: f64 = 2.144_786_687_916_927;

#[test]
fn spacing_is_the_smallest_distance_sharing_no_sample() {
    // ⌈2r⌉: box 1, tent 2, a Gaussian of σ 0.5 (radius 4σ) 4; 2r between integers rounds up.
    for (r, s) in [(0.5, 1), (1.0, 2), (2.0, 4), (0.75, 2), (1.5, 3), (1.01, 3)] {
        assert_eq!(layout(8, r).spacing(), s, "radius {r}");
    }
}

/// P(Binomial(n, p) > k), summed term by term.
fn binomial_tail(n: u64, p: f64, k: u64) -> f64 {
    let choose = |n: u64, i: u64| (0..i).fold(1.0, |c, j| c * (n - j) as f64 / (j + 1) as f64);
    (k + 1..=n)
        .map(|i| choose(n, i) * p.powi(i as i32) * (1.0 - p).powi((n - i) as i32))
        .sum()
}

#[test]
fn allowance_is_the_binomial_tail_bound() {
    // 16 values at α 1e-3, budget 1e-6/12: P(> 2) ≈ C(16, 3) 1e-9 = 5.6e-7 is too much,
    // P(> 3) ≈ C(16, 4) 1e-12 = 1.8e-9 is not.
    assert_eq!(allowance(16, 1e-3, 1e-6 / 12.0), 3);
    for (n, p, budget) in [
        (16, 1e-3, 1e-6 / 12.0),
        (64, 1e-3, 1e-6 / 3.0),
        (40, 1e-2, 1e-4),
    ] {
        let want = (0..).find(|&k| binomial_tail(n, p, k) < budget).unwrap();
        assert_eq!(allowance(n as usize, p, budget) as u64, want, "{n}, {p}");
    }
}

/// z = 10 at the given pixels of an 8 × 8 image, 0 elsewhere.
fn with_outliers(at: &[(usize, usize)]) -> (Estimate, Estimate) {
    let mut mean = vec![1.0; 64];
    for (x, y) in at {
        mean[y * 8 + x] += 10.0;
    }
    // Var(a) + Var(b) = 1 per value; dof so many that t is nearly the normal.
    let a = moments(mean, vec![0.5; 64], 1e3, 1.0);
    let b = moments(vec![1.0; 64], vec![0.5; 64], 1e3, 1.0);
    (a, b)
}

/// With a filter of radius 1 the pixels 2 apart form 4 lattices of 16, each at a
/// quarter of the pixel test's budget (3e-6 / 3): 3 outliers allowed, where the whole
/// budget would allow 2 (P(Binomial(16, 1e-3) > 2) = 5.5e-7). 4 outliers fail in one
/// lattice and pass spread over the four. With the box filter the 64 pixels are one
/// family, allowed 3 (P(Binomial(64, 1e-3) > 3) = 6.0e-7).
#[test]
fn pixel_outliers_are_counted_per_lattice() {
    let (alpha, false_alarm) = (1e-3, 3e-6);
    let filtered = layout(8, 1.0);
    let one_lattice = [(0, 0), (2, 0), (0, 2), (6, 6)];
    let (a, b) = with_outliers(&one_lattice);
    let c = compare(&a, &b, filtered, alpha, false_alarm);
    assert_eq!(
        (c.pixels.values, c.pixels.outliers, c.pixels.allowed),
        (64, 4, 12)
    );
    assert!(!c.pixels.passed, "four outliers in one lattice: {c}");
    let (a, b) = with_outliers(&[(0, 0), (1, 0), (0, 1), (1, 1)]);
    let c = compare(&a, &b, filtered, alpha, false_alarm);
    assert!(c.pixels.passed, "one outlier per lattice: {c}");
    let (a, b) = with_outliers(&one_lattice);
    let c = compare(&a, &b, PixelLayout::independent(8), alpha, false_alarm);
    assert_eq!((c.pixels.outliers, c.pixels.allowed), (4, 3));
    assert!(!c.pixels.passed, "{c}");
}

/// Blocks of side max(8, 4s) use their inner block − (s − 1) rows and columns: a
/// difference in the gaps is invisible to them, one inside is seen with Var = κ Σ v.
#[test]
fn blocks_skip_their_gaps_and_inflate_the_variance() {
    let (w, h) = (16, 16);
    let kappa: f64 = 2.0;
    let d = |gap: bool| {
        let mean: Vec<f64> = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let in_gap = x % 8 == 7 || y % 8 == 7;
                // The first block's inner 7 × 7 pixels, or every gap pixel.
                let moved = if gap {
                    in_gap
                } else {
                    !in_gap && x < 8 && y < 8
                };
                if moved {
                    1.0 + 3.0 * (2.0 * kappa).sqrt() / 7.0
                } else {
                    1.0
                }
            })
            .collect();
        moments(mean, vec![1.0; w * h], 1e3, kappa)
    };
    let b = moments(vec![1.0; w * h], vec![1.0; w * h], 1e3, 1.0);
    // Radius 1: spacing 2, blocks of 8 with one gap row and column.
    let c = compare(&d(true), &b, layout(w, 1.0), 1e-3, 1e-6);
    assert_eq!((c.block, c.blocks.values), (8, 4));
    assert_eq!(c.blocks.max_abs_z, 0.0, "the gaps reached a block: {c}");
    assert!(c.global_z[0] > 0.0);
    // Inside: z = d / √(κ · 49 · 2 / 49²) = 7 d / √(2κ) = 3 (κ the larger side's).
    let c = compare(&d(false), &b, layout(w, 1.0), 1e-3, 1e-6);
    assert_eq!(c.inflation, [kappa; 3]);
    assert!((c.blocks.max_abs_z - 3.0).abs() < 1e-9, "{c}");
    // Radius 1.5: spacing 3, blocks of 12.
    let c = compare(&d(false), &b, layout(w, 1.5), 1e-3, 1e-6);
    assert_eq!((c.block, c.blocks.values), (12, 4));
}

/// Chunks whose deviation is one number per chunk across the image: every pair
/// covaries fully, so κ = 1 + (ordered pairs within reach) / pixels, the pairs counted
/// per offset as (w − |dx|)(h − |dy|). In the second channel the deviation alternates
/// by column, so a pair counts (−1)^dx: below 0 within reach 1 (κ clamped to 1), above
/// it within reach 2. A channel without variance has κ 1.
#[test]
fn inflation_counts_the_covarying_pairs() {
    let (w, h) = (5, 3);
    let eps = [0.3f32, -0.1, 0.05, -0.25];
    let chunks: Vec<Vec<[f32; 3]>> = eps
        .iter()
        .map(|e| {
            (0..w * h)
                .map(|i| {
                    let sign = if i % w % 2 == 0 { 1.0 } else { -1.0 };
                    [0.5 + e, 0.5 + sign * e, 0.5]
                })
                .collect()
        })
        .collect();
    let pairs = |reach: i64, alternate: bool| -> f64 {
        let mut n = 0;
        for dx in -reach..=reach {
            for dy in -reach..=reach {
                let sign = if alternate && dx % 2 != 0 { -1 } else { 1 };
                n += sign * (w as i64 - dx.abs()) * (h as i64 - dy.abs());
            }
        }
        (n - (w * h) as i64) as f64
    };
    // Reach 1: 2 · (4·3 + 5·2 + 2·4·2) = 76 ordered pairs; alternating, (5 − 2·4) ·
    // (3 + 2·2) − 15 = −36; reach 2: (5 − 8 + 6) · 9 − 15 = 12.
    assert_eq!(
        (pairs(1, false), pairs(1, true), pairs(2, true)),
        (76.0, -36.0, 12.0)
    );
    for (r, reach) in [(1.0, 1), (1.5, 2)] {
        let e = Estimate::from_chunks(&chunks, layout(w, r));
        let k = e.inflation.unwrap();
        let pixels = (w * h) as f64;
        let want = [
            1.0 + pairs(reach, false) / pixels,
            (1.0 + pairs(reach, true) / pixels).max(1.0),
            1.0,
        ];
        for c in 0..3 {
            assert!(
                (k[c] - want[c]).abs() < 1e-4 * want[c],
                "radius {r}: {k:?} vs {want:?}"
            );
        }
    }
    // The box filter: pixels share no sample, whatever the chunks say.
    let e = Estimate::from_chunks(&chunks, PixelLayout::independent(w));
    assert_eq!(e.inflation, Some([1.0; 3]));
}

#[test]
#[should_panic(expected = "needs one side's chunks")]
fn a_filtered_comparison_needs_chunks() {
    let a = Estimate::from_moments(vec![[1.0; 3]; 4], vec![[1.0; 3]; 4], 7.0);
    compare(&a, &a.clone(), layout(2, 1.0), 1e-3, 1e-6);
}

/// The global test's ν = (Σ v)² / Σ (v_a²/ν_a + v_b²/ν_b), the least over channels, on
/// inputs where it is known: at false-alarm 0.45 the quantile is at 0.975 (0.45 / 3 for
/// the global test, / 3 channels, / 2 sides).
#[test]
fn global_threshold_has_welch_satterthwaite_dof() {
    let n = 8;
    let zero = || vec![0.0; n];
    let global = |va: Vec<f64>, dof_a: f64, vb: Vec<f64>, dof_b: f64| {
        let a = Estimate::from_moments(
            vec![[1.0; 3]; n],
            va.iter().map(|v| [*v; 3]).collect(),
            dof_a,
        );
        let b = Estimate::from_moments(
            vec![[1.0; 3]; n],
            vb.iter().map(|v| [*v; 3]).collect(),
            dof_b,
        );
        compare(&a, &b, PixelLayout::independent(4), 0.15, 0.45)
    };
    let one = |k: usize| {
        let mut v = vec![0.0; n];
        v[k] = 2.0;
        v
    };
    // No variance anywhere: the normal quantile.
    assert!((global(zero(), 7.0, zero(), 7.0).global_threshold - Z_975).abs() < 1e-6);
    // One noisy value on one side: ν = ν_a = 7, whatever the other values.
    let c = global(one(3), 7.0, zero(), 1e3);
    assert!((c.global_threshold - T7_975).abs() < 1e-6, "{c}");
    // The pixel test's t at α/3/2 = 0.025 has ν = min(ν_a, ν_b) = 7.
    assert!((c.pixels.threshold - T7_975).abs() < 1e-6, "{c}");
    // Two equal values (either side): ν = (2v)² / (2v²/7) = 14.
    let c = global(one(3), 7.0, one(5), 7.0);
    assert!((c.global_threshold - T14_975).abs() < 1e-6, "{c}");
    let mut two = one(3);
    two[6] = 2.0;
    assert!((global(two, 7.0, zero(), 7.0).global_threshold - T14_975).abs() < 1e-6);
    // One value in one channel dominates: the least ν over channels.
    let a = Estimate::from_moments(
        vec![[1.0; 3]; n],
        (0..n)
            .map(|i| [1.0, if i == 0 { 1.0 } else { 0.0 }, 1.0])
            .collect(),
        7.0,
    );
    let b = Estimate::from_moments(vec![[1.0; 3]; n], vec![[0.0; 3]; n], 1e3);
    let c = compare(&a, &b, PixelLayout::independent(4), 0.15, 0.45);
    assert!((c.global_threshold - T7_975).abs() < 1e-6, "{c}");
}

/// At ν = 1e9 (statrs' t quantile does not finish there) the thresholds are the normal
/// quantile: pixel, block and global tests at 0.975 (the setup of the test above).
#[test]
fn huge_degrees_of_freedom_give_the_normal_quantile() {
    let a = Estimate::from_moments(vec![[1.0; 3]; 8], vec![[2.0; 3]; 8], 1e9);
    let c = compare(&a, &a.clone(), PixelLayout::independent(4), 0.15, 0.45);
    for threshold in [c.pixels.threshold, c.blocks.threshold, c.global_threshold] {
        assert!((threshold - Z_975).abs() < 1e-9, "{c}");
    }
}

/// Just below the switch the quantile is Student's t, just above the normal's; they
/// differ by the first Cornish–Fisher term z (z² + 1) / (4ν) (Abramowitz & Stegun
/// 26.7.5), under 1e-3 of z out to 6σ.
#[test]
fn the_switch_to_the_normal_quantile_is_seamless() {
    for p in [0.975, 1.0 - 1e-3 / 6.0, 1.0 - 1e-9] {
        let t = t_quantile(NORMAL_ABOVE_DOF, p);
        let z = t_quantile(NORMAL_ABOVE_DOF * (1.0 + 1e-9), p);
        let first_order = z * (z * z + 1.0) / (4.0 * NORMAL_ABOVE_DOF);
        assert!(
            (t - z - first_order).abs() < 1e-5 && (t - z) / z < 1e-3,
            "p {p}: t {t}, normal {z}"
        );
    }
}
