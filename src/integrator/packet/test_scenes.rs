//! The scenes and rays the packet's tests render (`tests`, `plain_tests`): media behind
//! null and dielectric boundaries, diffuse surfaces, area, point and directional lights,
//! the sky, a heterogeneous cloud.

use glam::Vec3A;

use crate::scene::Scene;

/// Two media spheres under a sky: a grey forward-scattering one and a chromatic
/// backward-scattering one (σ_t of its channels within a factor 4: every channel's
/// variance stays finite with the hero's sampling).
pub(super) const TWO_SPHERES: &str = r#"<scene version="3.0.0">
    <integrator type="volpath"><integer name="rr_depth" value="3"/></integrator>
    <sensor type="perspective"><film type="hdrfilm">
        <integer name="width" value="4"/><integer name="height" value="4"/></film></sensor>
    <shape type="sphere"><point name="center" x="-0.6" y="0" z="4"/>
        <float name="radius" value="0.5"/><bsdf type="null"/>
        <medium type="homogeneous" name="interior">
            <float name="sigma_t" value="3"/><float name="albedo" value="0.8"/>
            <phase type="hg"><float name="g" value="0.6"/></phase></medium></shape>
    <shape type="sphere"><point name="center" x="0.6" y="0.1" z="4.5"/>
        <float name="radius" value="0.55"/><bsdf type="null"/>
        <medium type="homogeneous" name="interior">
            <rgb name="sigma_t" value="0.3, 0.6, 1"/><float name="scale" value="5"/><rgb name="albedo" value="0.9, 0.7, 0.5"/>
            <phase type="hg"><float name="g" value="-0.3"/></phase></medium></shape>
    <emitter type="constant"><rgb name="radiance" value="1, 0.8, 0.6"/></emitter>
</scene>"#;

/// The two spheres on a diffuse floor (touching the grey one) beside a diffuse ball,
/// lit by a point light, a directional light and the sky: emitter samples from medium
/// and surface vertices, shadow rays through media and blocked by surfaces.
pub(super) fn lit_spheres() -> String {
    TWO_SPHERES.replace(
        "<emitter type=\"constant\">",
        r#"<shape type="rectangle"><transform name="to_world"><scale value="3"/>
            <rotate x="1" angle="-90"/><translate x="0" y="-0.5" z="4"/></transform>
            <bsdf type="diffuse"><rgb name="reflectance" value="0.5, 0.6, 0.7"/></bsdf></shape>
        <shape type="sphere"><point name="center" x="0" y="0.9" z="5"/>
            <float name="radius" value="0.3"/>
            <bsdf type="diffuse"><rgb name="reflectance" value="0.8, 0.8, 0.8"/></bsdf></shape>
        <emitter type="point"><point name="position" x="0.5" y="2" z="3.5"/>
            <rgb name="intensity" value="5, 5, 5"/></emitter>
        <emitter type="directional"><vector name="direction" x="0.3" y="-1" z="0.2"/>
            <rgb name="irradiance" value="1.5, 1.5, 1.5"/></emitter>
        <emitter type="constant">"#,
    )
}

/// Rays from the origin into the lit scene: the media spheres, the floor, the ball.
pub(super) fn lit_rays() -> Vec<Vec3A> {
    [
        (-0.15, 0.0),
        (-0.22, 0.08),
        (0.133, 0.022),
        (0.0, -0.2),
        (0.3, -0.12),
        (0.0, 0.18),
    ]
    .into_iter()
    .map(|(x, y)| Vec3A::new(x, y, 1.0).normalize())
    .collect()
}

/// A chromatic medium cube and a grey medium sphere on a floor, lit by an area light
/// (seen directly by one of the rays), a point light and the sky: boxes, area-light
/// samples and hits with their MIS weights.
pub(super) fn box_and_area_light() -> String {
    lit_spheres()
        .replace(
            r#"<shape type="sphere"><point name="center" x="0.6" y="0.1" z="4.5"/>
        <float name="radius" value="0.55"/>"#,
            r#"<shape type="cube"><transform name="to_world"><scale value="0.45"/>
            <rotate y="1" angle="25"/><translate x="0.6" y="0" z="4.5"/></transform>"#,
        )
        .replace(
            r#"<emitter type="directional">"#,
            r#"<shape type="rectangle"><transform name="to_world"><scale value="0.4"/>
                <lookat origin="-0.3, 1.4, 3.6" target="0, 0, 2" up="0, 1, 0"/></transform>
                <emitter type="area"><rgb name="radiance" value="6, 5, 4"/></emitter></shape>
            <emitter type="directional">"#,
        )
}

/// The camera in a chromatic fog filling a large sphere, a diffuse cube and a small
/// sphere light in the fog, the sky outside: surfaces inside a medium, the camera in
/// one, and an area light seen through it (counted in expectation).
pub(super) const FOG: &str = r#"<scene version="3.0.0">
    <integrator type="volpath"><integer name="rr_depth" value="3"/></integrator>
    <medium type="homogeneous" id="fog">
        <rgb name="sigma_t" value="0.3, 0.4, 0.5"/><float name="albedo" value="0.8"/>
        <phase type="hg"><float name="g" value="0.4"/></phase></medium>
    <sensor type="perspective"><ref id="fog"/><film type="hdrfilm">
        <integer name="width" value="4"/><integer name="height" value="4"/></film></sensor>
    <shape type="sphere"><float name="radius" value="6"/><bsdf type="null"/>
        <ref name="interior" id="fog"/></shape>
    <shape type="cube"><transform name="to_world"><scale value="0.5"/>
        <rotate y="1" angle="25"/><translate z="3"/></transform>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.7, 0.5, 0.3"/></bsdf></shape>
    <shape type="sphere"><point name="center" x="1.2" y="1.2" z="3.5"/>
        <float name="radius" value="0.2"/>
        <emitter type="area"><rgb name="radiance" value="20, 18, 15"/></emitter></shape>
    <emitter type="constant"><rgb name="radiance" value="0.3, 0.3, 0.4"/></emitter>
</scene>"#;

/// Rays from the camera in the fog: the cube (centre and edge), the light, the fog
/// beside them, and away from everything (out to the sky through the fog).
pub(super) fn fog_rays() -> Vec<Vec3A> {
    [
        (0.0, 0.0, 1.0),
        (0.18, 0.1, 1.0),
        (1.2, 1.2, 3.5),
        (0.6, -0.4, 1.0),
        (0.0, 0.3, -1.0),
    ]
    .into_iter()
    .map(|(x, y, z)| Vec3A::new(x, y, z).normalize())
    .collect()
}

/// A cloud: a heterogeneous medium in a turned cube (a 4×4×4 chromatic σ_t grid, a
/// 2×2×2 albedo grid, HG) over a diffuse floor, lit by a directional light, a point
/// light and the sky: delta tracking, ratio-tracked shadow rays through the cube from
/// inside and from the floor, and the albedo volume's value at each collision.
pub(super) const CLOUD: &str = r#"<scene version="3.0.0">
    <integrator type="volpath"><integer name="rr_depth" value="3"/></integrator>
    <sensor type="perspective"><film type="hdrfilm">
        <integer name="width" value="4"/><integer name="height" value="4"/></film></sensor>
    <shape type="cube"><transform name="to_world"><scale value="0.5"/>
            <rotate y="1" angle="25"/><translate x="0" y="0" z="4"/></transform>
        <bsdf type="null"/>
        <medium type="heterogeneous" name="interior">
            <volume name="sigma_t" type="gridvolume">
                <string name="filename" value="packet_cloud_sigma_t.vol"/>
                <transform name="to_world"><translate value="-0.5, -0.5, -0.5"/>
                    <rotate y="1" angle="25"/><translate x="0" y="0" z="4"/></transform>
            </volume>
            <volume name="albedo" type="gridvolume">
                <string name="filename" value="packet_cloud_albedo.vol"/>
                <transform name="to_world"><translate value="-0.5, -0.5, -0.5"/>
                    <rotate y="1" angle="25"/><translate x="0" y="0" z="4"/></transform>
            </volume>
            <float name="scale" value="$scale"/>
            <phase type="hg"><float name="g" value="0.5"/></phase></medium></shape>
    <shape type="rectangle"><transform name="to_world"><scale value="3"/>
        <rotate x="1" angle="-90"/><translate x="0" y="-0.9" z="4"/></transform>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.5, 0.6, 0.7"/></bsdf></shape>
    <emitter type="point"><point name="position" x="0.5" y="2" z="3.5"/>
        <rgb name="intensity" value="5, 5, 5"/></emitter>
    <emitter type="directional"><vector name="direction" x="0.3" y="-1" z="0.2"/>
        <rgb name="irradiance" value="1.5, 1.5, 1.5"/></emitter>
    <emitter type="constant"><rgb name="radiance" value="0.3, 0.35, 0.45"/></emitter>
</scene>"#;

/// [`CLOUD`] with its density scaled by `scale`, its grids written beside it once.
pub(super) fn cloud(name: &str, scale: f32) -> Scene {
    use crate::medium::grid::write_vol;
    // Once: a test rewriting the files while another loads them read a torn grid.
    static GRIDS: std::sync::Once = std::sync::Once::new();
    GRIDS.call_once(|| {
        let dir = std::env::temp_dir().join(format!("mediareg_packet_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let sigma_t: Vec<f32> = (0..64)
            .flat_map(|i| {
                let v = 0.5 + ((i * 7) % 11) as f32 * 0.5;
                [v, 1.5 * v, 0.8 * v]
            })
            .collect();
        let albedo = [0.9, 0.6, 0.8, 0.95, 0.7, 0.85, 0.5, 0.99];
        for (file, data, res, channels) in [
            ("packet_cloud_sigma_t.vol", &sigma_t[..], [4, 4, 4], 3),
            ("packet_cloud_albedo.vol", &albedo[..], [2, 2, 2], 1),
        ] {
            std::fs::write(dir.join(file), write_vol(res, channels, data)).unwrap();
        }
    });
    load_xml(name, &CLOUD.replace("$scale", &scale.to_string()))
}

/// Rays into the cloud (centre, edge, corner), the floor in its shadow and beside it.
pub(super) fn cloud_rays() -> Vec<Vec3A> {
    [
        (0.0, 0.0),
        (0.1, 0.08),
        (-0.15, 0.12),
        (0.0, -0.2),
        (0.3, -0.2),
    ]
    .into_iter()
    .map(|(x, y)| Vec3A::new(x, y, 1.0).normalize())
    .collect()
}

pub(super) fn load_xml(name: &str, xml: &str) -> Scene {
    crate::integrator::scene_from_xml("packet", name, xml)
}

/// Rays from the origin: into the grey sphere (centre and rim), the chromatic one,
/// past both (between them), and away from both.
pub(super) fn rays() -> Vec<Vec3A> {
    [
        (-0.15, 0.0),
        (-0.22, 0.08),
        (0.133, 0.022),
        (0.17, -0.05),
        (0.0, 0.0),
        (0.0, 0.5),
    ]
    .into_iter()
    .map(|(x, y)| Vec3A::new(x, y, 1.0).normalize())
    .collect()
}

/// The box scene with its grey medium behind glass (a smooth dielectric of index 1.5):
/// Fresnel's choice, refraction into and out of the medium, total internal reflection,
/// η in the roulette, emitters met after delta vertices counted in full.
pub(super) fn glass_and_area_light() -> String {
    box_and_area_light().replacen(
        r#"<bsdf type="null"/>"#,
        r#"<bsdf type="dielectric"><float name="int_ior" value="1.5"/></bsdf>"#,
        1,
    )
}

/// Rays into the box scene: the sphere, the cube (centre and edge), the floor, the
/// area light, the ball.
pub(super) fn box_rays() -> Vec<Vec3A> {
    let light = Vec3A::new(-0.3, 1.4, 3.6).normalize();
    [
        (-0.15, 0.0),
        (0.133, 0.0),
        (0.2, 0.08),
        (0.0, -0.2),
        (0.0, 0.18),
    ]
    .into_iter()
    .map(|(x, y)| Vec3A::new(x, y, 1.0).normalize())
    .chain([light])
    .collect()
}
