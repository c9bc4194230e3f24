//! The built scene: everything the integrator needs, nothing about XML. Made from
//! plain objects by [`Scene::new`] (`prepare`), whether `load` translated them from a
//! file or a test built them by hand.

pub mod camera;
pub mod cost;
pub mod film;
pub mod medium_names;
pub mod prepare;
pub mod ray_log;
pub mod shot;
pub mod ties;

use glam::{Vec2, Vec3A};

use crate::bsdf::Bsdf;
use crate::emitter::selection::EmitterSelection;
use crate::emitter::{BSphere, Emitter};
use crate::geometry::accel::{Accel, CrossingList, Crossings, Hit, ShadowPass};
use crate::geometry::clearance::Clearance;
use crate::geometry::convex::ConvexBoundary;
use crate::geometry::shape::Geometry;
use crate::geometry::{offset_point, Frame};
use crate::medium::Medium;
use ray_log::RayLog;
use shot::Shot;

pub use medium_names::{MediumChoiceError, MediumSlot};
pub use prepare::SceneParts;

/// Which integrator the file asks for, with its settings.
#[derive(Clone, Debug, PartialEq)]
pub enum IntegratorKind {
    Path,
    Volpath,
    /// Mitsuba's `direct`: samples per camera ray of each strategy.
    Direct {
        emitter_samples: u32,
        bsdf_samples: u32,
    },
}

#[derive(Clone, Debug)]
pub struct IntegratorSettings {
    pub kind: IntegratorKind,
    /// `u32::MAX` for Mitsuba's −1 (unbounded).
    pub max_depth: u32,
    pub rr_depth: u32,
    pub hide_emitters: bool,
    /// The file asked for Mitsuba's `moment` around this integrator: its image is this
    /// one's, and the second-moment AOVs Mitsuba would add are not written.
    pub moment_aovs_dropped: bool,
}

/// What a shape is made of and what it emits, besides its geometry.
#[derive(Clone, Debug)]
pub struct ShapeInfo {
    pub bsdf: u32,
    pub emitter: Option<u32>,
    pub interior: Option<u32>,
    pub exterior: Option<u32>,
    /// Its XML id, by which `mi.traverse` keys its media (`<id>.interior_medium`).
    pub id: Option<String>,
    /// Where the file declares it, for messages (`shape "cube" at scene.xml:12:5`).
    pub origin: String,
    /// The shading frame follows ∂p/∂u (Mitsuba's `initialize_sh_frame`): needed by an
    /// anisotropic BSDF; any other frame around the normal serves the rest.
    pub tangent_frame: bool,
}

/// The built scene: immutable once built; a render takes it with a [`Shot`].
pub struct Scene {
    pub geometries: Vec<Geometry>,
    pub shapes: Vec<ShapeInfo>,
    pub bsdfs: Vec<Bsdf>,
    pub emitters: Vec<Emitter>,
    /// Which emitter a vertex samples (`emitter::selection`).
    pub emitter_selection: EmitterSelection,
    /// Per medium, a bounding sphere (centre, radius²) of each area emitter a ray in
    /// that medium may reach before it leaves it.
    pub area_emitter_bounds: Vec<Vec<(Vec3A, f32)>>,
    /// Per medium: no emitter sample from inside it can arrive (it is sealed in closed
    /// shapes that block shadow rays, with no emitter inside), so its vertices skip them.
    pub emitters_unreachable: Vec<bool>,
    /// The environment emitter (a `constant`), seen by rays that miss.
    pub environment: Option<u32>,
    pub media: Vec<Medium>,
    pub accel: Accel,
    /// How each shape treats shadow rays (by its BSDF), for [`Accel::crossings`].
    pub shadow_pass: Vec<ShadowPass>,
    /// Every shape blocks shadow rays: a crossings search is an occlusion test.
    pub shadow_rays_blocked: bool,
    /// Lower bounds on the distance to the nearest surface (built for scenes with
    /// media, where free flights and shadow rays use them; none otherwise).
    pub clearance: Clearance,
    /// Per medium: the closed convex shape it fills with nothing else inside, if it
    /// is one (see `geometry::convex`).
    pub convex_media: Vec<Option<ConvexBoundary>>,
    /// Per shape: where it is a null medium boundary with a surface coincident with
    /// it, whose hits there give way to that surface (see `ties`); empty when none is.
    pub tied_boundaries: Vec<ties::Ties>,
    pub bsphere: BSphere,
    /// The scene's size: the largest half-extent of its bounding box (1 when empty).
    /// Spawned rays are offset relative to it (see [`crate::geometry::offset_point`]).
    pub offset_scale: f32,
    /// What the loader accepted but the user should hear about (printed before rendering).
    pub warnings: Vec<String>,
    /// The medium the sensor sits in (`<ref name="medium">` inside the sensor). The
    /// prepared data (clearance, convex media) depends on it, so it belongs to the
    /// scene; a shot moves the camera within it.
    pub camera_medium: Option<u32>,
    /// The shot the file describes: its sensor, film and sampler (with the command
    /// line's spp, seed and crop). Renders take a shot, this one or a changed copy.
    pub shot: Shot,
    pub integrator: IntegratorSettings,
    /// Where the casts into the scene are recorded, when asked for (`mediareg render
    /// --ray-log`, in a build with the `ray-log` feature; see `scene::ray_log`); None
    /// otherwise.
    pub ray_log: Option<RayLog>,
}

/// A ray's hit, with the local geometry the integrator needs.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceInteraction {
    pub t: f32,
    pub p: Vec3A,
    /// Geometric normal (after flip_normals).
    pub n: Vec3A,
    /// Shading frame (around the interpolated normal).
    pub sh_frame: Frame,
    /// Texture coordinates (meshes and rectangles; 0 on other shapes).
    pub uv: Vec2,
    pub shape: u32,
}

impl SurfaceInteraction {
    /// Where a ray leaving along `d` starts: off the surface to `d`'s side by the spawn
    /// offset of a scene whose size is `offset_scale` (Mitsuba's `offset_p`,
    /// [`crate::geometry::offset_point`]).
    #[inline]
    pub fn offset_p(&self, d: Vec3A, offset_scale: f32) -> Vec3A {
        offset_point(self.p.into(), self.n.into(), d.into(), offset_scale).into()
    }
}

impl Scene {
    // One out-of-line copy with the BVH's traversal inlined into it (Accel::intersect
    // is forced inline). Left to the compiler, which split depended on how the crate
    // fell into codegen units: adding unrelated code inlined this into its callers
    // and moved the traversal out, 1-4% slower (camera_in_medium, cube, Lucy).
    #[inline(never)]
    pub fn intersect(&self, o: Vec3A, d: Vec3A, tmax: f32) -> Option<SurfaceInteraction> {
        self.log_cast(ray_log::Cast::ClosestHit, o, d, tmax);
        let hit = self.accel.intersect(&self.geometries, o, d, tmax)?;
        let si = self.interaction(o, d, &hit);
        if !self.tied_boundaries.is_empty() && self.tied_boundaries[hit.shape as usize].at(hit.prim)
        {
            return Some(self.surface_in_boundary(o, d, si));
        }
        Some(si)
    }

    /// [`Scene::intersect`] for a ray that starts in `medium`: where the medium fills
    /// a convex shape with nothing else inside, only that shape is tested.
    #[inline]
    pub fn intersect_in_medium(
        &self,
        medium: u32,
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
    ) -> Option<SurfaceInteraction> {
        match &self.convex_media[medium as usize] {
            Some(b) => {
                let hit = b.exit(&self.geometries, o, d, tmax)?;
                Some(self.interaction(o, d, &hit))
            }
            None => self.intersect(o, d, tmax),
        }
    }

    #[inline]
    pub fn occluded(&self, o: Vec3A, d: Vec3A, tmax: f32) -> bool {
        self.log_cast(ray_log::Cast::Occluded, o, d, tmax);
        self.accel.occluded(&self.geometries, o, d, tmax)
    }

    /// Records a cast in the ray log, when there is one; nothing at all in a build
    /// without the `ray-log` feature.
    #[inline(always)]
    fn log_cast(&self, kind: ray_log::Cast, o: Vec3A, d: Vec3A, tmax: f32) {
        #[cfg(feature = "ray-log")]
        if let Some(log) = &self.ray_log {
            log.record(kind, o, d, tmax);
        }
        #[cfg(not(feature = "ray-log"))]
        let _ = (kind, o, d, tmax);
    }

    /// Every surface a shadow ray crosses before `tmax` ([`Accel::crossings`], with how
    /// each shape treats shadow rays).
    #[inline]
    pub fn crossings(&self, o: Vec3A, d: Vec3A, tmax: f32, out: &mut CrossingList) -> Crossings {
        self.log_cast(ray_log::Cast::Crossings, o, d, tmax);
        if self.shadow_rays_blocked {
            // Whatever is hit blocks: the first hit answers (a plain occlusion test).
            out.clear();
            return if self.accel.occluded(&self.geometries, o, d, tmax) {
                Crossings::Blocked
            } else {
                Crossings::Found
            };
        }
        self.accel
            .crossings(&self.geometries, &self.shadow_pass, o, d, tmax, out)
    }

    /// Whether the ray o + t d (unit d, t > 0) in `medium` may meet an area emitter
    /// before it leaves the medium: it passes through the bounding sphere of one within
    /// the medium's reach.
    #[inline]
    pub fn may_see_area_emitter(&self, medium: u32, o: Vec3A, d: Vec3A) -> bool {
        self.area_emitter_bounds[medium as usize]
            .iter()
            .any(|&(c, r2)| {
                let oc = c - o;
                let along = oc.dot(d);
                let dist2 = oc.length_squared();
                // Inside the sphere, or ahead of o with the line within r of c.
                dist2 <= r2 || (along > 0.0 && dist2 - along * along <= r2)
            })
    }

    /// The local geometry at `hit`, a hit of the ray (o, d).
    pub fn interaction(&self, o: Vec3A, d: Vec3A, hit: &Hit) -> SurfaceInteraction {
        let info = &self.shapes[hit.shape as usize];
        let (p, n, sh_n, uv) = match &self.geometries[hit.shape as usize] {
            // A null boundary that emits nothing: the integrators read its point and
            // geometric normal only (which side is crossed), so the mesh's own arrays
            // (indices, positions, normals, uvs: cache misses on a large mesh) are not
            // read.
            Geometry::Mesh(m)
                if hit.leaf != u32::MAX
                    && info.emitter.is_none()
                    && matches!(self.bsdfs[info.bsdf as usize], Bsdf::Null) =>
            {
                let (p, n) = self.accel.triangle_surface(&self.geometries, o, d, hit);
                let n = if m.flip_normals { -n } else { n };
                (p, n, n, Vec2::ZERO)
            }
            Geometry::Mesh(m) => {
                let (p, n, sh_n) = m.surface(hit.prim, hit.u, hit.v);
                (p, n, sh_n, m.uv(hit.prim, hit.u, hit.v))
            }
            Geometry::Sphere(s) => {
                // Project onto the sphere to remove the error of o + t d.
                let radial = (o + d * hit.t - s.center).normalize_or_zero();
                let p = s.center + radial * s.radius;
                let n = if s.flip_normals { -radial } else { radial };
                (p, n, n, Vec2::ZERO)
            }
            Geometry::Planar(pl) => {
                let p = o + d * hit.t;
                // Mitsuba's rectangle: uv = (local + 1) / 2 over [-1, 1]².
                let uv = if pl.is_disk {
                    Vec2::ZERO
                } else {
                    let l = pl.to_local.transform_point3a(p);
                    Vec2::new(0.5 * l.x + 0.5, 0.5 * l.y + 0.5)
                };
                (p, pl.normal, pl.normal, uv)
            }
        };
        let sh_frame = if info.tangent_frame {
            let dp_du = match &self.geometries[hit.shape as usize] {
                Geometry::Mesh(m) => m.dp_du(hit.prim, n),
                // Mitsuba's rectangle: ∂p/∂u = to_world · (2, 0, 0); its disk: the radial
                // direction to_world · (cos φ, sin φ, 0) (zero at the centre).
                Geometry::Planar(pl) if pl.is_disk => {
                    let l = pl.to_local.transform_point3a(p);
                    pl.to_world.transform_vector3a(Vec3A::new(l.x, l.y, 0.0))
                }
                Geometry::Planar(pl) => pl.to_world.transform_vector3a(Vec3A::X),
                Geometry::Sphere(s) => s.dp_du(p),
            };
            Frame::with_tangent(sh_n, dp_du)
        } else {
            Frame::new(sh_n)
        };
        SurfaceInteraction {
            t: hit.t,
            p,
            n,
            sh_frame,
            uv,
            shape: hit.shape,
        }
    }
}
