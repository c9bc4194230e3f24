//! Which scenes the packet kernel takes, and what it keeps of them: media spheres,
//! diffuse surfaces, media, emitters and the integrator's settings.

use glam::{Vec3, Vec4};

use crate::bsdf::Bsdf;
use crate::emitter::Emitter;
use crate::geometry::shape::Geometry;
use crate::integrator::volpath::{Gradient, PathSettings};
use crate::medium::Phase;
use crate::scene::{IntegratorKind, Scene};

/// The largest |g| of a Henyey–Greenstein medium the packet takes: its sampling is in
/// f32, which resolves the peak (width ~(1 − |g|)² in 1 − cos θ) well below this.
pub const MAX_ABS_G: f32 = 0.95;

/// How far a diffuse surface's plane may reach into a medium sphere, relative to its
/// radius (a floor the sphere rests on touches it in one point, up to rounding).
const TOUCH_TOLERANCE: f32 = 1e-5;

/// A `null` sphere filled with a homogeneous medium, in empty space.
#[derive(Clone, Copy, Debug)]
pub struct MediumSphere {
    pub center: Vec3,
    pub radius2: f32,
    pub medium: u32,
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
}

/// An opaque `diffuse` surface (front side only, constant reflectance).
#[derive(Clone, Copy, Debug)]
pub struct Surface {
    pub shape: SurfaceShape,
    pub reflectance: Vec3,
}

/// A medium's extinction and phase function (the albedo is the render's).
#[derive(Clone, Copy, Debug)]
pub struct PacketMedium {
    pub sigma_t: Vec3,
    /// Henyey–Greenstein's g (0: isotropic).
    pub g: f32,
}

/// What the packet kernel needs of a scene it takes.
#[derive(Clone, Debug)]
pub struct PacketScene {
    pub spheres: Vec<MediumSphere>,
    pub surfaces: Vec<Surface>,
    pub media: Vec<PacketMedium>,
    /// The sky's radiance (0 where there is none).
    pub environment: Vec3,
    pub has_environment: bool,
    /// Whether a vertex has an emitter to sample (a sky alone is left to BSDF and
    /// phase sampling under volpath: `emitter::selection`).
    pub samples_emitters: bool,
    pub max_depth: u32,
    pub rr_depth: u32,
    pub hide_emitters: bool,
    /// Every medium's σ_t is the same in all channels: no transmittance is needed.
    pub grey: bool,
}

impl PacketScene {
    /// The packet form of `scene`, or why its paths need the scalar integrator. Taken:
    /// `volpath` with the camera in empty space; shapes that are `null` spheres each
    /// bounding a homogeneous medium inside empty space (no two touching), or
    /// rectangles, disks and spheres with a constant `diffuse` BSDF that reach into no
    /// medium sphere; isotropic or Henyey–Greenstein (|g| ≤ [`MAX_ABS_G`]) phase
    /// functions; point, spot and directional emitters and a `constant` sky (emitters
    /// sampled by their delta alone need no MIS weight, and a constant sky is never
    /// sampled under volpath, so none is needed on escape either).
    pub fn new(scene: &Scene) -> Result<PacketScene, String> {
        if scene.integrator.kind != IntegratorKind::Volpath {
            return Err("the integrator is not volpath".into());
        }
        if scene.camera_medium.is_some() {
            return Err("the camera is inside a medium".into());
        }
        if scene.ray_log.is_some() {
            return Err("casts are being logged".into());
        }
        let mut spheres = Vec::new();
        let mut surfaces = Vec::new();
        for (shape, geometry) in scene.shapes.iter().zip(&scene.geometries) {
            if shape.emitter.is_some() {
                return Err("a shape emits".into());
            }
            let bsdf = &scene.bsdfs[shape.bsdf as usize];
            match (geometry, bsdf, shape.interior, shape.exterior) {
                (Geometry::Sphere(s), Bsdf::Null, Some(medium), None) if !s.flip_normals => spheres
                    .push(MediumSphere {
                        center: Vec3::from(s.center),
                        radius2: s.radius * s.radius,
                        medium,
                    }),
                (_, Bsdf::Null, _, _) => {
                    return Err(
                        "a null shape is not a sphere bounding a medium inside empty space".into(),
                    )
                }
                (g, Bsdf::Diffuse { reflectance }, None, None) => {
                    let Some(reflectance) = reflectance.constant() else {
                        return Err("a diffuse reflectance is textured".into());
                    };
                    let shape = match g {
                        Geometry::Sphere(s) if !s.flip_normals => SurfaceShape::Sphere {
                            center: Vec3::from(s.center),
                            radius2: s.radius * s.radius,
                        },
                        Geometry::Planar(p) => SurfaceShape::Planar {
                            rows: [p.to_local.row(0), p.to_local.row(1), p.to_local.row(2)],
                            normal: Vec3::from(p.normal),
                            disk: p.is_disk,
                        },
                        _ => {
                            return Err("a diffuse shape is not a rectangle, disk or sphere".into())
                        }
                    };
                    surfaces.push(Surface { shape, reflectance });
                }
                _ => return Err("a shape's BSDF is not null or diffuse".into()),
            }
        }
        for (i, a) in spheres.iter().enumerate() {
            for b in &spheres[..i] {
                let reach = a.radius2.sqrt() + b.radius2.sqrt();
                if a.center.distance(b.center) <= reach {
                    return Err("two medium spheres touch or overlap".into());
                }
            }
            let r = a.radius2.sqrt();
            for s in &surfaces {
                let clear = match s.shape {
                    SurfaceShape::Sphere { center, radius2 } => {
                        a.center.distance(center) >= r + radius2.sqrt()
                    }
                    SurfaceShape::Planar { rows, .. } => {
                        // The plane z = 0 of the shape's space: its distance from the
                        // centre is |z_local| over the gradient's length.
                        let z = rows[2].dot(a.center.extend(1.0));
                        z.abs() >= r * (1.0 - TOUCH_TOLERANCE) * rows[2].truncate().length()
                    }
                };
                if !clear {
                    return Err("a diffuse surface reaches into a medium sphere".into());
                }
            }
        }
        let mut media = Vec::new();
        for m in &scene.media {
            if m.heterogeneous.is_some() {
                return Err("a medium is heterogeneous".into());
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
            });
        }
        let mut environment = Vec3::ZERO;
        let mut samples_emitters = false;
        for (i, e) in scene.emitters.iter().enumerate() {
            match e {
                Emitter::Constant { radiance } if scene.environment == Some(i as u32) => {
                    environment = *radiance
                }
                Emitter::Point { .. } | Emitter::Spot(_) | Emitter::Directional { .. } => {
                    samples_emitters = true
                }
                _ => {
                    return Err(
                        "an emitter is not a point, spot, directional or constant sky".into(),
                    )
                }
            }
        }
        let grey = scene.media.iter().all(|m| m.is_grey());
        Ok(PacketScene {
            spheres,
            surfaces,
            media,
            environment,
            has_environment: scene.environment.is_some(),
            samples_emitters,
            max_depth: scene.integrator.max_depth,
            rr_depth: scene.integrator.rr_depth,
            hide_emitters: scene.integrator.hide_emitters,
            grey,
        })
    }
}

/// A render's per-medium values: its albedo and the factors (a, b) by which a vertex
/// there updates dβ (`Gradient::vertex_factors`).
#[derive(Clone, Debug)]
pub struct PacketSettings {
    pub albedo: Vec<Vec3>,
    pub factor_a: Vec<Vec3>,
    pub factor_b: Vec<Vec3>,
    /// The difference's paths are rouletted by β + dβ (volpath's roulette).
    pub roulette_by_target: bool,
}

impl PacketSettings {
    pub fn new(settings: &PathSettings) -> PacketSettings {
        let n = settings.albedo.len();
        let (factor_a, factor_b) = (0..n)
            .map(|m| {
                settings
                    .gradient
                    .vertex_factors(m as u32, settings.albedo[m])
            })
            .unzip();
        PacketSettings {
            albedo: settings.albedo.to_vec(),
            factor_a,
            factor_b,
            roulette_by_target: matches!(settings.gradient, Gradient::Difference { .. }),
        }
    }
}
