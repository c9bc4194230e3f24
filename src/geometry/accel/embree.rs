//! The accelerator's triangles in Embree 3 (the ray caster Mitsuba 3 uses), when the
//! library loads ([`super::embree_api`]): its closest hit, occlusion test and every-hit
//! search answer for [`super::Accel`] where its BVH would hold triangles only (its
//! `Caster::Embree`). Analytic shapes and Mitsuba `cube`s tested as boxes stay beside
//! it, as with obvhs.
//!
//! One Embree triangle geometry per mesh, built as Mitsuba 3 builds its scene
//! (`RTC_BUILD_QUALITY_HIGH`, no robust flag) up to a million triangles; above, at
//! `RTC_BUILD_QUALITY_MEDIUM` ([`build_quality`]). A committed `RTCScene` may be queried
//! from any number of threads at once (Embree's API documentation, `rtcCommitScene`),
//! so one is shared by the render threads. Searches that must see every hit (the
//! filtered closest hit, the crossings of a shadow ray) hand Embree a filter function
//! in an extended intersect context, as its "Extending the Ray Structure" tutorial does:
//! no allocation per ray.

use std::ptr;
use std::sync::Arc;

use glam::Vec3A;

use super::embree_api::{self as sys, Api, IntersectContext, INVALID_ID};
use super::hit::{Crossing, Crossings, Hit, MAX_CROSSINGS};
use crate::geometry::shape::Geometry;

/// An Embree device and the committed scene of the accelerator's triangles.
pub(crate) struct EmbreeScene {
    api: &'static Api,
    device: sys::Device,
    scene: sys::Scene,
    /// The accelerator's leaf index of each geometry's first triangle (by `geomID`):
    /// a hit's leaf is `first_leaf[geomID] + primID`.
    first_leaf: Vec<u32>,
    /// The shape each geometry is (by `geomID`).
    shape: Vec<u32>,
    /// Whether the scene takes queries with a filter function (`intersect_filtered`,
    /// `each_hit`): only where it was built for them.
    pub(crate) filters: bool,
    /// The meshes' vertex and index arrays, which Embree reads in place (shared
    /// buffers, as Mitsuba 3 hands them over): held here as long as the scene lives, and
    /// never changed while shared.
    _shared: Vec<MeshRef>,
}

// SAFETY: the scene is committed before an `EmbreeScene` is handed out and never
// changed after: Embree allows concurrent queries of a committed scene from any
// thread. The handles are released once, in `Drop`.
unsafe impl Send for EmbreeScene {}
unsafe impl Sync for EmbreeScene {}

/// A mesh for Embree: vertex positions and triangles (indices into them); its
/// triangles are the accelerator's leaves `first_leaf..first_leaf + triangles.len()`.
pub(crate) struct MeshRef {
    pub positions: Arc<Vec<Vec3A>>,
    pub triangles: Arc<Vec<[u32; 3]>>,
    pub first_leaf: u32,
    pub shape: u32,
}

/// A candidate hit as a filter sees it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Candidate {
    /// The triangle's index in the accelerator's copy.
    pub leaf: u32,
    pub shape: u32,
    pub t: f32,
    /// Embree's geometric normal (not normalised): along (p1 − p0) × (p2 − p0), as
    /// the accelerator's (`embree_tests` checks the side against obvhs's).
    pub ng: Vec3A,
}

/// The intersect context Embree hands the filter function, extended (it comes first,
/// so a pointer to it is a pointer to this) with what the filter needs.
#[repr(C)]
struct FilterContext<'a> {
    base: IntersectContext,
    scene: &'a EmbreeScene,
    /// Called with each candidate hit; true accepts it (a closest-hit search keeps it
    /// as the nearest so far; an occlusion search ends), false rejects it.
    visit: &'a mut dyn FnMut(Candidate) -> bool,
}

/// Embree's filter callback: [`FilterContext::visit`] for each valid ray of the
/// packet (Embree's single-ray queries pass one), rejected by clearing its `valid`.
unsafe extern "C" fn filter(args: *const sys::FilterArguments) {
    // SAFETY: Embree passes valid arguments; `context` is the `FilterContext` the query
    // was started with (`base` first, `repr(C)`). RTCRayN and RTCHitN are N-wide SoA
    // structures of 4-byte fields: field k of ray i at word k·N + i (rtcore_ray.h's
    // RTCRayN_* accessors): tfar is the ray's field 8; Ng the hit's fields 0-2, primID
    // and geomID its fields 5 and 6. The hit distance of the candidate is the ray's tfar.
    unsafe {
        let args = &*args;
        let ctx = &mut *(args.context as *mut FilterContext);
        let n = args.n as usize;
        let ray = args.ray as *const f32;
        let hit = args.hit as *const u32;
        let hit_f = args.hit as *const f32;
        for i in 0..n {
            let valid = args.valid.add(i);
            if *valid == 0 {
                continue;
            }
            let t = *ray.add(8 * n + i);
            let prim = *hit.add(5 * n + i);
            let geom = *hit.add(6 * n + i);
            let ng = Vec3A::new(*hit_f.add(i), *hit_f.add(n + i), *hit_f.add(2 * n + i));
            let candidate = Candidate {
                leaf: ctx.scene.first_leaf[geom as usize] + prim,
                shape: ctx.scene.shape[geom as usize],
                t,
                ng,
            };
            if !(ctx.visit)(candidate) {
                *valid = 0;
            }
        }
    }
}

fn ray(o: Vec3A, d: Vec3A, tmax: f32) -> sys::Ray {
    sys::Ray {
        org: o.to_array(),
        tnear: 0.0,
        dir: d.to_array(),
        time: 0.0,
        tfar: tmax,
        mask: u32::MAX,
        id: 0,
        flags: 0,
    }
}

/// From this many triangles on ([`super::bvh_build::LARGE_MESH`]), Embree builds at medium
/// quality.
pub(crate) const MEDIUM_BUILD_FROM: usize = super::bvh_build::LARGE_MESH;

/// The build quality for a scene of `triangles`: high (spatial splits, as Mitsuba 3)
/// where the build is quick, medium for large scanned meshes, where the high build was
/// most of the load and rendered no faster (docs/performance_history.md, "Large
/// scenes").
pub(crate) fn build_quality(triangles: usize) -> std::os::raw::c_int {
    if triangles >= MEDIUM_BUILD_FROM {
        sys::BUILD_QUALITY_MEDIUM
    } else {
        sys::BUILD_QUALITY_HIGH
    }
}

impl EmbreeScene {
    /// The committed scene of `meshes` at build `quality`, or why Embree could not build
    /// it; `filters`: whether it will be asked queries with a filter function.
    pub(crate) fn build(
        api: &'static Api,
        meshes: Vec<MeshRef>,
        filters: bool,
        quality: std::os::raw::c_int,
    ) -> Result<EmbreeScene, String> {
        // SAFETY: plain Embree API calls on handles created here. The shared buffers
        // outlive the scene (`_shared` holds them) and are never written while shared
        // (behind an `Arc`); a vertex's 16-byte stride makes the last one readable by a
        // 16-byte load, as Embree requires of vertex buffers.
        unsafe {
            let device = (api.new_device)(ptr::null());
            if device.is_null() {
                return Err("Embree: rtcNewDevice failed".into());
            }
            let scene = (api.new_scene)(device);
            // The handles are released by Drop from here on, also on an error below.
            let mut s = EmbreeScene {
                api,
                device,
                scene,
                first_leaf: Vec::with_capacity(meshes.len()),
                shape: Vec::with_capacity(meshes.len()),
                filters,
                _shared: Vec::new(),
            };
            if scene.is_null() {
                return Err(s.error("rtcNewScene"));
            }
            (api.set_scene_build_quality)(scene, quality);
            // Filter functions in the intersect context (`filter` above) are called
            // only where the scene allows them; allowed, every query pays for it (4% of
            // a surface scene's render), so only a scene that asks for them has them.
            if filters {
                (api.set_scene_flags)(scene, sys::SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
            }
            for m in &meshes {
                let geometry = (api.new_geometry)(device, sys::GEOMETRY_TYPE_TRIANGLE);
                if geometry.is_null() {
                    return Err(s.error("rtcNewGeometry"));
                }
                (api.set_shared_geometry_buffer)(
                    geometry,
                    sys::BUFFER_TYPE_VERTEX,
                    0,
                    sys::FORMAT_FLOAT3,
                    m.positions.as_ptr().cast(),
                    0,
                    std::mem::size_of::<Vec3A>(),
                    m.positions.len(),
                );
                (api.set_shared_geometry_buffer)(
                    geometry,
                    sys::BUFFER_TYPE_INDEX,
                    0,
                    sys::FORMAT_UINT3,
                    m.triangles.as_ptr().cast(),
                    0,
                    std::mem::size_of::<[u32; 3]>(),
                    m.triangles.len(),
                );
                let code = (api.get_device_error)(device);
                if code != sys::ERROR_NONE {
                    (api.release_geometry)(geometry);
                    return Err(format!(
                        "Embree: rtcSetSharedGeometryBuffer failed (RTCError {code})"
                    ));
                }
                (api.set_geometry_build_quality)(geometry, quality);
                (api.commit_geometry)(geometry);
                let id = (api.attach_geometry)(scene, geometry);
                // The scene holds its own reference.
                (api.release_geometry)(geometry);
                if id as usize != s.first_leaf.len() {
                    return Err(s.error("rtcAttachGeometry"));
                }
                s.first_leaf.push(m.first_leaf);
                s.shape.push(m.shape);
            }
            s._shared = meshes;
            (api.commit_scene)(scene);
            match (api.get_device_error)(device) {
                sys::ERROR_NONE => Ok(s),
                _ => Err(s.error("rtcCommitScene")),
            }
        }
    }

    fn error(&self, call: &str) -> String {
        // SAFETY: a valid device handle.
        let code = unsafe { (self.api.get_device_error)(self.device) };
        format!("Embree: {call} failed (RTCError {code})")
    }

    /// Closest hit along `o + t d`, t ≤ tmax, u and v the barycentrics of vertices 1
    /// and 2 (as the accelerator's own test gives them). Its shape and triangle come
    /// from Embree's geometry and primitive ids (tables of one entry per mesh), not
    /// from the accelerator's per-triangle table: on a large mesh that read missed
    /// the cache on most hits.
    #[inline(always)]
    pub(crate) fn intersect(&self, o: Vec3A, d: Vec3A, tmax: f32) -> Option<Hit> {
        self.intersect_from(o, d, 0.0, tmax)
    }

    /// The closest hit with tnear ≤ t ≤ tmax.
    #[inline(always)]
    pub(crate) fn intersect_from(&self, o: Vec3A, d: Vec3A, tnear: f32, tmax: f32) -> Option<Hit> {
        let mut ctx = IntersectContext::new(None);
        self.intersect_with(&mut ctx, o, d, (tnear, tmax))
    }

    /// The closest hit `keep` accepts.
    pub(crate) fn intersect_filtered(
        &self,
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
        keep: &mut dyn FnMut(Candidate) -> bool,
    ) -> Option<Hit> {
        let mut ctx = FilterContext {
            base: IntersectContext::new(Some(filter)),
            scene: self,
            visit: keep,
        };
        self.intersect_with(&mut ctx.base, o, d, (0.0, tmax))
    }

    #[inline(always)]
    fn intersect_with(
        &self,
        ctx: &mut IntersectContext,
        o: Vec3A,
        d: Vec3A,
        (tnear, tmax): (f32, f32),
    ) -> Option<Hit> {
        let mut rh = sys::RayHit {
            ray: sys::Ray {
                tnear,
                ..ray(o, d, tmax)
            },
            hit: sys::Hit {
                ng: [0.0; 3],
                u: 0.0,
                v: 0.0,
                prim_id: INVALID_ID,
                geom_id: INVALID_ID,
                inst_id: [INVALID_ID],
            },
        };
        // SAFETY: a committed scene; `ctx` is a plain context or the `base` of a
        // FilterContext that outlives the call.
        unsafe { (self.api.intersect1)(self.scene, ctx, &mut rh) };
        let h = rh.hit;
        (h.geom_id != INVALID_ID).then(|| Hit {
            t: rh.ray.tfar,
            shape: self.shape[h.geom_id as usize],
            prim: h.prim_id,
            u: h.u,
            v: h.v,
            leaf: self.first_leaf[h.geom_id as usize] + h.prim_id,
            ng: h.ng,
        })
    }

    /// Whether any triangle meets `o + t d`, t ≤ tmax.
    #[inline(always)]
    pub(crate) fn occluded(&self, o: Vec3A, d: Vec3A, tmax: f32) -> bool {
        let mut ctx = IntersectContext::new(None);
        let mut r = ray(o, d, tmax);
        // SAFETY: a committed scene and a plain context.
        unsafe { (self.api.occluded1)(self.scene, &mut ctx, &mut r) };
        // Embree marks an occluded ray by setting tfar to −∞.
        r.tfar < 0.0
    }

    /// Every hit along `o + t d`, t ≤ tmax, in the order Embree meets them, handed to
    /// `visit` until it answers true; whether it did. A triangle Embree's
    /// spatial splits put in several leaves may be handed over more than once.
    pub(crate) fn each_hit(
        &self,
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
        visit: &mut dyn FnMut(Candidate) -> bool,
    ) -> bool {
        let mut ctx = FilterContext {
            base: IntersectContext::new(Some(filter)),
            scene: self,
            visit,
        };
        let mut r = ray(o, d, tmax);
        // SAFETY: a committed scene; the context outlives the call.
        unsafe { (self.api.occluded1)(self.scene, &mut ctx.base, &mut r) };
        r.tfar < 0.0
    }
}

/// As the scene's ray caster ([`super::Accel`]'s searches, past the shapes beside it).
impl EmbreeScene {
    /// The closest hit, 0 < t < tmax, with a shape `keep` accepts; `filtered` false
    /// says `keep` accepts every shape (Embree is then asked without a filter).
    #[inline(always)]
    pub(crate) fn intersect_where(
        &self,
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
        keep: impl Fn(u32) -> bool,
        filtered: bool,
    ) -> Option<Hit> {
        if !filtered {
            return self.intersect(o, d, tmax);
        }
        if self.filters {
            return self.intersect_filtered(o, d, tmax, &mut |c| keep(c.shape));
        }
        // Built without filters (not expected to be asked): past every hit `keep`
        // refuses, one plain cast after another.
        let mut tnear = 0.0;
        loop {
            match self.intersect_from(o, d, tnear, tmax) {
                Some(h) if !keep(h.shape) && h.t < tmax => tnear = h.t.next_up(),
                Some(h) if keep(h.shape) => break Some(h),
                _ => break None,
            }
        }
    }

    /// Every crossing, 0 < t < tmax, to `record` (see [`super::Accel::crossings`])
    /// until it answers; unsupported where the scene was built without filters (not
    /// expected to be asked: the caller then casts once per crossing).
    #[inline(always)]
    pub(crate) fn crossings(
        &self,
        shapes: &[Geometry],
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
        record: &mut impl FnMut(Crossing) -> Option<Crossings>,
    ) -> Crossings {
        if !self.filters {
            return Crossings::Unsupported;
        }
        // Embree may hand over a triangle twice (see `each_hit`): each counts once.
        let mut seen = arrayvec::ArrayVec::<u32, MAX_CROSSINGS>::new();
        let mut answer = None;
        self.each_hit(o, d, tmax, &mut |c| {
            if seen.contains(&c.leaf) {
                return false;
            }
            // Embree's normal is the triangle's (p1 − p0) × (p2 − p0), as the hit has
            // it: no load of the accelerator's copy (a cache miss).
            let flip = matches!(&shapes[c.shape as usize], Geometry::Mesh(m) if m.flip_normals);
            answer = record(Crossing {
                t: c.t,
                shape: c.shape,
                along_normal: (d.dot(c.ng) > 0.0) != flip,
            });
            // A crossing recorded (and so seen) only where the search goes on.
            if answer.is_none() {
                seen.push(c.leaf);
            }
            answer.is_some()
        });
        answer.unwrap_or(Crossings::Found)
    }
}

impl Drop for EmbreeScene {
    fn drop(&mut self) {
        // SAFETY: the handles were created by `build` and are released once.
        unsafe {
            if !self.scene.is_null() {
                (self.api.release_scene)(self.scene);
            }
            (self.api.release_device)(self.device);
        }
    }
}
