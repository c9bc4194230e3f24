//! Tracking whose derivatives in every voxel are estimated (reverse mode,
//! `integrator::backward`): delta tracking for free flights and ratio tracking for
//! shadow rays, made so that differentiating their weights with the sampling held
//! fixed (detached) is unbiased, and its variance bounded, for every density ≥ 0.
//!
//! In the null-collision form of the radiative transfer equation (Novák et al. 2018,
//! Sec. 5) tentative collisions come at a majorant rate σ̄; at each, a real collision is
//! chosen with probability P_r (else a null one), and the weights
//!
//!   real: σ_s / (σ̄ P_r),   null: σ_n / (σ̄ (1 − P_r)),   σ_n = σ̄ − σ_t,          (1)
//!
//! keep the estimator unbiased for any P_r in (0, 1). With σ̄ and P_r detached, the
//! derivative of a path's contribution C in a voxel value θ is C times the sum of
//! ∂ ln(weight)/∂θ over the tentative collisions:
//!
//!   real: ∂σ_s / σ_s = ∂σ_t / σ_t + ∂α / α,   null: −∂σ_t / σ_n.                   (2)
//!
//! This is unbiased only where the sampling reaches every point at which ∂σ_t ≠ 0.
//! Delta tracking as rendered (P_r = σ_t / σ̄, the weights α and 1, a grid's local
//! majorants), and Mitsuba 3's `prbvolpath`, which differentiates (1) with
//! P_r = σ_t / σ̄ at one global majorant, miss or nearly miss three places:
//! * where σ_t = 0 no real collision happens, so the in-scattering a density added there
//!   would bring (the ∂σ_s term) is never seen: an empty voxel's gradient is only the
//!   transmittance's, and a fit can never grow density from zero; where σ_t is small the
//!   term is 1/σ_t with probability σ_t/σ̄, of unbounded variance;
//! * where σ_t reaches σ̄ (the densest voxel, at the global majorant) σ_n → 0 and the
//!   null term −∂σ_t/σ_n has unbounded variance;
//! * an empty cell's local majorant is 0: no tentative collision samples its
//!   transmittance's derivative, and a thin cell's few samples give each a large term
//!   (a Poisson estimate of ∫f at rate λ has variance ∫f²/λ).
//!
//! Here, for the medium whose voxels are differentiated (both passes of the adjoint
//! render, so that they take the same paths): σ̄' = max(κ σ̄_cell, σ̄_floor) with κ > 1
//! and σ̄_floor a fraction of the grid's global majorant, so σ_n ≥ (1 − 1/κ) σ̄' and
//! every point of the box sees tentative collisions; the flight itself stays plain delta
//! tracking at σ̄' (P_r = σ_t/σ̄', weights α and 1). The ∂σ_s term is split by region:
//! where σ_t ≥ ρ it rides on the flight's real collisions (|term| ≤ 1/ρ); where σ_t < ρ,
//! each tentative collision forks, with probability ρ_g/σ̄' drawn from a stream of its
//! own, a ghost: a path from that point, scattered there with weight β/ρ_g, whose radiance
//! G estimates the in-scattering, and which carries ∂σ_s · G alone (its own derivatives
//! would be of second order). The rendered path is untouched by the ghosts, which are
//! traced in the replay only. ρ, ρ_g ≥ ρ and σ̄_floor come from the global majorant
//! (where the grid is empty or thin, from its box's diagonal: about one ghost per
//! crossing of an empty box).

use glam::{Vec3, Vec3A};

use super::heterogeneous::HeterogeneousMedium;
use super::majorant::{self, MajorantSegment, MajorantSegments};
use super::tracking::sample_t_maj;
use crate::sampling::Pcg32;

/// The majorant's inflation κ over the rendered one.
const INFLATION: f32 = 1.25;
/// σ̄_floor over the grid's global majorant (scale · its largest value).
const FLOOR_OF_GLOBAL: f32 = 0.1;
/// ρ over the global majorant.
const MIN_REAL_OF_GLOBAL: f32 = 0.005;
/// Where the grid is empty: σ̄_floor and ρ times the grid box's diagonal.
const FLOOR_PER_DIAGONAL: f32 = 1.0;
const MIN_REAL_PER_DIAGONAL: f32 = 0.1;
/// The ghosts' fork rate where σ_t < ρ, times the diagonal (at least ρ).
const GHOSTS_PER_DIAGONAL: f32 = 1.0;

/// The majorants and real-collision probability of differentiated tracking (the module
/// comment): σ̄' = max(κ σ̄, `floor`), P_r = max(σ_t, `min_real`) / σ̄'.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DifferentialTracking {
    pub floor: f32,
    pub min_real: f32,
    /// The rate at which ghosts fork where σ_t < `min_real`.
    pub ghost_rate: f32,
}

/// A tentative collision of differentiated delta tracking.
#[derive(Clone, Copy, Debug)]
pub struct Tentative {
    pub t: f32,
    pub p: Vec3A,
    /// σ_t there (with `scale`; grey).
    pub sigma_t: f32,
    /// σ̄' there.
    pub majorant: f32,
}

impl DifferentialTracking {
    /// The settings for `medium`, from its box's diagonal.
    pub fn for_medium(medium: &HeterogeneousMedium) -> DifferentialTracking {
        let [lo, hi] = medium.sigma_t.bbox;
        let diagonal = (hi - lo).length();
        let diagonal = if diagonal.is_finite() && diagonal > 0.0 {
            diagonal
        } else {
            1.0
        };
        let global = medium.majorant;
        DifferentialTracking {
            floor: (FLOOR_OF_GLOBAL * global).max(FLOOR_PER_DIAGONAL / diagonal),
            min_real: (MIN_REAL_OF_GLOBAL * global).max(MIN_REAL_PER_DIAGONAL / diagonal),
            ghost_rate: (MIN_REAL_OF_GLOBAL * global).max(GHOSTS_PER_DIAGONAL / diagonal),
        }
    }

    #[inline]
    fn majorant(&self, sigma_maj: f32) -> f32 {
        (sigma_maj * INFLATION).max(self.floor)
    }

    /// The majorant segments of `o + t d` within `medium`'s span up to `tmax`, inflated
    /// and floored: every point of the box is covered, also where σ_t = 0.
    fn segments<'a>(
        &'a self,
        medium: &'a HeterogeneousMedium,
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
    ) -> impl Iterator<Item = MajorantSegment<f32>> + 'a {
        let span = medium.span(o, d, tmax);
        let base = match (span, &medium.majorants) {
            (Some(span), Some(grid)) => {
                let (ol, dl) = majorant::to_local(&medium.sigma_t, o, d);
                MajorantSegments::Cells(grid.segments(ol, dl, span))
            }
            (span, _) => MajorantSegments::One(span.map(|(t_min, t_max)| MajorantSegment {
                t_min,
                t_max,
                sigma_maj: medium.majorant,
            })),
        };
        base.map(move |s| MajorantSegment {
            sigma_maj: self.majorant(s.sigma_maj),
            ..s
        })
    }

    /// Delta tracking at the majorants above from `o` along unit `d` up to `tmax` (grey
    /// σ_t; P_r = σ_t / σ̄', so every weight is 1 and α): `collide(c, real)` is told of
    /// every tentative collision, real or null, and the real one, if any, is returned.
    pub fn delta_tracking(
        &self,
        medium: &HeterogeneousMedium,
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
        rng: &mut Pcg32,
        mut collide: impl FnMut(Tentative, bool),
    ) -> Option<Tentative> {
        let mut real_one = None;
        let segments = self.segments(medium, o, d, tmax);
        sample_t_maj(segments, true, rng, |t, major, _, rng: &mut Pcg32| {
            let p = o + d * t;
            let sigma_t = medium.sigma_t_at(p).x;
            let c = Tentative {
                t,
                p,
                sigma_t,
                majorant: major,
            };
            let real = rng.next_1d() * major < sigma_t;
            collide(c, real);
            if real {
                real_one = Some(c);
            }
            real
        });
        real_one
    }

    /// Whether a ghost forks at tentative collision `c` (where σ_t < ρ), with draw
    /// `u`, and the rate its weight is divided by (its forks' rate per unit length).
    #[inline]
    pub fn ghost_forks(&self, c: &Tentative, u: f32) -> Option<f32> {
        let rate = self.ghost_rate.min(c.majorant);
        (c.sigma_t < self.min_real && u * c.majorant < rate).then_some(rate)
    }

    /// Ratio tracking at the majorants above: an unbiased estimate of the transmittance
    /// `exp(−∫₀^dist σ_t)` from `o` along `d` (grey); `null(p, σ_n)` is told of every
    /// tentative collision, whose factor σ_n/σ̄' has the derivative (2).
    pub fn ratio_tracking(
        &self,
        medium: &HeterogeneousMedium,
        o: Vec3A,
        d: Vec3A,
        dist: f32,
        rng: &mut Pcg32,
        mut null: impl FnMut(Vec3A, f32),
    ) -> Vec3 {
        let mut tr = 1.0f32;
        let segments = self.segments(medium, o, d, dist);
        let ended = sample_t_maj(segments, true, rng, |t, major, _, rng: &mut Pcg32| {
            let p = o + d * t;
            let sigma_n = major - medium.sigma_t_at(p).x;
            tr *= sigma_n / major;
            null(p, sigma_n);
            // Russian roulette once little is left, detached (survivors weigh 1/q).
            if tr < super::heterogeneous::RATIO_ROULETTE_BELOW {
                if rng.next_1d() >= super::heterogeneous::RATIO_SURVIVAL {
                    return true;
                }
                tr *= 1.0 / super::heterogeneous::RATIO_SURVIVAL;
            }
            false
        });
        if ended {
            Vec3::ZERO
        } else {
            Vec3::splat(tr)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::medium::grid::{parse_vol, write_vol, Filter, Source, Volume, Wrap};
    use glam::Affine3A;

    /// A 4³ grid with an empty half and a dense voxel, local majorants on.
    fn medium() -> HeterogeneousMedium {
        let data: Vec<f32> = (0..64)
            .map(|i| match i % 4 {
                0 | 1 => 0.0,
                _ => 0.5 + (i % 7) as f32 * 0.3,
            })
            .collect();
        let grid = parse_vol(&write_vol([4, 4, 4], 1, &data)).unwrap();
        let sigma_t = Volume::new(
            Source::Grid {
                grid,
                filter: Filter::Trilinear,
                wrap: Wrap::Clamp,
            },
            Affine3A::IDENTITY,
        );
        let albedo = Volume::new(Source::Const(Vec3::splat(0.8)), Affine3A::IDENTITY);
        HeterogeneousMedium::new(sigma_t, albedo, 3.0, true)
    }

    /// Both trackers keep the rendered ones' expectations: the transmittance (ratio
    /// tracking, and delta tracking's pass weight) and the mean real-collision distance,
    /// within 5 standard errors of the plain trackers' along rays through the empty and
    /// the dense part; every weight finite. Power: the medium at 1.1× its density differs.
    #[test]
    fn differential_tracking_has_the_rendered_expectations() {
        let m = medium();
        let denser = {
            let mut d = medium();
            d.set_scale(3.3);
            d
        };
        let dt = DifferentialTracking::for_medium(&m);
        let rays = [
            (Vec3A::new(-0.5, 0.3, 0.6), Vec3A::new(1.0, 0.05, 0.02)),
            (Vec3A::new(0.2, -0.5, 0.4), Vec3A::new(0.0, 1.0, 0.1)),
        ];
        let n = 60_000;
        let mut worst_power = 0f64;
        for (r, (o, d)) in rays.into_iter().enumerate() {
            let d = d.normalize();
            let stats = |xs: &[f64]| {
                let mean = xs.iter().sum::<f64>() / xs.len() as f64;
                let var =
                    xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (xs.len() - 1) as f64;
                (mean, var / xs.len() as f64)
            };
            let mut rng = Pcg32::new(5, r as u64);
            let plain = |m: &HeterogeneousMedium, rng: &mut Pcg32| {
                let (mut a, mut b, mut c) = (vec![], vec![], vec![]);
                for _ in 0..n {
                    a.push(m.transmittance(o, d, 3.0, rng).x as f64);
                    let (hit, w) = m.sample_flight(o, d, 3.0, rng);
                    b.push(if hit.is_none() { w.x as f64 } else { 0.0 });
                    c.push(hit.map_or(0.0, |h| h.t as f64));
                }
                [stats(&a), stats(&b), stats(&c)]
            };
            let (mut a, mut b, mut c) = (vec![], vec![], vec![]);
            for _ in 0..n {
                let tr = dt.ratio_tracking(&m, o, d, 3.0, &mut rng, |_, s| assert!(s > 0.0));
                a.push(tr.x as f64);
                let hit = dt.delta_tracking(&m, o, d, 3.0, &mut rng, |c, _| {
                    assert!(c.majorant - c.sigma_t >= 0.2 * c.majorant * 0.999)
                });
                b.push(if hit.is_none() { 1.0 } else { 0.0 });
                c.push(hit.map_or(0.0, |h| h.t as f64));
            }
            let ours = [stats(&a), stats(&b), stats(&c)];
            let want = plain(&m, &mut rng);
            let dense = plain(&denser, &mut rng);
            for i in 0..3 {
                let z = |x: (f64, f64), y: (f64, f64)| (x.0 - y.0) / (x.1 + y.1).sqrt().max(1e-30);
                let same = z(ours[i], want[i]);
                assert!(same.abs() < 5.0, "ray {r}, estimate {i}: z = {same}");
                worst_power = worst_power.max(z(ours[i], dense[i]).abs());
            }
        }
        assert!(worst_power >= 5.0, "1.1x density undetected: {worst_power}");
    }
}
