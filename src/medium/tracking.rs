//! Tracking against a majorant (pbrt-v4's `SampleT_maj`, Sec. 14.1.2 of "Physically
//! Based Rendering", 4th ed.): a medium that varies in space yields the ray's majorant
//! segments, stretches [t_min, t_max] over which σ_t ≤ σ̄, and one loop draws the
//! tentative collisions along them: exponential optical depths τ, spent at each
//! segment's own σ̄,
//!
//!   t_{k+1} = t_k + τ / σ̄,   τ = −ln(1 − u),                                   (1)
//!
//! with what is left of τ at a segment's end carried into the next (the exponential is
//! memoryless, so carrying it or drawing anew have one expectation; carrying spends no
//! draw on the cells a flight crosses). The caller decides at each tentative collision:
//! delta tracking (free flights) and ratio tracking (shadow rays) differ only there.
//!
//! The segments come from the global majorant (one segment over the medium's span) or
//! from a majorant grid (`medium::majorant`, one a cell; the segment types live there). The lane path tracks at the
//! global majorant with the same step (1) in lanes (`MajorantSegment<L>`).

pub use super::majorant::{MajorantSegment, MajorantSegments};
use crate::sampling::Pcg32;
use crate::simd::Float;

/// −ln(1 − u), an exponential optical depth from uniform `u`: the distance to the next
/// tentative collision in units of 1 / σ̄ (as `medium::sample_distance` at σ = 1).
#[inline(always)]
pub fn optical_depth<F: Float>(u: F) -> F {
    (F::one() - u).ln().negate()
}

/// Tentative collisions along `segments` (1): `collide(t, σ̄, rng)` decides at each
/// whether the tracking ends there, and with what; None once the segments are spent.
/// The draws: one τ before the first collision and one after each (none where there is
/// no segment).
pub fn sample_t_maj<T>(
    mut segments: impl Iterator<Item = MajorantSegment<f32>>,
    rng: &mut Pcg32,
    mut collide: impl FnMut(f32, f32, &mut Pcg32) -> Option<T>,
) -> Option<T> {
    let mut segment = segments.next()?;
    let mut tau = optical_depth(rng.next_1d());
    let mut t = segment.t_min;
    loop {
        if segment.sigma_maj > 0.0 {
            loop {
                let (next, inside) = segment.next_collision(t, tau);
                if !inside {
                    break;
                }
                t = next;
                if let Some(answer) = collide(t, segment.sigma_maj, rng) {
                    return Some(answer);
                }
                tau = optical_depth(rng.next_1d());
            }
        }
        // The rest of the segment spends σ̄ (t_max − t) of τ.
        tau = (tau - segment.sigma_maj * (segment.t_max - t)).max(0.0);
        segment = segments.next()?;
        t = segment.t_min;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn segments(cuts: &[(f32, f32, f32)]) -> Vec<MajorantSegment<f32>> {
        cuts.iter()
            .map(|&(t_min, t_max, sigma_maj)| MajorantSegment {
                t_min,
                t_max,
                sigma_maj,
            })
            .collect()
    }

    /// The count's mean and variance of tentative collisions along `cuts`.
    fn count(cuts: &[(f32, f32, f32)], seed: u64, trials: usize) -> (f64, f64) {
        let mut rng = Pcg32::new(3, seed);
        let (mut sum, mut sq) = (0f64, 0f64);
        for _ in 0..trials {
            let mut n = 0f64;
            sample_t_maj(
                segments(cuts).into_iter(),
                &mut rng,
                |_, _, _| -> Option<()> {
                    n += 1.0;
                    None
                },
            );
            sum += n;
            sq += n * n;
        }
        let mean = sum / trials as f64;
        (mean, sq / trials as f64 - mean * mean)
    }

    /// The tentative collisions are a Poisson process of rate σ̄(t): their count has
    /// mean and variance ∫σ̄ however the ray is cut, across cells of other rates and an
    /// empty one (τ carried over), within 5 standard errors. Power: the same cells with
    /// every σ̄ 5% higher are told apart.
    #[test]
    fn tentative_collisions_are_poisson_at_the_segments_rates() {
        let trials = 40_000;
        let cells = [
            (0.0, 1.0, 2.0),
            (1.0, 2.0, 0.0),
            (2.0, 3.5, 5.0),
            (3.5, 5.0, 1.0),
        ];
        // ∫σ̄ = 2 + 0 + 7.5 + 1.5.
        let want = 11.0;
        let band = 5.0 * (want / trials as f64).sqrt();
        for (name, cuts) in [
            ("one segment", vec![(0.0, 5.0, 2.2)]),
            ("four cells", cells.to_vec()),
        ] {
            let (mean, var) = count(&cuts, 1, trials);
            assert!((mean - want).abs() < band, "{name}: mean {mean}");
            assert!((var - want).abs() < 0.05 * want, "{name}: variance {var}");
        }
        let denser: Vec<_> = cells.iter().map(|&(a, b, s)| (a, b, 1.05 * s)).collect();
        let (mean, _) = count(&denser, 2, trials);
        assert!((mean - want).abs() >= band, "5% denser undetected: {mean}");
    }
}
