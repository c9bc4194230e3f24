//! The accelerator's triangles in Embree 3 (the ray caster Mitsuba 3 uses), behind the
//! `embree` cargo feature: its closest hit, occlusion test and every-hit search answer
//! for the BVH of [`super::Accel`] when that holds triangles only. Analytic shapes and
//! Mitsuba `cube`s tested as boxes stay beside it, as with obvhs.
//!
//! One Embree triangle geometry per mesh, built as Mitsuba 3 builds its scene
//! (`RTC_BUILD_QUALITY_HIGH`, no robust flag). A committed `RTCScene` may be queried
//! from any number of threads at once (Embree's API documentation, `rtcCommitScene`),
//! so one is shared by the render threads. Searches that must see every hit (the
//! filtered closest hit, the crossings of a shadow ray) hand Embree a filter function
//! in an extended intersect context, as its "Extending the Ray Structure" tutorial does:
//! no allocation per ray.

use std::ptr;

use embree::sys;
use glam::Vec3A;

use super::Hit;

/// An Embree device and the committed scene of the accelerator's triangles.
pub(crate) struct EmbreeScene {
    device: sys::RTCDevice,
    scene: sys::RTCScene,
    /// The accelerator's leaf index of each geometry's first triangle (by `geomID`):
    /// a hit's leaf is `first_leaf[geomID] + primID`.
    first_leaf: Vec<u32>,
    /// The shape each geometry is (by `geomID`).
    shape: Vec<u32>,
}

// SAFETY: the scene is committed before an `EmbreeScene` is handed out and never
// changed after: Embree allows concurrent queries of a committed scene from any
// thread. The handles are released once, in `Drop`.
unsafe impl Send for EmbreeScene {}
unsafe impl Sync for EmbreeScene {}

/// A mesh for Embree: vertex positions and triangles (indices into them); its
/// triangles are the accelerator's leaves `first_leaf..first_leaf + triangles.len()`.
pub(crate) struct MeshRef<'a> {
    pub positions: &'a [Vec3A],
    pub triangles: &'a [[u32; 3]],
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
    base: sys::RTCIntersectContext,
    scene: &'a EmbreeScene,
    /// Called with each candidate hit; true accepts it (a closest-hit search keeps it
    /// as the nearest so far; an occlusion search ends), false rejects it.
    visit: &'a mut dyn FnMut(Candidate) -> bool,
}

/// Embree's filter callback: [`FilterContext::visit`] for each valid ray of the
/// packet (Embree's single-ray queries pass one), rejected by clearing its `valid`.
unsafe extern "C" fn filter(args: *const sys::RTCFilterFunctionNArguments) {
    // SAFETY: Embree passes valid arguments; `context` is the `FilterContext` the query
    // was started with (`base` first, `repr(C)`). RTCRayN and RTCHitN are N-wide SoA
    // structures of 4-byte fields: field k of ray i at word k·N + i (rtcore_ray.h's
    // RTCRayN_* accessors): tfar is the ray's field 8; Ng the hit's fields 0-2, primID
    // and geomID its fields 5 and 6. The hit distance of the candidate is the ray's tfar.
    unsafe {
        let args = &*args;
        let ctx = &mut *(args.context as *mut FilterContext);
        let n = args.N as usize;
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

fn context() -> sys::RTCIntersectContext {
    // rtcInitIntersectContext (an inline function of rtcore_scene.h).
    sys::RTCIntersectContext {
        flags: sys::RTCIntersectContextFlags::INCOHERENT,
        filter: None,
        instID: [u32::MAX; 1],
    }
}

fn ray(o: Vec3A, d: Vec3A, tmax: f32) -> sys::RTCRay {
    sys::RTCRay {
        org_x: o.x,
        org_y: o.y,
        org_z: o.z,
        tnear: 0.0,
        dir_x: d.x,
        dir_y: d.y,
        dir_z: d.z,
        time: 0.0,
        tfar: tmax,
        mask: u32::MAX,
        id: 0,
        flags: 0,
    }
}

const INVALID_ID: u32 = u32::MAX;

impl EmbreeScene {
    /// The committed scene of `meshes`, or why Embree could not build it.
    pub(crate) fn build(meshes: &[MeshRef]) -> Result<EmbreeScene, String> {
        // SAFETY: plain Embree API calls on handles created here; buffer writes stay
        // within the sizes asked for (Embree pads new buffers for its 16-byte loads).
        unsafe {
            let device = sys::rtcNewDevice(ptr::null());
            if device.is_null() {
                return Err("rtcNewDevice failed (is libembree3 installed?)".into());
            }
            let scene = sys::rtcNewScene(device);
            // The handles are released by Drop from here on, also on an error below.
            let mut s = EmbreeScene {
                device,
                scene,
                first_leaf: Vec::with_capacity(meshes.len()),
                shape: Vec::with_capacity(meshes.len()),
            };
            if scene.is_null() {
                s.scene = ptr::null_mut();
                return Err(s.error("rtcNewScene"));
            }
            sys::rtcSetSceneBuildQuality(scene, sys::RTCBuildQuality::HIGH);
            // Filter functions in the intersect context (`filter` below) are called
            // only where the scene allows them; a query without one pays a null check.
            sys::rtcSetSceneFlags(scene, sys::RTCSceneFlags::CONTEXT_FILTER_FUNCTION);
            for m in meshes {
                let geometry = sys::rtcNewGeometry(device, sys::RTCGeometryType::TRIANGLE);
                if geometry.is_null() {
                    return Err(s.error("rtcNewGeometry"));
                }
                let vertices = sys::rtcSetNewGeometryBuffer(
                    geometry,
                    sys::RTCBufferType::VERTEX,
                    0,
                    sys::RTCFormat::FLOAT3,
                    16,
                    m.positions.len(),
                ) as *mut [f32; 4];
                let indices = sys::rtcSetNewGeometryBuffer(
                    geometry,
                    sys::RTCBufferType::INDEX,
                    0,
                    sys::RTCFormat::UINT3,
                    12,
                    m.triangles.len(),
                ) as *mut [u32; 3];
                if vertices.is_null() || indices.is_null() {
                    sys::rtcReleaseGeometry(geometry);
                    return Err(s.error("rtcSetNewGeometryBuffer"));
                }
                for (i, p) in m.positions.iter().enumerate() {
                    vertices.add(i).write([p.x, p.y, p.z, 0.0]);
                }
                ptr::copy_nonoverlapping(m.triangles.as_ptr(), indices, m.triangles.len());
                sys::rtcSetGeometryBuildQuality(geometry, sys::RTCBuildQuality::HIGH);
                sys::rtcCommitGeometry(geometry);
                let id = sys::rtcAttachGeometry(scene, geometry);
                // The scene holds its own reference.
                sys::rtcReleaseGeometry(geometry);
                if id as usize != s.first_leaf.len() {
                    return Err(s.error("rtcAttachGeometry"));
                }
                s.first_leaf.push(m.first_leaf);
                s.shape.push(m.shape);
            }
            sys::rtcCommitScene(scene);
            match sys::rtcGetDeviceError(device) {
                sys::RTCError::NONE => Ok(s),
                _ => Err(s.error("rtcCommitScene")),
            }
        }
    }

    fn error(&self, call: &str) -> String {
        // SAFETY: a valid device handle.
        let code = unsafe { sys::rtcGetDeviceError(self.device) };
        format!("Embree: {call} failed ({code:?})")
    }

    /// Closest hit along `o + t d`, t ≤ tmax, u and v the barycentrics of vertices 1
    /// and 2 (as the accelerator's own test gives them). Its shape and triangle come
    /// from Embree's geometry and primitive ids (tables of one entry per mesh), not
    /// from the accelerator's per-triangle table: on a large mesh that read missed
    /// the cache on most hits.
    #[inline(always)]
    pub(crate) fn intersect(&self, o: Vec3A, d: Vec3A, tmax: f32) -> Option<Hit> {
        let mut ctx = context();
        self.intersect_with(&mut ctx, o, d, tmax)
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
            base: sys::RTCIntersectContext {
                filter: Some(filter),
                ..context()
            },
            scene: self,
            visit: keep,
        };
        self.intersect_with(&mut ctx.base, o, d, tmax)
    }

    #[inline(always)]
    fn intersect_with(
        &self,
        ctx: &mut sys::RTCIntersectContext,
        o: Vec3A,
        d: Vec3A,
        tmax: f32,
    ) -> Option<Hit> {
        let mut rh = sys::RTCRayHit {
            ray: ray(o, d, tmax),
            hit: sys::RTCHit {
                Ng_x: 0.0,
                Ng_y: 0.0,
                Ng_z: 0.0,
                u: 0.0,
                v: 0.0,
                primID: INVALID_ID,
                geomID: INVALID_ID,
                instID: [INVALID_ID; 1],
            },
        };
        // SAFETY: a committed scene; `ctx` is a plain context or the `base` of a
        // FilterContext that outlives the call.
        unsafe { sys::rtcIntersect1(self.scene, ctx, &mut rh) };
        let h = rh.hit;
        (h.geomID != INVALID_ID).then(|| Hit {
            t: rh.ray.tfar,
            shape: self.shape[h.geomID as usize],
            prim: h.primID,
            u: h.u,
            v: h.v,
            leaf: self.first_leaf[h.geomID as usize] + h.primID,
            ng: [h.Ng_x, h.Ng_y, h.Ng_z],
        })
    }

    /// Whether any triangle meets `o + t d`, t ≤ tmax.
    #[inline(always)]
    pub(crate) fn occluded(&self, o: Vec3A, d: Vec3A, tmax: f32) -> bool {
        let mut ctx = context();
        let mut r = ray(o, d, tmax);
        // SAFETY: a committed scene and a plain context.
        unsafe { sys::rtcOccluded1(self.scene, &mut ctx, &mut r) };
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
            base: sys::RTCIntersectContext {
                filter: Some(filter),
                ..context()
            },
            scene: self,
            visit,
        };
        let mut r = ray(o, d, tmax);
        // SAFETY: a committed scene; the context outlives the call.
        unsafe { sys::rtcOccluded1(self.scene, &mut ctx.base, &mut r) };
        r.tfar < 0.0
    }
}

impl Drop for EmbreeScene {
    fn drop(&mut self) {
        // SAFETY: the handles were created by `build` and are released once.
        unsafe {
            if !self.scene.is_null() {
                sys::rtcReleaseScene(self.scene);
            }
            sys::rtcReleaseDevice(self.device);
        }
    }
}
