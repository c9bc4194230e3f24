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
//! from a majorant grid (`medium::majorant`, one a cell; the segment types live there).
//! The loop is written once over the number type: on one path it walks the ray's
//! segments; in lanes each lane tracks its own ray, the lanes stepping together until
//! the last one's tracking ends (there each lane's walk is one segment at the global σ̄:
//! walking the cells in lanes was tried and was slower, the lanes that cross many cells
//! holding up the others).

pub use super::majorant::{MajorantSegment, MajorantSegments};
use crate::sampling::Sampler;
use crate::simd::Float;

/// −ln(1 − u), an exponential optical depth from uniform `u`: the distance to the next
/// tentative collision in units of 1 / σ̄ (as `medium::sample_distance` at σ = 1).
#[inline(always)]
pub fn optical_depth<F: Float>(u: F) -> F {
    (F::one() - u).ln().negate()
}

/// A ray's majorant segments in turn, per path (pbrt-v4's `RayMajorantIterator`).
pub trait MajorantWalk<F: Float> {
    /// The next segment of the paths of `active`, and the paths that have one.
    fn next_segment(&mut self, active: F::Mask) -> (MajorantSegment<F>, F::Mask);
}

/// One path's segments from an iterator of them (a majorant grid's cells, or one).
impl<I: Iterator<Item = MajorantSegment<f32>>> MajorantWalk<f32> for I {
    #[inline(always)]
    fn next_segment(&mut self, _: bool) -> (MajorantSegment<f32>, bool) {
        match self.next() {
            Some(segment) => (segment, true),
            None => (NO_SEGMENT, false),
        }
    }
}

const NO_SEGMENT: MajorantSegment<f32> = MajorantSegment {
    t_min: 0.0,
    t_max: 0.0,
    sigma_maj: 0.0,
};

/// One segment per path, in the paths of `some` (the medium's span at its global σ̄).
pub struct OneSegment<F: Float> {
    pub segment: MajorantSegment<F>,
    pub some: F::Mask,
}

impl<F: Float> MajorantWalk<F> for OneSegment<F> {
    #[inline(always)]
    fn next_segment(&mut self, active: F::Mask) -> (MajorantSegment<F>, F::Mask) {
        let some = self.some;
        self.some = some & !some;
        (self.segment, active & some)
    }
}

/// Tentative collisions along each path's `segments` (1), in the paths of `mask`:
/// `collide(t, σ̄, active, sampler)` decides at each collision of the paths of `active`
/// which of them the tracking ends at (their answers are the caller's to keep); the
/// paths where it did are returned, the others ran past their segments. A path's draws:
/// one τ before its first collision and one after each it goes on from (none where it
/// has no segment), so that one path and a lane draw alike.
#[inline(always)]
pub fn sample_t_maj<F: Float, S: Sampler<F> + ?Sized>(
    mut segments: impl MajorantWalk<F>,
    mask: F::Mask,
    sampler: &mut S,
    mut collide: impl FnMut(F, F, F::Mask, &mut S) -> F::Mask,
) -> F::Mask {
    let (mut segment, mut active) = segments.next_segment(mask);
    let mut ended = active & !active;
    if !F::any(active) {
        return ended;
    }
    let mut tau = optical_depth(sampler.draw_1d(active));
    let mut t = segment.t_min;
    loop {
        let mut within = active & segment.sigma_maj.gt(F::zero());
        while F::any(within) {
            let (next, inside) = segment.next_collision(t, tau);
            within = within & inside;
            if !F::any(within) {
                break;
            }
            t = F::select(within, next, t);
            let done = collide(t, segment.sigma_maj, within, sampler);
            ended = ended | done;
            active = active & !done;
            within = within & !done;
            if !F::any(within) {
                break;
            }
            tau = F::select(within, optical_depth(sampler.draw_1d(within)), tau);
        }
        if !F::any(active) {
            return ended;
        }
        // The rest of the segment spends σ̄ (t_max − t) of τ.
        let spent = segment.sigma_maj * (segment.t_max - t);
        tau = F::select(active, (tau - spent).max(F::zero()), tau);
        let (next, some) = segments.next_segment(active);
        active = active & some;
        if !F::any(active) {
            return ended;
        }
        segment = MajorantSegment {
            t_min: F::select(active, next.t_min, segment.t_min),
            t_max: F::select(active, next.t_max, segment.t_max),
            sigma_maj: F::select(active, next.sigma_maj, segment.sigma_maj),
        };
        t = F::select(active, segment.t_min, t);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Pcg32;

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
            sample_t_maj(segments(cuts).into_iter(), true, &mut rng, |_, _, _, _| {
                n += 1.0;
                false
            });
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
