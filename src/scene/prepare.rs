//! Preparing a scene for rendering: from its plain parts (shapes, BSDFs, emitters,
//! media, the shot, the integrator) to what the integrators query: the BVH, the
//! clearance grid, the emitter selection, and per medium the convex shape it fills and
//! whether emitters can be reached from it. Independent of any file format, so a test
//! can build a scene by hand.

use glam::Vec3A;

use super::shot::Shot;
use super::ties::Ties;
use super::{IntegratorKind, IntegratorSettings, Scene, ShapeInfo};
use crate::bsdf::Bsdf;
use crate::emitter::selection::EmitterSelection;
use crate::emitter::{BSphere, Emitter};
use crate::geometry::accel::{Accel, ShadowPass};
use crate::geometry::clearance::Clearance;
use crate::geometry::convex::ConvexBoundary;
use crate::geometry::cuboid::Cuboid;
use crate::geometry::shape::Geometry;
use crate::geometry::Bounds;
use crate::geometry::RAY_EPSILON;
use crate::medium::Medium;

/// What a scene is made of, as plain objects: what `load` translates a file into, or
/// what a test builds by hand. Indices tie them together: a [`ShapeInfo`] names its
/// BSDF, emitter and media by their index in `bsdfs`, `emitters` and `media`, and
/// `geometries[i]` is shape `i`'s geometry.
pub struct SceneParts {
    pub geometries: Vec<Geometry>,
    pub shapes: Vec<ShapeInfo>,
    pub bsdfs: Vec<Bsdf>,
    pub emitters: Vec<Emitter>,
    /// The environment emitter (a `constant`), seen by rays that miss.
    pub environment: Option<u32>,
    pub media: Vec<Medium>,
    /// The medium the sensor sits in.
    pub camera_medium: Option<u32>,
    pub shot: Shot,
    pub integrator: IntegratorSettings,
    /// What the loader accepted but the user should hear about.
    pub warnings: Vec<String>,
}

impl Scene {
    /// Prepares `parts` for rendering (Mitsuba's scene constructor: the acceleration
    /// structure, and what mediareg precomputes besides).
    pub fn new(parts: SceneParts) -> Scene {
        let SceneParts {
            geometries,
            shapes,
            bsdfs,
            emitters,
            environment,
            media,
            camera_medium,
            shot,
            integrator,
            mut warnings,
        } = parts;
        let shadow_pass: Vec<ShadowPass> = shapes
            .iter()
            .map(|info| bsdfs[info.bsdf as usize].shadow_pass())
            .collect();
        // Where every surface blocks shadow rays and none bounds a medium, nothing asks
        // the accelerator for the searches that pass over some shapes (crossings, or
        // the ties of a medium's boundary): Embree is then built without filters.
        let shadow_rays_blocked = shadow_pass.iter().all(|p| *p == ShadowPass::Blocks);
        let boundaries = shapes
            .iter()
            .any(|s| s.interior.is_some() || s.exterior.is_some());
        let refs: Vec<&Geometry> = geometries.iter().collect();
        let mut accel = Accel::build(&refs, !shadow_rays_blocked || boundaries);
        warnings.extend(accel.warning.take());
        // The clearance saves ray casts; where a cast is a few analytic tests (no BVH), the
        // two grid lookups a scattering cost more than the cast, and the shadow roulette's
        // variance is not paid back: the furnace sphere lost 20% of its efficiency with it,
        // and the medium cube (a box and two rectangles) about 20%.
        let clearance = if media.is_empty()
            || integrator.kind != IntegratorKind::Volpath
            || !accel.traverses_bvh()
        {
            Clearance::none()
        } else {
            // Media lie inside the shapes that have an interior medium, unless a medium is
            // outside some shape or around the camera: then it may fill the whole scene.
            let unbounded = camera_medium.is_some() || shapes.iter().any(|s| s.exterior.is_some());
            let region = if unbounded {
                accel.bounds
            } else {
                shapes
                    .iter()
                    .zip(&geometries)
                    .filter(|(s, _)| s.interior.is_some())
                    .fold(Bounds::EMPTY, |r, (_, g)| r.union(&g.bounds()))
            };
            Clearance::build(&geometries, region, accel.bounds)
        };
        // Mitsuba's bounding sphere of the scene's bounding box, padded by RayEpsilon.
        let bsphere = if accel.bounds.is_empty() {
            BSphere {
                center: Vec3A::ZERO,
                radius: RAY_EPSILON,
            }
        } else {
            let c = (accel.bounds.min + accel.bounds.max) * 0.5;
            let r = (accel.bounds.max - c).length() * (1.0 + RAY_EPSILON);
            BSphere {
                center: c,
                radius: r.max(RAY_EPSILON),
            }
        };
        let offset_scale = if accel.bounds.is_empty() {
            1.0
        } else {
            let half = (accel.bounds.max - accel.bounds.min).max_element() * 0.5;
            if half.is_finite() && half > 0.0 {
                half
            } else {
                1.0
            }
        };
        // volpath and path leave a uniform sky to BSDF and phase sampling; direct keeps it (its
        // emitter samples may be all it takes). See EmitterSelection::new.
        let emitter_selection = EmitterSelection::new(
            &emitters,
            &geometries,
            matches!(
                integrator.kind,
                IntegratorKind::Volpath | IntegratorKind::Path
            ),
        );
        let area_emitter_bounds =
            area_emitters_within_media(&emitters, &geometries, &shapes, media.len());
        let emitters_unreachable =
            media_sealed_from_emitters(&emitters, &geometries, &shapes, &shadow_pass, media.len());
        let tied_boundaries =
            super::ties::tied_boundaries(&geometries, &shapes, &bsdfs, &accel, offset_scale);
        // A medium whose boundary has a surface in it is no convex medium: rays in it
        // must see that surface.
        let convex_media = (0..media.len() as u32)
            .map(|mi| {
                let tied = |s: usize| tied_boundaries.get(s).is_some_and(|t| *t != Ties::None);
                if (0..shapes.len()).any(|s| tied(s) && shapes[s].interior == Some(mi)) {
                    return None;
                }
                convex_medium(mi, camera_medium, &geometries, &shapes, &accel)
            })
            .collect();
        Scene {
            tied_boundaries,
            convex_media,
            emitters_unreachable,
            shadow_pass,
            shadow_rays_blocked,
            emitter_selection,
            area_emitter_bounds,
            geometries,
            shapes,
            bsdfs,
            emitters,
            environment,
            media,
            accel,
            clearance,
            bsphere,
            offset_scale,
            warnings,
            camera_medium,
            shot,
            integrator,
            ray_log: None,
        }
    }
}

/// The box of the shapes medium `mi` fills, or `None` where it is unbounded (outside
/// some shape, or inside none, as a camera's medium may be).
fn medium_region(mi: u32, geometries: &[Geometry], shapes: &[ShapeInfo]) -> Option<Bounds> {
    if shapes.iter().any(|s| s.exterior == Some(mi)) {
        return None;
    }
    let mut filled = shapes
        .iter()
        .zip(geometries)
        .filter(|(s, _)| s.interior == Some(mi))
        .peekable();
    filled.peek()?;
    Some(filled.fold(Bounds::EMPTY, |r, (_, g)| r.union(&g.bounds())))
}

/// The closed convex shape medium `mi` fills, where rays in it need test only that
/// shape (see `geometry::convex`): it fills exactly one shape, a sphere or a cube; it
/// is the exterior of none and not the camera's (so every ray in it starts inside the
/// shape); and no other shape's box meets that shape's box (so no other surface lies
/// inside it).
fn convex_medium(
    mi: u32,
    camera_medium: Option<u32>,
    geometries: &[Geometry],
    shapes: &[ShapeInfo],
    accel: &Accel,
) -> Option<ConvexBoundary> {
    if camera_medium == Some(mi) || shapes.iter().any(|s| s.exterior == Some(mi)) {
        return None;
    }
    let mut filled = (0..shapes.len()).filter(|&i| shapes[i].interior == Some(mi));
    let si = filled.next()?;
    if filled.next().is_some() {
        return None;
    }
    let own = geometries[si].bounds();
    let alone = geometries
        .iter()
        .enumerate()
        .all(|(i, g)| i == si || !g.bounds().overlaps(&own));
    if !alone {
        return None;
    }
    match &geometries[si] {
        Geometry::Sphere(_) => Some(ConvexBoundary::Sphere(si as u32)),
        // The accelerator's box when it tests the cube as one (its hits name the
        // triangles of its copy), else one of its own.
        Geometry::Mesh(m) => match accel.cuboid(si as u32) {
            Some(c) => Some(ConvexBoundary::Box {
                cuboid: Box::new(c.clone()),
                leaf_valid: true,
            }),
            None => Some(ConvexBoundary::Box {
                cuboid: Box::new(Cuboid::new(si as u32, m, m.cube_to_world.as_ref()?)?),
                leaf_valid: false,
            }),
        },
        Geometry::Planar(_) => None,
    }
}

/// Per medium: whether no emitter sample from a point inside it can arrive, so that
/// its vertices need not sample emitters. That holds for a medium that fills the
/// interior of closed shapes (spheres, Mitsuba cubes) whose surfaces all block shadow
/// rays (a glass ball of juice: Mitsuba's shadow rays stop at any non-null surface), is
/// the exterior of none, and holds no emitter (no area emitter's box meets its box, no
/// point or spot light lies in it; the other emitters lie at infinity). Every such
/// sample is 0, and no emitter can be hit from such a vertex without first meeting its
/// boundary, whose BSDF then sets the MIS weights: skipping them changes no estimate.
fn media_sealed_from_emitters(
    emitters: &[Emitter],
    geometries: &[Geometry],
    shapes: &[ShapeInfo],
    shadow_pass: &[ShadowPass],
    n_media: usize,
) -> Vec<bool> {
    let closed = |g: &Geometry| match g {
        Geometry::Sphere(_) => true,
        Geometry::Mesh(m) => m.cube_to_world.is_some(),
        Geometry::Planar(_) => false,
    };
    (0..n_media as u32)
        .map(|mi| {
            let Some(region) = medium_region(mi, geometries, shapes) else {
                return false;
            };
            let sealed = shapes
                .iter()
                .zip(geometries)
                .zip(shadow_pass)
                .filter(|((s, _), _)| s.interior == Some(mi))
                .all(|((_, g), pass)| closed(g) && *pass == ShadowPass::Blocks);
            let inside = |p: Vec3A| region.overlaps(&Bounds { min: p, max: p });
            sealed
                && emitters.iter().all(|e| match e {
                    Emitter::Area { shape, .. } => {
                        !geometries[*shape as usize].bounds().overlaps(&region)
                    }
                    Emitter::Point { position, .. } => !inside(*position),
                    Emitter::Spot(spot) => !inside(spot.position),
                    Emitter::Directional { .. } | Emitter::Constant { .. } | Emitter::EnvMap(_) => {
                        true
                    }
                })
        })
        .collect()
}

/// Per medium, a bounding sphere (centre, radius²) of each area emitter a ray in it may
/// reach without leaving it: every one where the medium is unbounded (outside some
/// shape, or bounded by none, as a camera's medium may be), else those whose box meets
/// the box of the shapes it fills.
fn area_emitters_within_media(
    emitters: &[Emitter],
    geometries: &[Geometry],
    shapes: &[ShapeInfo],
    n_media: usize,
) -> Vec<Vec<(Vec3A, f32)>> {
    let area: Vec<Bounds> = emitters
        .iter()
        .filter_map(|e| match e {
            Emitter::Area { shape, .. } => Some(geometries[*shape as usize].bounds()),
            _ => None,
        })
        .collect();
    (0..n_media as u32)
        .map(|mi| {
            let region = medium_region(mi, geometries, shapes);
            area.iter()
                .filter(|e| region.is_none_or(|r| e.overlaps(&r)))
                .map(|e| {
                    let (centre, r) = e.bounding_sphere();
                    let r = r * (1.0 + 1e-4);
                    (centre, r * r)
                })
                .collect()
        })
        .collect()
}
