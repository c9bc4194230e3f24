//! The scene's ray caster, one per scene, chosen once when it is built ([`Caster`], as
//! Mitsuba 3 builds its scene for one backend): each shape tested in turn
//! ([`brute_force`]) where there are few primitives; a few dozen triangles all at once
//! in SIMD lanes ([`lanes`]); Embree 3 where it is installed and there are many
//! triangles ([`embree`], [`Backend`]); else obvhs's compressed wide BVH ([`bvh`]). Few
//! analytic shapes, and few Mitsuba `cube`s as boxes ([`Cuboid`]), are tested beside
//! the caster by every one of them, here; a query then asks the caster, with one match.
//!
//! Files: `build` (which shapes go where, and the choice), `primitive` (what the casters
//! test one at a time), one file per caster, `node` and `triangle` (the BVH's node and
//! leaf tests), `hit` (the answers), `backend` (what `MEDIAREG_ACCEL` asks for).

use glam::Vec3A;

mod backend;
mod brute_force;
mod build;
mod bvh;
mod bvh_build;
mod embree;
pub mod embree_api;
mod hit;
mod lanes;
mod node;
mod primitive;
mod triangle;

pub use backend::{Backend, EMBREE_MIN_TRIANGLES};
pub(super) use hit::cuboid_hit;
pub use hit::{Crossing, CrossingList, Crossings, Hit, ShadowPass, MAX_CROSSINGS};

use super::cuboid::Cuboid;
use super::shape::Geometry;
use super::Bounds;
use primitive::{analytic_crossing, analytic_hits, analytic_intersect, Primitives};

/// What casts the rays against the primitives (the triangles, and the analytic shapes
/// where they are not tested beside it).
enum Caster {
    /// Few primitives ([`brute_force::BRUTE_FORCE_PRIMS`], or none), each tested in turn.
    BruteForce,
    /// A few dozen triangles ([`lanes::MAX_TRIANGLES`]) tested all at once.
    Lanes(lanes::TriangleLanes),
    /// obvhs's BVH (of triangles only unless analytic shapes are many).
    Obvhs(bvh::Bvh),
    /// Embree's BVH of the triangles (where there are many).
    Embree(embree::EmbreeScene),
}

pub struct Accel {
    caster: Caster,
    /// The caster's primitives and the triangles the hit tests read.
    prims: Primitives,
    /// Analytic shapes tested beside the caster (when there are few; see
    /// [`build::SEPARATE_ANALYTIC`]): their shape indices.
    analytic: Vec<u32>,
    /// Mitsuba cubes tested beside the caster as boxes (when, with the analytic shapes,
    /// there are few); their triangles follow the caster's in `prims.triangles`.
    cuboids: Vec<Cuboid>,
    pub bounds: Bounds,
    /// Why the requested backend was not used, when it could not be built (Embree
    /// failed): for the scene's warnings.
    pub warning: Option<String>,
}

impl Accel {
    /// The accelerator over `shapes` with [`Backend::requested`] (obvhs, with a warning,
    /// where that is an error). `filtered`: whether it will be asked the searches that
    /// pass over some shapes ([`Accel::intersect_where`], [`Accel::crossings`]); without,
    /// Embree's scene is built without filter functions, and those searches fall back
    /// to plain casts.
    pub fn build(shapes: &[&Geometry], filtered: bool) -> Accel {
        match Backend::requested() {
            Ok(b) => Self::build_filtered(shapes, b, filtered),
            Err(e) => {
                let mut a = Self::build_filtered(shapes, Backend::Obvhs, filtered);
                a.warning = Some(format!("{e}; rays are cast with obvhs instead"));
                a
            }
        }
    }

    /// The accelerator over `shapes` with `backend`, for every kind of search.
    pub fn build_with(shapes: &[&Geometry], backend: Backend) -> Accel {
        Self::build_filtered(shapes, backend, true)
    }

    /// What casts this scene's rays, for the render's output: "Embree 3.13.5",
    /// "obvhs", or the shapes tested one by one where there is no BVH.
    pub fn describe(&self) -> String {
        match &self.caster {
            Caster::Embree(_) => match embree_api::load() {
                Ok(api) => format!("Embree {}", api.version),
                Err(_) => "Embree".to_string(),
            },
            Caster::Lanes(l) => format!("{} triangles tested in SIMD lanes", l.len()),
            Caster::Obvhs(b) => {
                let below_threshold = !b.mixed
                    && self.prims.len() < EMBREE_MIN_TRIANGLES
                    && Backend::requested() == Ok(Backend::Embree);
                if below_threshold {
                    format!(
                        "obvhs ({} triangles: fewer than the {EMBREE_MIN_TRIANGLES} Embree \
                         pays for)",
                        self.prims.len()
                    )
                } else {
                    "obvhs".to_string()
                }
            }
            Caster::BruteForce => "each shape tested in turn (too few for a BVH)".to_string(),
        }
    }

    /// Which ray caster traverses the triangles.
    pub fn backend(&self) -> Backend {
        match self.caster {
            Caster::Embree(_) => Backend::Embree,
            _ => Backend::Obvhs,
        }
    }

    /// Whether a ray cast traverses a BVH or tests triangles in lanes (else it tests a
    /// few primitives one by one).
    pub fn traverses_bvh(&self) -> bool {
        !matches!(self.caster, Caster::BruteForce)
    }

    /// The cube `shape` as the accelerator tests it, if it is tested as a box.
    pub fn cuboid(&self, shape: u32) -> Option<&Cuboid> {
        self.cuboids.iter().find(|c| c.shape == shape)
    }

    /// Closest hit along `o + t d`, 0 < t < tmax.
    #[inline(always)]
    pub fn intersect(&self, shapes: &[Geometry], o: Vec3A, d: Vec3A, tmax: f32) -> Option<Hit> {
        self.closest(shapes, o, d, tmax, |_| true, false)
    }

    /// Closest hit along `o + t d`, 0 < t < tmax, with a shape `keep` accepts (with
    /// `|_| true`, as [`Accel::intersect`], the test compiles away).
    #[inline(always)]
    pub fn intersect_where(
        &self,
        shapes: &[Geometry],
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
        keep: impl Fn(u32) -> bool,
    ) -> Option<Hit> {
        self.closest(shapes, o, d, tmax, keep, true)
    }

    /// [`Accel::intersect_where`]; `filtered` false says `keep` accepts every shape
    /// (Embree is then asked without a filter callback).
    #[inline(always)]
    fn closest(
        &self,
        shapes: &[Geometry],
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
        keep: impl Fn(u32) -> bool,
        filtered: bool,
    ) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let mut t_best = tmax;
        // The shapes beside the caster first: a hit among them shortens its ray.
        for &shape in self.analytic.iter().filter(|&&s| keep(s)) {
            if let Some(t) = analytic_intersect(shapes, shape, o, d, t_best) {
                t_best = t;
                best = Some(Hit::analytic(shape, t));
            }
        }
        for c in self.cuboids.iter().filter(|c| keep(c.shape)) {
            if let Some(h) = c.intersect(o, d, t_best) {
                t_best = h.t;
                best = Some(cuboid_hit(c, h));
            }
        }
        let prims = &self.prims;
        let found = match &self.caster {
            Caster::BruteForce => brute_force::intersect_where(prims, shapes, o, d, t_best, keep),
            Caster::Lanes(l) => l.intersect_where(prims, o, d, t_best, keep),
            Caster::Obvhs(b) => b.intersect_where(prims, shapes, o, d, t_best, keep),
            Caster::Embree(e) => e.intersect_where(o, d, t_best, keep, filtered),
        };
        found.or(best)
    }

    /// The point of a triangle hit of `o + t d` and its unit geometric normal
    /// (p1 − p0) × (p2 − p0), with no lookups in the mesh (where a surface needs no
    /// shading frame, see `Scene::intersect`). Where the ray caster gave the normal
    /// (Embree), the point is o + t d: reading the triangle for its barycentric point
    /// missed the cache on most hits of a large mesh, and the spawn offset
    /// (`geometry::offset_magnitude`) is far larger than the difference. Else both
    /// come from the copy the hit test has just read.
    #[inline]
    pub fn triangle_surface(
        &self,
        shapes: &[Geometry],
        o: Vec3A,
        d: Vec3A,
        hit: &Hit,
    ) -> (Vec3A, Vec3A) {
        if hit.ng != [0.0; 3] {
            return (o + d * hit.t, Vec3A::from_array(hit.ng).normalize_or_zero());
        }
        let t = self.prims.triangle(shapes, hit.leaf as usize);
        (
            t.p0 + t.e1 * hit.u + t.e2 * hit.v,
            t.e1.cross(t.e2).normalize_or_zero(),
        )
    }

    /// Every surface a shadow ray crosses on `o + t d`, 0 < t < tmax, found in one
    /// traversal instead of one closest-hit cast per crossing (a ray out of a mesh
    /// boundary crosses it about twice on the Bunny, a ray out of a sphere once, and
    /// each cast of the old way ended in a second one to find nothing beyond). `pass[shape]`
    /// says how each shape treats the ray. The crossings go into `out` in the order
    /// found (not sorted), each with the side it crosses to.
    ///
    /// A blocking surface ends the search at once: whatever else lies on the ray,
    /// nothing gets through. A BVH that holds analytic shapes, a thin-dielectric
    /// surface the ray passes through and more than [`MAX_CROSSINGS`] crossings answer
    /// [`Crossings::Unsupported`], and the caller casts one ray per crossing.
    pub fn crossings(
        &self,
        shapes: &[Geometry],
        pass: &[ShadowPass],
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
        out: &mut CrossingList,
    ) -> Crossings {
        out.clear();
        // Records a crossing; Some(answer) when the search is over.
        let mut record = |c: Crossing| match pass[c.shape as usize] {
            ShadowPass::Passes if !out.is_full() => {
                out.push(c);
                None
            }
            ShadowPass::Blocks => Some(Crossings::Blocked),
            _ => Some(Crossings::Unsupported),
        };
        if let Some(answer) = self.crossings_beside(shapes, o, d, tmax, &mut record) {
            return answer;
        }
        let prims = &self.prims;
        match &self.caster {
            Caster::BruteForce => brute_force::crossings(prims, shapes, o, d, tmax, &mut record),
            Caster::Lanes(l) => l.crossings(prims, shapes, o, d, tmax, &mut record),
            Caster::Obvhs(b) => b.crossings(prims, shapes, o, d, tmax, &mut record),
            Caster::Embree(e) => e.crossings(shapes, o, d, tmax, &mut record),
        }
    }

    /// The crossings of the shapes beside the caster, to `record` until it answers.
    #[inline(always)]
    fn crossings_beside(
        &self,
        shapes: &[Geometry],
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
        record: &mut impl FnMut(Crossing) -> Option<Crossings>,
    ) -> Option<Crossings> {
        for &shape in &self.analytic {
            let hits = analytic_hits(shapes, shape, o, d, tmax);
            for t in hits.into_iter().flatten() {
                let c = analytic_crossing(shapes, shape, o, d, t);
                if let Some(answer) = record(c) {
                    return Some(answer);
                }
            }
        }
        for c in &self.cuboids {
            let shape = c.shape;
            if let Some(exit_along) = c.exit_along_normal {
                // Entry first, then exit: the box's side is the whole face's.
                let [entry, exit] = c.span_within(o, d, tmax);
                for (t, along_normal) in [(entry, !exit_along), (exit, exit_along)] {
                    let Some(t) = t else { continue };
                    if let Some(answer) = record(Crossing {
                        t,
                        shape,
                        along_normal,
                    }) {
                        return Some(answer);
                    }
                }
            } else {
                for h in c.hits_within(o, d, tmax).into_iter().flatten() {
                    let leaf = h.leaf as usize;
                    let crossing = self.prims.triangle_crossing(shapes, shape, leaf, h.t, d);
                    if let Some(answer) = record(crossing) {
                        return Some(answer);
                    }
                }
            }
        }
        None
    }

    /// Whether anything blocks `o + t d` for 0 < t < tmax.
    #[inline]
    pub fn occluded(&self, shapes: &[Geometry], o: Vec3A, d: Vec3A, tmax: f32) -> bool {
        if self
            .analytic
            .iter()
            .any(|&shape| analytic_intersect(shapes, shape, o, d, tmax).is_some())
        {
            return true;
        }
        if self.cuboids.iter().any(|c| c.hit_within(o, d, tmax)) {
            return true;
        }
        let prims = &self.prims;
        match &self.caster {
            Caster::BruteForce => brute_force::occluded(prims, shapes, o, d, tmax),
            Caster::Lanes(l) => l.any_hit(o, d, tmax),
            Caster::Obvhs(b) => b.occluded(prims, shapes, o, d, tmax),
            Caster::Embree(e) => e.occluded(o, d, tmax),
        }
    }
}

#[cfg(test)]
mod embree_tests;
#[cfg(test)]
mod tests;
