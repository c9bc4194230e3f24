//! Shape plugins: Mitsuba's `obj`, `ply`, `serialized`, `cube`, `sphere`, `rectangle`
//! and `disk`, with the BSDF, emitter and media each one carries.

use std::path::Path;

use glam::{DMat4, DVec3, Vec3};

use super::instance::Placement;
use super::props::Props;
use super::{to_mat4, unsupported, Builder};
use crate::bsdf::Bsdf;
use crate::error::{Result, SceneError};
use crate::geometry::mesh::{cube, read_obj, TriangleMesh};
use crate::geometry::ply::read_ply;
use crate::geometry::serialized::read_serialized;
use crate::geometry::shape::{Geometry, Planar, Sphere};
use crate::scene::ShapeInfo;
use crate::texture::Texture;
use crate::xml::description::{ObjId, ObjectKind};
use crate::xml::resolve::resolve_path;

thread_local! {
    static MESH_FILES_READ: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

/// How many mesh files (ply, obj, serialized) this thread has read from disk while
/// loading scenes: tests check that instances share one read.
pub fn mesh_files_read() -> usize {
    MESH_FILES_READ.with(|n| n.get())
}

/// The largest |coordinate| a shape may reach.
const MAX_COORDINATE: f32 = 1e12;

impl Builder<'_> {
    /// Builds one shape; a shapegroup's shape is built once per instance, `placed` by it.
    pub(super) fn shape(&mut self, id: ObjId, placed: Option<&Placement>) -> Result<()> {
        let p = Props::new(self.desc, id);
        let to_world = placed.map_or(DMat4::IDENTITY, |i| i.to_world) * p.transform("to_world")?;
        let under = placed.map_or(String::new(), |i| {
            format!(" (placed by the instance at {})", i.loc)
        });
        let flip_normals = p.bool("flip_normals", false)?;
        let geometry = match p.obj.plugin.as_str() {
            "ply" | "obj" | "serialized" => self.mesh_geometry(&p, to_world, flip_normals)?,
            "cube" => {
                let to_world = to_mat4(to_world);
                let mut mesh =
                    TriangleMesh::new(cube(), &to_world, true, flip_normals, Path::new("cube"))?;
                mesh.cube_to_world = Some(to_world);
                Geometry::Mesh(mesh)
            }
            "sphere" => sphere_geometry(&p, to_world, flip_normals, &under)?,
            "rectangle" => Geometry::Planar(Planar::new(to_mat4(to_world), flip_normals, false)),
            "disk" => Geometry::Planar(Planar::new(to_mat4(to_world), flip_normals, true)),
            _ => {
                return Err(unsupported(
                    &p,
                    "shape",
                    "ply, obj, serialized, sphere, cube, rectangle, disk",
                ))
            }
        };
        check_reach(&p, &geometry)?;
        let shape_index = self.geometries.len() as u32;
        let emitter = match p.child_of(ObjectKind::Emitter)? {
            Some(c) if placed.is_some() => {
                return Err(SceneError::at(
                    &c.loc,
                    format!("{}: an emitter on a shape in a shapegroup: Mitsuba 3 refuses it (\"Instancing of emitters is not supported\")", p.obj.label()),
                )
                .with_hint("give each light its own <shape> outside the shapegroup"))
            }
            Some(c) => Some(self.emitter(c.object, Some(shape_index))?),
            None => None,
        };
        let bsdf = match p.child_of(ObjectKind::Bsdf)? {
            Some(c) => self.bsdf(c.object)?,
            None => {
                // Mitsuba's default: diffuse 0.5, or black for an emitter.
                let r = if emitter.is_some() { 0.0 } else { 0.5 };
                self.bsdfs.push(Bsdf::Diffuse {
                    reflectance: Texture::Constant(Vec3::splat(r)),
                });
                self.bsdfs.len() as u32 - 1
            }
        };
        let (interior, exterior) = self.shape_media(&p)?;
        let tangent_frame = self.check_surface(&p, bsdf, emitter.is_some(), &geometry)?;
        let names = match p.obj.plugin.as_str() {
            "ply" => "filename, to_world, face_normals, flip_normals, bsdf, emitter, interior, exterior",
            "obj" => "filename, to_world, face_normals, flip_normals, flip_tex_coords, bsdf, emitter, interior, exterior",
            "serialized" => "filename, shape_index, to_world, face_normals, flip_normals, bsdf, emitter, interior, exterior",
            "sphere" => "center, radius, to_world, flip_normals, bsdf, emitter, interior, exterior",
            _ => "to_world, flip_normals, bsdf, emitter, interior, exterior",
        };
        let (id, origin) = (
            p.obj.id.clone(),
            format!("{} at {}", p.obj.label(), p.loc()),
        );
        p.finish(names)?;
        self.geometries.push(geometry);
        self.shapes.push(ShapeInfo {
            bsdf,
            emitter,
            interior,
            exterior,
            id,
            origin,
            tangent_frame,
        });
        Ok(())
    }

    /// The mesh of a `ply`, `obj` or `serialized` shape `p`, placed by `to_world`: its
    /// file found on the search path and read once however many shapes use it.
    fn mesh_geometry(
        &mut self,
        p: &Props,
        to_world: DMat4,
        flip_normals: bool,
    ) -> Result<Geometry> {
        let (name, loc) = p
            .string_opt("filename")?
            .ok_or_else(|| p.error("missing the \"filename\" property"))?;
        let path = resolve_path(&self.desc.search_path, name).ok_or_else(|| {
            let dirs: Vec<String> = self.desc.search_path.iter().map(|d| d.display().to_string()).collect();
            SceneError::at(loc, format!("mesh file \"{name}\" not found"))
                .with_hint(format!(
                    "searched: {}; add its folder with -a DIR (for the Stanford meshes run scripts/fetch_meshes)",
                    dirs.join(", ")
                ))
        })?;
        let face_normals = p.bool("face_normals", false)?;
        let index = match p.obj.plugin.as_str() {
            "serialized" => {
                let index = p.int("shape_index", 0)?;
                u32::try_from(index)
                    .map_err(|_| p.error(format!("shape_index = {index}: must be 0 or more")))?
            }
            _ => 0,
        };
        // Each file is read once, however many instances (or shapes) use it.
        let key = (p.obj.plugin.clone(), path.clone(), index);
        let mut raw = match self.meshes.get(&key) {
            Some(raw) => raw.clone(),
            None => {
                MESH_FILES_READ.with(|n| n.set(n.get() + 1));
                let raw = match p.obj.plugin.as_str() {
                    "ply" => read_ply(&path),
                    "obj" => read_obj(&path),
                    _ => read_serialized(&path, index),
                }
                // Name the scene line of the <shape> too, not only the mesh file.
                .map_err(|e| SceneError::at(p.loc(), format!("{}: {e}", p.obj.label())))?;
                self.meshes.insert(key, raw.clone());
                raw
            }
        };
        // Mitsuba flips an OBJ's v (v ↦ 1 − v) unless told not to.
        if p.obj.plugin == "obj" && p.bool("flip_tex_coords", true)? {
            if let Some(uvs) = &mut raw.uvs {
                uvs.iter_mut().for_each(|t| t.y = 1.0 - t.y);
            }
        }
        self.warnings
            .extend(raw.warnings.iter().map(|w| format!("{}: {w}", p.loc())));
        Ok(Geometry::Mesh(TriangleMesh::new(
            raw,
            &to_mat4(to_world),
            face_normals,
            flip_normals,
            Path::new(&path),
        )?))
    }

    /// The shape's interior and exterior media; a nested medium under any other name
    /// (or none) is loaded, bound to nothing, and warned about.
    fn shape_media(&mut self, p: &Props) -> Result<(Option<u32>, Option<u32>)> {
        let interior = match p.named_child_of("interior", ObjectKind::Medium)? {
            Some(c) => Some(self.medium(c.object)?),
            None => None,
        };
        let exterior = match p.named_child_of("exterior", ObjectKind::Medium)? {
            Some(c) => Some(self.medium(c.object)?),
            None => None,
        };
        // Mitsuba binds a nested medium only by the name interior or exterior; any other
        // (or none) is loaded and bound to nothing.
        for c in p.children_of(ObjectKind::Medium) {
            if !matches!(c.name.as_deref(), Some("interior" | "exterior")) {
                self.medium(c.object)?;
                let named = c
                    .name
                    .as_deref()
                    .map_or("no name".to_string(), |n| format!("name=\"{n}\""));
                let line = format!(
                    "{}: {}: a medium with {named} is bound to nothing (as in Mitsuba 3); write name=\"interior\" or name=\"exterior\" to bind it",
                    c.loc,
                    p.obj.label()
                );
                // Once, though a shapegroup's shape is built once per instance.
                if !self.warnings.contains(&line) {
                    self.warnings.push(line);
                }
            }
        }
        Ok((interior, exterior))
    }

    /// Refuses what the shape `p`'s surface cannot carry here: a textured or anisotropic
    /// `bsdf` without the texture coordinates it needs, an area light (`emitter`) of no
    /// finite area. Returns whether the shading frame must follow ∂p/∂u.
    fn check_surface(
        &self,
        p: &Props,
        bsdf: u32,
        emitter: bool,
        geometry: &Geometry,
    ) -> Result<bool> {
        // Texture coordinates exist on meshes and rectangles only (Mitsuba's cube, sphere
        // and disk have their own, not implemented here).
        if self.bsdfs[bsdf as usize].is_textured()
            && matches!(p.obj.plugin.as_str(), "cube" | "sphere" | "disk")
        {
            return Err(p.error(format!(
                "a textured bsdf on a \"{}\" shape is not supported yet (texture coordinates exist on ply/obj meshes and rectangles)",
                p.obj.plugin
            )));
        }
        // Anisotropy is oriented by ∂p/∂u, which mediareg follows on meshes, rectangles,
        // disks and spheres; Mitsuba's cube has its own texture coordinates, which
        // mediareg's cube lacks.
        let tangent_frame = self.bsdfs[bsdf as usize].is_anisotropic();
        if tangent_frame && p.obj.plugin == "cube" {
            return Err(p.error(format!(
                "anisotropic roughness on a \"{}\" shape is not supported yet (it follows the surface's ∂p/∂u, which mediareg has on ply/obj/serialized meshes, rectangles, disks and spheres)",
                p.obj.plugin
            )));
        }
        // An area light is sampled with pdf 1 / area.
        if emitter && !(geometry.area() > 0.0 && geometry.area().is_finite()) {
            return Err(p.error(format!(
                "the area light's shape has area {}: it must be finite and > 0; check its to_world scale",
                geometry.area()
            )));
        }
        Ok(tangent_frame)
    }
}

/// The sphere of shape `p` placed by `to_world` (a similarity transform; `under` names
/// the instance that places it, if one does).
fn sphere_geometry(
    p: &Props,
    to_world: DMat4,
    flip_normals: bool,
    under: &str,
) -> Result<Geometry> {
    let center = p.point_opt("center")?.unwrap_or(DVec3::ZERO);
    let radius = p.float("radius", 1.0)?;
    if radius <= 0.0 {
        return Err(p.error(format!("radius = {radius}: must be > 0")));
    }
    // Mitsuba: to_world · translate(center) · scale(radius); only similarity
    // transforms keep it a sphere.
    let c = to_world.transform_point3(center);
    let axes = [DVec3::X, DVec3::Y, DVec3::Z].map(|a| to_world.transform_vector3(a).length());
    if (axes[0] - axes[1]).abs() > 1e-6 * axes[0] || (axes[0] - axes[2]).abs() > 1e-6 * axes[0] {
        return Err(p.error(format!(
            "to_world scales the sphere non-uniformly{under}; use a ply/obj mesh for an ellipsoid"
        )));
    }
    let linear = glam::DMat3::from_mat4(to_world) / axes[0];
    Ok(Geometry::Sphere(Sphere {
        center: c.as_vec3().into(),
        radius: (radius * axes[0]) as f32,
        flip_normals,
        axes: glam::Mat3A::from(linear.as_mat3()),
    }))
}

/// Refuses a shape `p` whose `geometry` is not finite or reaches past `MAX_COORDINATE`.
fn check_reach(p: &Props, geometry: &Geometry) -> Result<()> {
    // Single-precision ray tracing needs finite coordinates of sane magnitude (at 1e12
    // one f32 step is 6e4 units; box areas overflow near 1e19 and break the BVH).
    let b = geometry.bounds();
    let mut reach = b.min.abs().max(b.max.abs()).max_element();
    if let Geometry::Mesh(m) = geometry {
        // Bounds skip NaN; a NaN vertex (binary PLY) must not.
        if m.positions.iter().any(|p| !p.is_finite()) {
            reach = f32::NAN;
        }
    }
    if !b.is_empty() && (reach.is_nan() || reach > MAX_COORDINATE) {
        return Err(p.error(format!(
            "the shape reaches {reach:e} from the origin: coordinates must be finite and within ±{MAX_COORDINATE:e}; check its to_world, radius or the mesh's units"
        )));
    }
    Ok(())
}
