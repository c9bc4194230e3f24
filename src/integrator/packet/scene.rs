//! Which scenes the packet kernel takes, and what it keeps of them: media spheres,
//! diffuse surfaces, media, emitters and the integrator's settings.

use glam::{Mat4, Vec3, Vec4};

use crate::bsdf::dielectric::Dielectric;
use crate::bsdf::Bsdf;
use crate::emitter::Emitter;
use crate::geometry::cuboid::Cuboid;
use crate::geometry::shape::{Geometry, Planar};
use crate::medium::Phase;
use crate::scene::ties::Ties;
use crate::scene::{IntegratorKind, Scene};

/// The largest |g| of a Henyey–Greenstein medium the packet takes: its sampling is in
/// f32, which resolves the peak (width ~(1 − |g|)² in 1 − cos θ) well below this.
pub const MAX_ABS_G: f32 = 0.95;

/// How far a diffuse surface's plane may reach into a medium sphere, relative to its
/// radius (a floor the sphere rests on touches it in one point, up to rounding).
const TOUCH_TOLERANCE: f32 = 1e-5;

/// The shape of a `null` boundary filled with a homogeneous medium.
#[derive(Clone, Copy, Debug)]
pub enum MediumKind {
    Sphere {
        center: Vec3,
        radius2: f32,
    },
    /// Mitsuba's `cube`: the rows of the map from the world to its [-1, 1]³.
    Box {
        rows: [Vec4; 3],
    },
}

/// A medium in a sphere or a box, in empty space, behind a `null` boundary or a
/// dielectric one (which seals it: no shadow ray passes).
#[derive(Clone, Copy, Debug)]
pub struct MediumShape {
    pub kind: MediumKind,
    pub medium: u32,
    /// A smooth `dielectric` boundary's BSDF.
    pub dielectric: Option<Dielectric>,
    /// A sphere around it (centre, radius), for the scene's overlap checks.
    bound: (Vec3, f32),
}

/// The shape of a diffuse surface.
#[derive(Clone, Copy, Debug)]
pub enum SurfaceShape {
    Sphere {
        center: Vec3,
        radius2: f32,
    },
    /// A rectangle or disk: the rows of its `to_local` map (the shape in z = 0, within
    /// [-1, 1]² or the unit disk) and its normal (after `flip_normals`).
    Planar {
        rows: [Vec4; 3],
        normal: Vec3,
        disk: bool,
    },
    /// Mitsuba's `cube`: the rows of the map from the world to its [-1, 1]³.
    Box {
        rows: [Vec4; 3],
    },
}

/// An opaque `diffuse` surface (front side only, constant reflectance), and the
/// area emitter on it, if any.
#[derive(Clone, Copy, Debug)]
pub struct Surface {
    pub shape: SurfaceShape,
    pub reflectance: Vec3,
    pub emitter: Option<u32>,
    /// The medium shape it lies in (as f32, the lanes' type; −1: empty space).
    pub container: f32,
    /// A sphere around it (centre, radius), for the scene's overlap checks.
    bound: (Vec3, f32),
}

/// A medium's extinction and phase function (the albedo is the render's).
#[derive(Clone, Copy, Debug)]
pub struct PacketMedium {
    /// (Unused where the scene's medium is heterogeneous: tracked instead.)
    pub sigma_t: Vec3,
    /// Henyey–Greenstein's g (0: isotropic).
    pub g: f32,
    /// Whether the phase function is Henyey–Greenstein's (an isotropic one has no g
    /// to differentiate).
    pub hg: bool,
}

/// The scene's one emitter to sample, where it is one whose sample the packet draws in
/// lanes (`Emitter::sample_direction`'s forms); else the scalar code samples per lane.
#[derive(Clone, Debug)]
pub enum LaneEmitter {
    Scalar,
    Point {
        position: Vec3,
        intensity: Vec3,
    },
    /// Light arriving along `-toward` from the scene's bounding sphere (centre, radius).
    Directional {
        toward: Vec3,
        irradiance: Vec3,
        bsphere: (Vec3, f32),
    },
    /// An area light on a rectangle.
    Rectangle {
        light: Planar,
        radiance: Vec3,
    },
    /// An area light on a sphere seen from outside (or from its surface), sampled by
    /// its visible cone; from inside it, by the scalar code.
    Sphere {
        center: Vec3,
        radius: f32,
        radiance: Vec3,
    },
}

/// What the packet kernel needs of a scene it takes.
#[derive(Clone, Debug)]
pub struct PacketScene {
    pub media_shapes: Vec<MediumShape>,
    pub surfaces: Vec<Surface>,
    pub media: Vec<PacketMedium>,
    /// The sky's radiance (0 where there is none).
    pub environment: Vec3,
    pub has_environment: bool,
    /// Whether a vertex has an emitter to sample (a sky alone is left to BSDF and
    /// phase sampling under volpath: `emitter::selection`).
    pub samples_emitters: bool,
    /// Whether an emitter is an area light: its samples and hits take MIS weights.
    pub area_emitters: bool,
    /// How emitter samples are drawn.
    pub lane_emitter: LaneEmitter,
    pub max_depth: u32,
    pub rr_depth: u32,
    pub hide_emitters: bool,
    /// Every medium's σ_t is the same in all channels: no transmittance is needed.
    pub grey: bool,
    /// The scene's size, for the offset of a ray entering a medium
    /// (`geometry::offset_point`).
    pub offset_scale: f32,
    /// The medium shape the camera is in (the one filled with the sensor's medium).
    pub camera_shape: Option<u32>,
    /// Whether a medium's boundary is a dielectric.
    pub dielectrics: bool,
}

impl PacketScene {
    /// The packet form of `scene`, or why its paths need the scalar integrator. Taken:
    /// `volpath`; shapes that are `null` spheres or cubes each bounding a homogeneous
    /// medium inside empty space (no two within reach of each other; or a heterogeneous
    /// medium, where it is the scene's only one), or rectangles,
    /// disks, spheres and cubes with a constant `diffuse` BSDF, each inside one medium
    /// shape or clear of all; the camera in empty space or in a medium that fills one
    /// shape ([`PacketScene::takes_camera_ray`] checks a shot's camera); isotropic or
    /// Henyey–Greenstein (|g| ≤ [`MAX_ABS_G`]) phase functions; area emitters on those
    /// surfaces, point, spot and directional emitters and a `constant` sky (never
    /// sampled under volpath, so a path that escapes sees it with weight 1).
    pub fn new(scene: &Scene) -> Result<PacketScene, String> {
        if scene.integrator.kind != IntegratorKind::Volpath {
            return Err("the integrator is not volpath".into());
        }
        if scene.ray_log.is_some() {
            return Err("casts are being logged".into());
        }
        if scene
            .tied_boundaries
            .iter()
            .any(|t| !matches!(t, Ties::None))
        {
            // A surface in a medium's boundary (a box resting on a floor): the scalar
            // path breaks the tie for the surface (`scene::ties`); the packet would not.
            return Err("a medium's boundary is coincident with a surface".into());
        }
        let mut media_shapes = Vec::new();
        let mut surfaces = Vec::new();
        for (info, geometry) in scene.shapes.iter().zip(&scene.geometries) {
            let bsdf = &scene.bsdfs[info.bsdf as usize];
            match (bsdf, info.interior, info.exterior) {
                (Bsdf::Null | Bsdf::Dielectric(_), Some(medium), None)
                    if info.emitter.is_none() =>
                {
                    let Some((kind, bound)) = medium_kind(geometry) else {
                        return Err(
                            "a null shape bounding a medium is not a sphere or a cube".into()
                        );
                    };
                    let dielectric = match bsdf {
                        Bsdf::Dielectric(d) => Some(*d),
                        _ => None,
                    };
                    media_shapes.push(MediumShape {
                        kind,
                        medium,
                        dielectric,
                        bound,
                    })
                }
                (Bsdf::Null, _, _) => {
                    return Err("a null shape does not bound a medium inside empty space".into())
                }
                (Bsdf::Diffuse { reflectance }, None, None) => {
                    let Some(reflectance) = reflectance.constant() else {
                        return Err("a diffuse reflectance is textured".into());
                    };
                    surfaces.push(diffuse_surface(geometry, reflectance, info.emitter)?);
                }
                _ => return Err("a shape's BSDF is not null or diffuse".into()),
            }
        }
        place(&media_shapes, &mut surfaces)?;
        let media = packet_media(scene)?;
        let (environment, samples_emitters, area_emitters) = emitters_taken(scene)?;
        let camera_shape = match scene.camera_medium {
            None => None,
            Some(m) => match media_shapes.iter().filter(|s| s.medium == m).count() {
                1 => media_shapes
                    .iter()
                    .position(|s| s.medium == m)
                    .map(|i| i as u32),
                _ => return Err("the camera's medium does not fill one sphere or cube".into()),
            },
        };
        if camera_shape.is_some_and(|i| media_shapes[i as usize].dielectric.is_some()) {
            return Err("the camera is inside a dielectric".into());
        }
        if area_emitters && scene.integrator.hide_emitters {
            // The camera ray would have to pass through the emitters' shapes.
            return Err("area emitters are hidden".into());
        }
        let grey = scene.media.iter().all(|m| m.is_grey());
        Ok(PacketScene {
            surfaces,
            media,
            environment,
            has_environment: scene.environment.is_some(),
            samples_emitters,
            area_emitters,
            lane_emitter: lane_emitter(scene),
            max_depth: scene.integrator.max_depth,
            rr_depth: scene.integrator.rr_depth,
            hide_emitters: scene.integrator.hide_emitters,
            grey,
            offset_scale: scene.offset_scale,
            camera_shape,
            dielectrics: media_shapes.iter().any(|m| m.dielectric.is_some()),
            media_shapes,
        })
    }

    /// Whether a camera ray from `o` that ends at `tmax` (the far clip) starts where the
    /// scene says the camera is: for a camera in a medium, inside the shape the medium
    /// fills, and not clipped before it leaves it (in empty space the scalar path
    /// takes the camera to be there too, wherever it is).
    pub fn takes_camera_ray(&self, o: Vec3, tmax: f32) -> bool {
        let Some(i) = self.camera_shape else {
            return true;
        };
        let shape = &self.media_shapes[i as usize];
        let inside = match shape.kind {
            MediumKind::Sphere { center, radius2 } => o.distance_squared(center) < radius2,
            MediumKind::Box { rows } => rows.iter().all(|r| r.dot(o.extend(1.0)).abs() < 1.0),
        };
        inside && tmax >= 2.0 * shape.bound.1
    }
}

/// The packet form of the one emitter a vertex can pick, if it has one.
fn lane_emitter(scene: &Scene) -> LaneEmitter {
    let Some(i) = scene.emitter_selection.single() else {
        return LaneEmitter::Scalar;
    };
    match &scene.emitters[i] {
        Emitter::Point {
            position,
            intensity,
        } => LaneEmitter::Point {
            position: Vec3::from(*position),
            intensity: *intensity,
        },
        Emitter::Directional {
            direction,
            irradiance,
        } => LaneEmitter::Directional {
            toward: -Vec3::from(*direction),
            irradiance: *irradiance,
            bsphere: (Vec3::from(scene.bsphere.center), scene.bsphere.radius),
        },
        Emitter::Area { shape, radiance } => match &scene.geometries[*shape as usize] {
            Geometry::Planar(p) if !p.is_disk => LaneEmitter::Rectangle {
                light: p.clone(),
                radiance: *radiance,
            },
            Geometry::Sphere(s) if !s.flip_normals => LaneEmitter::Sphere {
                center: Vec3::from(s.center),
                radius: s.radius,
                radiance: *radiance,
            },
            _ => LaneEmitter::Scalar,
        },
        _ => LaneEmitter::Scalar,
    }
}

/// The medium shape of a sphere (not inside out) or of Mitsuba's `cube` (a mesh
/// that is the box of its `to_world`), with a sphere around it.
fn medium_kind(geometry: &Geometry) -> Option<(MediumKind, (Vec3, f32))> {
    match geometry {
        Geometry::Sphere(s) if !s.flip_normals => {
            let center = Vec3::from(s.center);
            let kind = MediumKind::Sphere {
                center,
                radius2: s.radius * s.radius,
            };
            Some((kind, (center, s.radius)))
        }
        Geometry::Mesh(m) => {
            let to_world = m.cube_to_world?;
            // The map to the box's space as the one path's slab test has it.
            let rows = Cuboid::new(0, m, &to_world)?.rows();
            let center = to_world.transform_point3(Vec3::ZERO);
            // The farthest corner from the centre bounds the box.
            let radius = (0..8)
                .map(|c| {
                    let corner = Vec3::new(
                        if c & 1 == 0 { -1.0 } else { 1.0 },
                        if c & 2 == 0 { -1.0 } else { 1.0 },
                        if c & 4 == 0 { -1.0 } else { 1.0 },
                    );
                    to_world.transform_point3(corner).distance(center)
                })
                .fold(0.0f32, f32::max);
            Some((MediumKind::Box { rows }, (center, radius)))
        }
        _ => None,
    }
}

/// Whether the sphere `(c, r)` lies inside the medium shape `m`.
fn contains(m: &MediumShape, (c, r): (Vec3, f32)) -> bool {
    match m.kind {
        MediumKind::Sphere { center, radius2 } => c.distance(center) + r <= radius2.sqrt(),
        // Within the faces on every axis: |x_k| + r |∇x_k| ≤ 1.
        MediumKind::Box { rows } => rows
            .iter()
            .all(|row| row.dot(c.extend(1.0)).abs() + r * row.truncate().length() <= 1.0),
    }
}

/// Whether surface `s` stays out of the medium shape `m`: their bounding spheres apart,
/// or the surface's plane no nearer the medium's centre than its extent along the
/// plane's normal (a floor the shape rests on may touch it, up to rounding).
fn clear_of(m: &MediumShape, s: &Surface) -> bool {
    let (c, r) = m.bound;
    if c.distance(s.bound.0) > r + s.bound.1 {
        return true;
    }
    match s.shape {
        SurfaceShape::Sphere { center, radius2 } => c.distance(center) >= r + radius2.sqrt(),
        // (Its bounding sphere reaches into the medium's: taken as not clear.)
        SurfaceShape::Box { .. } => false,
        SurfaceShape::Planar { rows, .. } => {
            // The plane is z = 0 of the surface's space: a point's distance from it is
            // |z_local| / |∇z_local|.
            let grad = rows[2].truncate().length();
            let dist = |p: Vec3| rows[2].dot(p.extend(1.0)).abs() / grad;
            let normal = rows[2].truncate() / grad;
            let extent = match m.kind {
                MediumKind::Sphere { radius2, .. } => radius2.sqrt(),
                // The box's support along the normal: Σ_k |n · axis_k|, the axes the
                // columns of to_world (the inverse of `rows`).
                MediumKind::Box { rows: b } => {
                    let to_world = Mat4::from_cols(b[0], b[1], b[2], Vec4::W)
                        .transpose()
                        .inverse();
                    (0..3)
                        .map(|k| normal.dot(to_world.col(k).truncate()).abs())
                        .sum()
                }
            };
            dist(c) >= extent * (1.0 - TOUCH_TOLERANCE)
        }
    }
}

/// A `diffuse` surface the packet takes (a sphere, rectangle, disk or cube) with its
/// bounding sphere, not yet placed in a medium.
fn diffuse_surface(
    geometry: &Geometry,
    reflectance: Vec3,
    emitter: Option<u32>,
) -> Result<Surface, String> {
    let (shape, bound) = match geometry {
        Geometry::Sphere(s) if !s.flip_normals => {
            let center = Vec3::from(s.center);
            let shape = SurfaceShape::Sphere {
                center,
                radius2: s.radius * s.radius,
            };
            (shape, (center, s.radius))
        }
        Geometry::Planar(p) => {
            let shape = SurfaceShape::Planar {
                rows: [p.to_local.row(0), p.to_local.row(1), p.to_local.row(2)],
                normal: Vec3::from(p.normal),
                disk: p.is_disk,
            };
            let center = p.to_world.transform_point3(Vec3::ZERO);
            let radius = [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)]
                .into_iter()
                .map(|(x, y)| {
                    p.to_world
                        .transform_point3(Vec3::new(x, y, 0.0))
                        .distance(center)
                })
                .fold(0.0f32, f32::max);
            (shape, (center, radius))
        }
        g => match medium_kind(g) {
            Some((MediumKind::Box { rows }, bound)) => (SurfaceShape::Box { rows }, bound),
            _ => return Err("a diffuse shape is not a rectangle, disk, sphere or cube".into()),
        },
    };
    Ok(Surface {
        shape,
        reflectance,
        emitter,
        container: -1.0,
        bound,
    })
}

/// Checks that no two media shapes are within reach of each other, and puts each
/// surface in the medium shape that contains it (or none, where it is clear of all).
fn place(media_shapes: &[MediumShape], surfaces: &mut [Surface]) -> Result<(), String> {
    for (i, a) in media_shapes.iter().enumerate() {
        let (c, r) = a.bound;
        for b in &media_shapes[..i] {
            if c.distance(b.bound.0) <= r + b.bound.1 {
                return Err("two media shapes are within reach of each other".into());
            }
        }
    }
    for s in surfaces.iter_mut() {
        for (i, m) in media_shapes.iter().enumerate() {
            if contains(m, s.bound) && s.container < 0.0 {
                if m.dielectric.is_some() {
                    return Err("a surface lies inside a dielectric".into());
                }
                s.container = i as f32;
            } else if !clear_of(m, s) {
                return Err("a diffuse surface crosses a medium's boundary".into());
            }
        }
    }
    Ok(())
}

/// The media's values in the packet, or why one is refused.
fn packet_media(scene: &Scene) -> Result<Vec<PacketMedium>, String> {
    let mut media = Vec::new();
    for m in &scene.media {
        if m.heterogeneous.is_some() && scene.media.len() > 1 {
            return Err("a heterogeneous medium is not the scene's only one".into());
        }
        if !m.sample_emitters {
            return Err("a medium does not sample emitters".into());
        }
        let g = match m.phase {
            Phase::Isotropic => 0.0,
            Phase::HenyeyGreenstein { g } if g.abs() <= MAX_ABS_G => g,
            _ => {
                return Err(format!(
                    "a phase function is not isotropic or hg with |g| <= {MAX_ABS_G}"
                ))
            }
        };
        media.push(PacketMedium {
            sigma_t: m.sigma_t,
            g,
            hg: matches!(m.phase, Phase::HenyeyGreenstein { .. }),
        });
    }
    Ok(media)
}

/// The constant sky's radiance, whether emitters are sampled and whether there are area
/// emitters, or why an emitter is refused.
fn emitters_taken(scene: &Scene) -> Result<(Vec3, bool, bool), String> {
    let mut environment = Vec3::ZERO;
    let mut samples_emitters = false;
    let mut area_emitters = false;
    for (i, e) in scene.emitters.iter().enumerate() {
        match e {
            Emitter::Constant { radiance } if scene.environment == Some(i as u32) => {
                environment = *radiance
            }
            Emitter::Point { .. } | Emitter::Spot(_) | Emitter::Directional { .. } => {
                samples_emitters = true
            }
            // On a surface taken above (the shapes loop refuses any other).
            Emitter::Area { .. } => {
                samples_emitters = true;
                area_emitters = true;
            }
            _ => {
                return Err(
                    "an emitter is not an area, point, spot, directional or constant sky".into(),
                )
            }
        }
    }
    Ok((environment, samples_emitters, area_emitters))
}
