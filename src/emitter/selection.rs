//! Which emitter a vertex samples for next-event estimation.
//!
//! Mitsuba 3 picks one uniformly (`Scene::sample_emitter`). With two to
//! [`WEIGHED_MAX`] emitters, here the choice follows an estimate `w_i` of what each
//! delivers at the vertex, mixed with the uniform choice so that every emitter keeps a
//! share:
//!
//! `p_i = (1 − ε) · w_i / Σ_j w_j + ε / n`, ε = [`DEFENSIVE`].
//!
//! * directional: its mean irradiance E;
//! * point: I / d²; spot: I · falloff / d² (0 outside its cone);
//! * area: L · min(2π, A⊥ / d²), d from the vertex to the shape's bounding sphere, A⊥
//!   the largest area the shape can show (a sphere's cross-section πr², a flat shape's
//!   area): the solid angle it can subtend, without occlusion; 0 behind a flat emitter
//!   (one-sided);
//! * constant and envmap: π · mean L, what a surface facing a uniform sky receives.
//!
//! (Means are over the RGB channels.) An environment counts a quarter of the 4π · L a
//! medium point receives from it: it is also reached by BSDF and phase sampling
//! everywhere, with MIS, while a delta light is reached by emitter sampling only and a
//! small area light seldom otherwise. In an A/B at fixed selection probabilities of the
//! non-sky emitter (0.5, Mitsuba's, up to 0.98), the MSE of the bench Bunny (a directional
//! light and a sky) fell from 2.04e-4 at 0.5 to 1.17e-4 at 0.75 and 0.80e-4 at 0.95, and
//! Lucy's (an area light and a sky) from 2.02e-4 to 1.18e-4 at 0.9 and 1.12e-4 at 0.95.
//!
//! Under `volpath` and `path` a `constant` sky is not among the choices at all (n
//! counts the others): it is found by BSDF and phase sampling alone, which draw
//! directions in proportion to f · cos or to the phase function, while its emitter
//! samples are uniform over the sphere. At equal spp (64², 3 seeds) the MSE fell on the
//! furnace from 3.87e-4 to 4.35e-5, on max_depth_directional (a directional light and a
//! sky) from 2.40e-4 to 5.37e-5, on the bench Bunny from 2.30e-4 to 1.49e-4 and on Lucy
//! from 2.43e-4 to 2.27e-4, with 0–25% less time; on the medium cube lit by a sky alone
//! (σ_t 10, where emitter sampling's exact transmittance should help most) by 12% at
//! albedo 0.5 and 9% at 0.95, with 39% less time. Under `path` (64 spp): conductor −12%,
//! plastic −20%, roughplastic −29%, spot −60%, dielectric_sphere −2%, anisotropic −44%,
//! with 3–27% less time. `direct` still samples the sky: its emitter samples may be all
//! it takes.
//!
//! Counting a sphere light's whole area 4πr² instead of its cross-section πr² made it
//! look four times brighter than it is to every vertex: on a Bunny medium (σ_t 8, HG
//! 0.5) lit by a small sphere light and a point light of about equal power, 64², 64 spp,
//! 6 seeds, the per-pixel variance fell from 1.38e-4 to 0.86e-4 with the cross-section
//! (Mitsuba 3's uniform choice: 2.16e-4), and from 1.88e-4 to 1.39e-4 with a sky added.
//!
//! Any positive `p` keeps the estimate unbiased: the emitter-sampled value is divided
//! by it, and the MIS weight of an emitter hit uses the same `p`, evaluated at the
//! vertex the path left ([`EmitterSelection::pdf`]); an emitter never picked has `p` = 0
//! and its hits weigh 1, which is unbiased where BSDF and phase sampling reach every
//! direction it lights (a sky: everywhere). Above [`WEIGHED_MAX`] candidates, or where
//! no estimate is positive, the choice is uniform, as in Mitsuba.

use std::f32::consts::PI;

use glam::{Vec2, Vec3, Vec3A};

use super::{Emitter, Spot};
use crate::geometry::shape::Geometry;

/// Up to this many emitters, the choice is weighed per vertex (a loop over them all);
/// with more it is uniform.
pub const WEIGHED_MAX: usize = 8;

/// The uniform share of the choice: every emitter is picked with probability at least
/// `DEFENSIVE / n`, so no emitter the estimate underrates is starved.
pub const DEFENSIVE: f32 = 0.1;

/// What an emitter is estimated to deliver at a point.
#[derive(Clone, Debug)]
enum Estimate {
    /// The same everywhere (directional, environment).
    Constant(f32),
    Point {
        position: Vec3A,
        intensity: f32,
    },
    Spot {
        spot: Spot,
        intensity: f32,
    },
    Area {
        center: Vec3A,
        radius: f32,
        /// The largest area the shape shows any point (see `Estimate::new`).
        projected: f32,
        radiance: f32,
        /// A flat emitter's plane (a point on it, its normal): it lights only the side
        /// its normal faces.
        front: Option<(Vec3A, Vec3A)>,
    },
}

impl Estimate {
    fn new(e: &Emitter, geometries: &[Geometry]) -> Estimate {
        let mean = |c: Vec3| (c.x + c.y + c.z) / 3.0;
        match e {
            Emitter::Directional { irradiance, .. } => Estimate::Constant(mean(*irradiance)),
            Emitter::Constant { radiance } => Estimate::Constant(PI * mean(*radiance)),
            Emitter::EnvMap(map) => Estimate::Constant(PI * mean(map.mean_radiance())),
            Emitter::Point {
                position,
                intensity,
            } => Estimate::Point {
                position: *position,
                intensity: mean(*intensity),
            },
            Emitter::Spot(spot) => Estimate::Spot {
                spot: spot.clone(),
                intensity: mean(spot.intensity),
            },
            // A sphere shows at most its cross-section πr² (a quarter of its area), a flat
            // shape its area; a mesh of unknown shape counts its whole area.
            Emitter::Area { shape, radiance } => {
                let g = &geometries[*shape as usize];
                let (center, radius, projected, front) = match g {
                    Geometry::Sphere(s) => (s.center, s.radius, PI * s.radius * s.radius, None),
                    Geometry::Planar(pl) => {
                        let (c, r) = g.bounds().bounding_sphere();
                        (
                            c,
                            r,
                            g.area(),
                            Some((pl.to_world.transform_point3a(Vec3A::ZERO), pl.normal)),
                        )
                    }
                    Geometry::Mesh(_) => {
                        let (c, r) = g.bounds().bounding_sphere();
                        (c, r, g.area(), None)
                    }
                };
                Estimate::Area {
                    center,
                    radius,
                    projected,
                    radiance: mean(*radiance),
                    front,
                }
            }
        }
    }

    #[inline]
    fn at(&self, p: Vec3A) -> f32 {
        match self {
            Estimate::Constant(w) => *w,
            Estimate::Point {
                position,
                intensity,
            } => intensity / (p - *position).length_squared(),
            Estimate::Spot { spot, intensity } => {
                let v = p - spot.position;
                intensity * spot.falloff(v) / v.length_squared()
            }
            Estimate::Area {
                center,
                radius,
                projected,
                radiance,
                front,
            } => {
                if front.is_some_and(|(o, n)| (p - o).dot(n) <= 0.0) {
                    return 0.0;
                }
                let d = ((p - *center).length() - radius).max(0.0);
                radiance * (projected / (d * d)).min(2.0 * PI)
            }
        }
    }
}

/// The emitter choice of a scene (see the module comment).
#[derive(Clone, Debug)]
pub struct EmitterSelection {
    /// The emitters the choice is among: all, or all but the constant environments when
    /// those are left to BSDF and phase sampling (see [`EmitterSelection::new`]).
    candidates: Vec<u32>,
    /// Per emitter: its place in `candidates`, or `None` if it is never picked.
    slot: Vec<Option<u32>>,
    /// One per candidate where the choice is weighed; empty where it is uniform.
    estimates: Vec<Estimate>,
}

impl EmitterSelection {
    /// The choice among `emitters`. With `constant_by_bsdf_only`, a `constant` emitter is
    /// never picked: it is found by BSDF and phase sampling alone, its hits then weighted
    /// 1 by MIS (its emitter pdf is 0). Under a uniform sky, those draw directions in
    /// proportion to f · cos or to the phase function (times a constant L), while emitter
    /// sampling draws them uniformly over the sphere: its samples add variance where the
    /// BSDF or phase function is not flat, and in a medium they break the balance between
    /// a path that escapes and one that scatters on.
    pub fn new(emitters: &[Emitter], geometries: &[Geometry], constant_by_bsdf_only: bool) -> Self {
        let skipped = |e: &Emitter| constant_by_bsdf_only && matches!(e, Emitter::Constant { .. });
        let mut candidates = Vec::new();
        let slot = emitters
            .iter()
            .enumerate()
            .map(|(i, e)| {
                (!skipped(e)).then(|| {
                    candidates.push(i as u32);
                    candidates.len() as u32 - 1
                })
            })
            .collect();
        let estimates = if (2..=WEIGHED_MAX).contains(&candidates.len()) {
            candidates
                .iter()
                .map(|&i| Estimate::new(&emitters[i as usize], geometries))
                .collect()
        } else {
            Vec::new()
        };
        EmitterSelection {
            candidates,
            slot,
            estimates,
        }
    }

    /// The selection probabilities at `p` of the candidates, in the first
    /// `candidates.len()` entries (where the choice is weighed: `estimates` holds one
    /// per candidate).
    #[inline]
    fn probabilities(&self, p: Vec3A) -> [f32; WEIGHED_MAX] {
        let n = self.candidates.len();
        let mut w = [0.0f32; WEIGHED_MAX];
        let uniform = 1.0 / n as f32;
        let mut total = 0.0;
        for (wi, e) in w.iter_mut().zip(&self.estimates) {
            // A NaN or negative estimate (a degenerate emitter) counts as none.
            *wi = e.at(p).max(0.0);
            total += *wi;
        }
        if !(total > 0.0 && total.is_finite()) {
            w[..n].fill(uniform);
            return w;
        }
        let scale = (1.0 - DEFENSIVE) / total;
        for wi in &mut w[..n] {
            *wi = *wi * scale + DEFENSIVE * uniform;
        }
        w
    }

    /// Picks an emitter for the vertex `p` with `u.x`: its index, the sample with
    /// `u.x` rescaled to [0, 1) for reuse, and the probability it was picked with.
    /// `None` when there is nothing to pick.
    #[inline]
    pub fn select(&self, p: Vec3A, u: Vec2) -> Option<(usize, Vec2, f32)> {
        let n = self.candidates.len();
        if n == 0 {
            return None;
        }
        if self.estimates.is_empty() {
            // Mitsuba's uniform choice, reusing the sample.
            let x = u.x * n as f32;
            let j = (x as usize).min(n - 1);
            let idx = self.candidates[j] as usize;
            return Some((idx, Vec2::new(x - j as f32, u.y), 1.0 / n as f32));
        }
        let probs = self.probabilities(p);
        let mut start = 0.0;
        for (j, &pj) in probs[..n].iter().enumerate() {
            if u.x < start + pj || j + 1 == n {
                let x = ((u.x - start) / pj).clamp(0.0, 1.0 - f32::EPSILON);
                return Some((self.candidates[j] as usize, Vec2::new(x, u.y), pj));
            }
            start += pj;
        }
        unreachable!("the loop returns at its last candidate")
    }

    /// The one emitter a vertex can pick, where there is exactly one (picked with
    /// probability 1 and the sample passed on unchanged).
    pub fn single(&self) -> Option<usize> {
        match self.candidates.as_slice() {
            [only] => Some(*only as usize),
            _ => None,
        }
    }

    /// The probability that [`EmitterSelection::select`] at `p` picks `index`.
    #[inline]
    pub fn pdf(&self, p: Vec3A, index: usize) -> f32 {
        let Some(j) = self.slot[index] else {
            return 0.0;
        };
        if self.estimates.is_empty() {
            1.0 / self.candidates.len() as f32
        } else {
            self.probabilities(p)[j as usize]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::shape::Planar;
    use glam::{Mat3A, Mat4};

    /// A rectangle light at the origin (facing +z, 2 × 2), a point light, a spot, a
    /// directional light and a sky.
    fn scene() -> (Vec<Emitter>, Vec<Geometry>) {
        let geometries = vec![Geometry::Planar(Planar::new(Mat4::IDENTITY, false, false))];
        let emitters = vec![
            Emitter::Area {
                shape: 0,
                radiance: Vec3::splat(10.0),
            },
            Emitter::Point {
                position: Vec3A::new(3.0, 0.0, 0.0),
                intensity: Vec3::splat(5.0),
            },
            Emitter::Spot(Spot::new(
                Vec3A::new(0.0, 3.0, 0.0),
                Mat3A::IDENTITY,
                Vec3::splat(50.0),
                0.5,
                0.4,
            )),
            Emitter::Directional {
                direction: Vec3A::NEG_Y,
                irradiance: Vec3::new(1.0, 2.0, 3.0),
            },
            Emitter::Constant {
                radiance: Vec3::splat(0.1),
            },
        ];
        (emitters, geometries)
    }

    #[test]
    fn probabilities_are_the_estimates_mixed_with_uniform() {
        let (emitters, geometries) = scene();
        let sel = EmitterSelection::new(&emitters, &geometries, false);
        let n = emitters.len() as f32;
        for p in [
            Vec3A::new(0.0, 0.0, 4.0),
            Vec3A::new(2.5, 0.0, 0.0),
            Vec3A::new(0.0, 1.0, 0.5),
            Vec3A::new(-20.0, 5.0, 0.0),
        ] {
            let probs = sel.probabilities(p);
            let total: f32 = probs[..emitters.len()].iter().sum();
            assert!((total - 1.0).abs() < 1e-5, "{p}: sum {total}");
            assert!(probs[..emitters.len()]
                .iter()
                .all(|&x| x >= DEFENSIVE / n - 1e-7));
            // The estimates by hand (area: sqrt 2 bounding radius; one-sided, facing +z,
            // so nothing in or behind its plane).
            let d_area = (p.length() - 2f32.sqrt()).max(0.0);
            let area = if p.z > 0.0 {
                10.0 * (4.0 / (d_area * d_area)).min(2.0 * PI)
            } else {
                0.0
            };
            let w = [
                area,
                5.0 / (p - Vec3A::new(3.0, 0.0, 0.0)).length_squared(),
                match &emitters[2] {
                    Emitter::Spot(s) => {
                        let v = p - s.position;
                        50.0 * s.falloff(v) / v.length_squared()
                    }
                    _ => unreachable!(),
                },
                2.0,
                PI * 0.1,
            ];
            let sum: f32 = w.iter().sum();
            for i in 0..5 {
                let want = 0.9 * w[i] / sum + 0.1 / n;
                assert!(
                    (probs[i] - want).abs() < 1e-5,
                    "{p} emitter {i}: {} vs {want}",
                    probs[i]
                );
                assert_eq!(sel.pdf(p, i), probs[i]);
            }
        }
    }

    /// A sphere light shows at most its cross-section: against a point light of the same
    /// power (4π I = π L · 4πr²), far away, the two are picked about equally often.
    #[test]
    fn a_sphere_light_counts_its_cross_section() {
        let r = 0.1;
        let geometries = vec![Geometry::Sphere(crate::geometry::shape::Sphere {
            center: Vec3A::ZERO,
            radius: r,
            flip_normals: false,
            axes: Mat3A::IDENTITY,
        })];
        let emitters = vec![
            Emitter::Area {
                shape: 0,
                radiance: Vec3::splat(1.0),
            },
            Emitter::Point {
                position: Vec3A::ZERO,
                intensity: Vec3::splat(PI * r * r),
            },
        ];
        let sel = EmitterSelection::new(&emitters, &geometries, false);
        let p = Vec3A::new(0.0, 0.0, 50.0);
        let probs = sel.probabilities(p);
        let d = 50.0 - r;
        let w = [PI * r * r / (d * d), PI * r * r / (50.0 * 50.0)];
        let want = 0.9 * w[0] / (w[0] + w[1]) + 0.05;
        assert!((probs[0] - want).abs() < 1e-5, "{} vs {want}", probs[0]);
        assert!((probs[0] - 0.5).abs() < 0.01, "{}", probs[0]);
    }

    /// Picks follow the probabilities (binomial bounds at 5 standard deviations), report
    /// them, and the rescaled sample is uniform within each pick.
    #[test]
    fn select_picks_by_the_probabilities_and_rescales_the_sample() {
        let (emitters, geometries) = scene();
        let sel = EmitterSelection::new(&emitters, &geometries, false);
        let p = Vec3A::new(0.5, 0.5, 1.5);
        let probs = sel.probabilities(p);
        let n = 200_000;
        let mut count = [0usize; 5];
        let mut below_half = [0usize; 5];
        for k in 0..n {
            let u = Vec2::new((k as f32 + 0.5) / n as f32, 0.25);
            let (i, v, pi) = sel.select(p, u).unwrap();
            assert_eq!(pi, probs[i]);
            assert!((0.0..1.0).contains(&v.x) && v.y == 0.25);
            count[i] += 1;
            below_half[i] += usize::from(v.x < 0.5);
        }
        for i in 0..5 {
            let expect = probs[i] as f64 * n as f64;
            let sd = (expect * (1.0 - probs[i] as f64)).sqrt();
            assert!(
                (count[i] as f64 - expect).abs() < 5.0 * sd + 2.0,
                "{i}: {} vs {expect}",
                count[i]
            );
            let half = count[i] as f64 / 2.0;
            assert!(
                (below_half[i] as f64 - half).abs() < 2.0,
                "{i}: rescaled sample not uniform"
            );
        }
    }

    #[test]
    fn one_emitter_or_many_are_chosen_uniformly() {
        let (emitters, geometries) = scene();
        let one = EmitterSelection::new(&emitters[..1], &geometries, false);
        assert_eq!(
            one.select(Vec3A::ZERO, Vec2::new(0.3, 0.7)),
            Some((0, Vec2::new(0.3, 0.7), 1.0))
        );
        let many: Vec<Emitter> = emitters
            .iter()
            .cycle()
            .take(WEIGHED_MAX + 1)
            .cloned()
            .collect();
        let sel = EmitterSelection::new(&many, &geometries, false);
        let (i, v, p) = sel.select(Vec3A::ZERO, Vec2::new(0.5, 0.1)).unwrap();
        assert_eq!((i, p), (4, 1.0 / 9.0));
        assert!((v.x - 0.5).abs() < 1e-5);
        assert_eq!(sel.pdf(Vec3A::ONE, 7), 1.0 / 9.0);
    }

    /// Left to BSDF and phase sampling, a `constant` sky is never picked and its pdf is
    /// 0 (its hits then weigh 1 under MIS); the others share the whole choice, weighed
    /// (up to WEIGHED_MAX candidates) or uniform. A sky alone leaves nothing to pick.
    #[test]
    fn a_constant_sky_left_to_bsdf_sampling_is_never_picked() {
        let (emitters, geometries) = scene();
        let p = Vec3A::new(0.5, 0.5, 1.5);
        let sel = EmitterSelection::new(&emitters, &geometries, true);
        assert_eq!(sel.pdf(p, 4), 0.0);
        let total: f32 = (0..4).map(|i| sel.pdf(p, i)).sum();
        assert!((total - 1.0).abs() < 1e-5, "sum {total}");
        assert!((0..4).all(|i| sel.pdf(p, i) >= DEFENSIVE / 4.0 - 1e-7));
        for k in 0..10_000 {
            let u = Vec2::new((k as f32 + 0.5) / 10_000.0, 0.5);
            let (i, _, pi) = sel.select(p, u).unwrap();
            assert_ne!(i, 4);
            assert_eq!(pi, sel.pdf(p, i));
        }
        // A directional light and the sky: the light, with probability 1.
        let two = [emitters[3].clone(), emitters[4].clone()];
        let sel = EmitterSelection::new(&two, &geometries, true);
        let u = Vec2::new(0.7, 0.2);
        assert_eq!(sel.select(p, u), Some((0, u, 1.0)));
        assert_eq!(sel.pdf(p, 1), 0.0);
        // Many emitters (uniform choice): the two skies are skipped, 9 others remain.
        let many: Vec<Emitter> = emitters.iter().cycle().take(11).cloned().collect();
        let sel = EmitterSelection::new(&many, &geometries, true);
        assert_eq!((sel.pdf(p, 4), sel.pdf(p, 9)), (0.0, 0.0));
        assert_eq!(sel.pdf(p, 10), 1.0 / 9.0);
        for k in 0..900 {
            let (i, v, pi) = sel
                .select(p, Vec2::new((k as f32 + 0.5) / 900.0, 0.1))
                .unwrap();
            assert!(i != 4 && i != 9 && pi == 1.0 / 9.0 && (0.0..1.0).contains(&v.x));
        }
        // The sky alone: nothing to pick; without the flag it is picked like any other.
        let sky = EmitterSelection::new(&emitters[4..], &geometries, true);
        assert_eq!(sky.select(p, u), None);
        assert_eq!(sky.pdf(p, 0), 0.0);
        let sky = EmitterSelection::new(&emitters[4..], &geometries, false);
        assert_eq!(sky.select(p, u), Some((0, u, 1.0)));
    }
}
