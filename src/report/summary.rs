//! `table1.json`: a table run's images (`Row`, one per seed) summarized per scene,
//! method and accounting, with each ratio's 95% confidence interval over the seeds.
//!
//! For a method m and a baseline b with corrected MSEs x_i (n_m seeds) and y_j (n_b),
//! the ratio of means R = x̄ / ȳ has, to first order (the delta method),
//!
//!   SE(R)² ≈ R² (s_x² / (n_m x̄²) + s_y² / (n_b ȳ²)),                             (S1)
//!
//! and its interval is R ± t SE(R), t the 97.5% quantile of Student's t with the
//! Welch–Satterthwaite degrees of freedom of the two relative variances. The seeds of
//! m and b are independent renders. *Best* is the baseline (volpath, volpath_oidn,
//! volpath_filtered) of least mean corrected MSE in the same scene and accounting.
//!
//! Where m and b were rendered at the same seeds (pairs (x_i, y_i) that share samples,
//! as `regularize --frames 1` shares its first samples with a plain render at its seed),
//! their errors move together, and the paired form is the tighter, valid one: with
//! d_i = x_i − R y_i,
//!
//!   SE(R)² ≈ s_d² / (n ȳ²),                                                      (S2)
//!
//! t with n − 1 degrees of freedom (`paired_ratio_interval`).
//!
//! The correction's own standard error (`metrics::correction_se`) is common to every row
//! of a scene, so it moves all of them together.

use serde::{Deserialize, Serialize};

use super::row::{Accounting, Method, Row};
use crate::image::stats::t_quantile;

#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
pub struct Summary {
    pub scene: String,
    pub method: Method,
    pub accounting: Accounting,
    pub seeds: Vec<u64>,
    /// Means over the seeds.
    pub spp: f64,
    pub seconds: f64,
    pub mse: f64,
    pub mse_corrected: f64,
    /// The standard error of `mse_corrected` (the seeds' spread).
    pub mse_corrected_se: f64,
    /// The correction's own standard error (`metrics::correction_se`), common to the
    /// scene's rows.
    pub correction_se: f64,
    /// `[mean, ci_low, ci_high]` of the corrected MSE over plain volpath's (S1).
    pub ratio_to_volpath: Option<[f64; 3]>,
    /// The same over the best baseline's, `best`.
    pub ratio_to_best: Option<[f64; 3]>,
    pub best: Option<Method>,
}

fn mean_var(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let var = match x.len() {
        0 | 1 => f64::NAN,
        _ => x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0),
    };
    (mean, var)
}

/// (S1): `[R, low, high]` for the ratio of the means of `x` over `y`; the bounds NaN
/// where either has one value (the ratio stands, its interval needs seeds); None where
/// either is empty or a mean is not positive.
pub fn ratio_interval(x: &[f64], y: &[f64]) -> Option<[f64; 3]> {
    if x.is_empty() || y.is_empty() {
        return None;
    }
    let ((mx, vx), (my, vy)) = (mean_var(x), mean_var(y));
    if !(mx > 0.0 && my > 0.0) {
        return None;
    }
    let r = mx / my;
    if x.len() < 2 || y.len() < 2 {
        return Some([r, f64::NAN, f64::NAN]);
    }
    let a = vx / (x.len() as f64 * mx * mx);
    let b = vy / (y.len() as f64 * my * my);
    let se = r * (a + b).sqrt();
    let dof = match a + b > 0.0 {
        true => (a + b).powi(2) / (a * a / (x.len() as f64 - 1.0) + b * b / (y.len() as f64 - 1.0)),
        false => (x.len() + y.len() - 2) as f64,
    };
    // image::stats' quantile: the one place that handles a huge ν (statrs' does not finish).
    let t = t_quantile(dof.max(1.0), 0.975);
    Some([r, r - t * se, r + t * se])
}

/// (S2): `[R, low, high]` for the ratio of the means of paired `x` over `y` (the same
/// seeds, in the same order); the bounds NaN for one pair; None where the lengths
/// differ, there are none, or a mean is not positive.
pub fn paired_ratio_interval(x: &[f64], y: &[f64]) -> Option<[f64; 3]> {
    if x.is_empty() || x.len() != y.len() {
        return None;
    }
    let ((mx, _), (my, _)) = (mean_var(x), mean_var(y));
    if !(mx > 0.0 && my > 0.0) {
        return None;
    }
    let r = mx / my;
    let d: Vec<f64> = x.iter().zip(y).map(|(x, y)| x - r * y).collect();
    let (_, vd) = mean_var(&d);
    if x.len() < 2 {
        return Some([r, f64::NAN, f64::NAN]);
    }
    let n = x.len() as f64;
    let se = (vd / n).sqrt() / my;
    let t = t_quantile(n - 1.0, 0.975);
    Some([r, r - t * se, r + t * se])
}

/// The rows summarized, in the order of their first appearance; `correction` gives each
/// scene's correction standard error.
pub fn summarize(rows: &[Row], correction: impl Fn(&str) -> f64) -> Vec<Summary> {
    let mut keys: Vec<(&str, Method, Accounting)> = Vec::new();
    for r in rows {
        let k = (r.scene.as_str(), r.method, r.accounting);
        if !keys.contains(&k) {
            keys.push(k);
        }
    }
    let of = |scene: &str, method: Method, accounting: Accounting| -> Vec<&Row> {
        rows.iter()
            .filter(|r| r.scene == scene && r.method == method && r.accounting == accounting)
            .collect()
    };
    let corrected = |rs: &[&Row]| -> Vec<f64> { rs.iter().map(|r| r.mse_corrected).collect() };
    let mean = |v: Vec<f64>| mean_var(&v).0;
    keys.iter()
        .map(|&(scene, method, accounting)| {
            let own = of(scene, method, accounting);
            let x = corrected(&own);
            let best = [
                Method::Volpath,
                Method::VolpathOidn,
                Method::VolpathFiltered,
            ]
            .into_iter()
            .filter(|b| !of(scene, *b, accounting).is_empty())
            .min_by(|a, b| {
                let (ma, mb) = (
                    mean(corrected(&of(scene, *a, accounting))),
                    mean(corrected(&of(scene, *b, accounting))),
                );
                ma.total_cmp(&mb)
            });
            // A row against itself is 1 exactly (the interval of two independent sets of
            // seeds does not apply).
            let versus = |b: Method| match b == method {
                true => (x.len() >= 2).then_some([1.0; 3]),
                false => ratio_interval(&x, &corrected(&of(scene, b, accounting))),
            };
            let (mx, vx) = mean_var(&x);
            Summary {
                scene: scene.to_string(),
                method,
                accounting,
                seeds: own.iter().map(|r| r.seed).collect(),
                spp: mean(own.iter().map(|r| r.spp as f64).collect()),
                seconds: mean(own.iter().map(|r| r.seconds).collect()),
                mse: mean(own.iter().map(|r| r.mse).collect()),
                mse_corrected: mx,
                mse_corrected_se: (vx / x.len() as f64).sqrt(),
                correction_se: correction(scene),
                ratio_to_volpath: versus(Method::Volpath),
                ratio_to_best: best.and_then(versus),
                best,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Standard normal draws (Box–Muller on a 64-bit LCG) from `seed`.
    fn gaussian(seed: u64) -> impl FnMut() -> f64 {
        let mut state = seed;
        move || {
            let mut u = || {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
            };
            let (a, b) = (u(), u());
            (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
        }
    }

    /// Counts whether the true ratio 2 lies within an interval `[r − w, r + w]`, w the
    /// interval's half-width `hi − r` at the 95%, 99% and 90% normal widths.
    fn count_covering(covered: &mut [usize; 3], r: f64, hi: f64) {
        for (c, w) in covered.iter_mut().zip([1.0, 2.576 / 1.96, 1.645 / 1.96]) {
            *c += ((2.0 - r).abs() <= w * (hi - r)) as usize;
        }
    }

    /// Gaussian MSEs around 2 and 1 (relative spread 20%), 4 seeds each: the 95% interval
    /// must cover 2 in 94–97.5% of 4000 trials (measured: 96.1%; the delta method at n = 4
    /// is slightly conservative; the binomial standard error of the rate is 0.3 points).
    /// Power: the same intervals at the normal's 99% or 90% width (×2.576/1.96 or
    /// ×1.645/1.96: measured 98.4% and 93.1%) fall outside it, so a wrong level is caught.
    #[test]
    fn the_ratio_interval_covers_the_true_ratio_at_about_its_level() {
        let mut gauss = gaussian(12345);
        let trials = 4000;
        let mut covered = [0usize; 3];
        for _ in 0..trials {
            let x: Vec<f64> = (0..4).map(|_| 2.0 * (1.0 + 0.2 * gauss())).collect();
            let y: Vec<f64> = (0..4).map(|_| 1.0 + 0.2 * gauss()).collect();
            let [r, _, hi] = ratio_interval(&x, &y).unwrap();
            count_covering(&mut covered, r, hi);
        }
        let [rate, rate_99, rate_90] = covered.map(|c| c as f64 / trials as f64);
        println!("coverage {rate} (99% width {rate_99}, 90% width {rate_90})");
        let band = 0.94..=0.975;
        assert!(band.contains(&rate), "coverage {rate}");
        assert!(!band.contains(&rate_99), "a 99% interval passes: {rate_99}");
        assert!(!band.contains(&rate_90), "a 90% interval passes: {rate_90}");
    }

    /// Pairs sharing most of their noise (x = 2·(1 + 0.2 g + 0.05 h), y = 1 + 0.2 g), 8
    /// seeds: the paired interval must cover 2 at about its level in 4000 trials (and a
    /// 99% or 90% width must not), and be narrower than the unpaired (S1) one, which
    /// ignores that the pairs move together.
    #[test]
    fn the_paired_interval_covers_at_its_level_and_is_narrower_for_shared_noise() {
        let mut gauss = gaussian(777);
        let trials = 4000;
        let mut covered = [0usize; 3];
        let mut narrower = 0;
        for _ in 0..trials {
            let (mut x, mut y) = (vec![], vec![]);
            for _ in 0..8 {
                let (g, h) = (gauss(), gauss());
                x.push(2.0 * (1.0 + 0.2 * g + 0.05 * h));
                y.push(1.0 + 0.2 * g);
            }
            let [r, _, hi] = paired_ratio_interval(&x, &y).unwrap();
            count_covering(&mut covered, r, hi);
            let [_, _, unpaired_hi] = ratio_interval(&x, &y).unwrap();
            narrower += (hi - r < unpaired_hi - r) as usize;
        }
        let [rate, rate_99, rate_90] = covered.map(|c| c as f64 / trials as f64);
        println!("paired coverage {rate} (99% width {rate_99}, 90% width {rate_90}), narrower in {narrower}");
        let band = 0.94..=0.965;
        assert!(band.contains(&rate), "coverage {rate}");
        assert!(!band.contains(&rate_99), "a 99% interval passes: {rate_99}");
        assert!(!band.contains(&rate_90), "a 90% interval passes: {rate_90}");
        assert!(
            narrower > trials * 99 / 100,
            "narrower in {narrower} of {trials}"
        );
        assert_eq!(paired_ratio_interval(&[1.0], &[1.0, 2.0]), None);
        let [r, lo, _] = paired_ratio_interval(&[3.0], &[1.0]).unwrap();
        assert!(r == 3.0 && lo.is_nan());
    }

    #[test]
    fn no_interval_from_one_seed_or_a_nonpositive_mean() {
        let [r, lo, hi] = ratio_interval(&[3.0], &[1.0, 2.0]).unwrap();
        assert!(r == 2.0 && lo.is_nan() && hi.is_nan(), "{r} [{lo}, {hi}]");
        assert_eq!(ratio_interval(&[], &[1.0, 2.0]), None);
        assert_eq!(ratio_interval(&[-1.0, -2.0], &[1.0, 2.0]), None);
        let [r, lo, hi] = ratio_interval(&[2.0, 2.0], &[1.0, 1.0]).unwrap();
        assert_eq!((r, lo, hi), (2.0, 2.0, 2.0));
    }
}
