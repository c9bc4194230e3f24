//! The XML loader and scene builder, item by item, each test asserting built values.
//! Transform matrices against real Mitsuba 3 are checked in tests/parser.rs.

mod common;

use std::path::PathBuf;

use glam::{DVec3, Vec3};
use mediareg::bsdf::Bsdf;
use mediareg::emitter::Emitter;
use mediareg::geometry::shape::Geometry;
use mediareg::load::build_scene;
use mediareg::medium::Phase;
use mediareg::scene::film::Rfilter;
use mediareg::scene::{IntegratorKind, Scene};
use mediareg::xml::description::{ObjectKind, SceneDescription, Value};
use mediareg::xml::{load_file, LoadOptions};
use mediareg::BuildOverrides;

use common::scene_text::{self, build_desc, load_or_build_error, prop, write, SENSOR};

fn tmp_dir(tag: &str) -> PathBuf {
    scene_text::tmp_dir("xml", tag)
}

/// Loads `<scene version="3.0.0">{body}</scene>`, all on line 1, from a temp file.
fn load(tag: &str, body: &str, params: &[(&str, &str)]) -> Result<SceneDescription, String> {
    let text = format!("<scene version=\"3.0.0\">{body}</scene>");
    scene_text::load_text("xml", tag, &text, params)
}

fn build(tag: &str, body: &str) -> Scene {
    let desc = load(tag, &format!("{SENSOR}{body}"), &[]).unwrap_or_else(|e| panic!("{e}"));
    build_desc(tag, &desc)
}

fn build_err(tag: &str, body: &str) -> String {
    load_or_build_error(tag, load(tag, &format!("{SENSOR}{body}"), &[]))
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * (1.0 + a.abs().max(b.abs()))
}

#[test]
fn default_and_substitution_in_any_attribute() {
    let body = r#"<default name="kind" value="sphere"/><default name="r" value="2.5"/><default name="prop" value="radius"/>
        <shape type="$kind"><float name="$prop" value="$r"/></shape>"#;
    let desc = load("subst", body, &[]).unwrap();
    assert!(desc.objects.iter().any(|o| o.plugin == "sphere"));
    assert_eq!(prop(&desc, ObjectKind::Shape, "radius"), &Value::Float(2.5));
    // -D wins over <default>.
    let desc = load("subst_d", body, &[("r", "7")]).unwrap();
    assert_eq!(prop(&desc, ObjectKind::Shape, "radius"), &Value::Float(7.0));
}

#[test]
fn undefined_and_unused_parameters_are_errors() {
    let e = load(
        "undef",
        r#"<shape type="sphere"><float name="radius" value="$nope"/></shape>"#,
        &[],
    )
    .unwrap_err();
    assert!(
        e.contains("undefined parameter $nope") && e.contains("scene.xml:1:"),
        "{e}"
    );
    let e = load("unused", r#"<shape type="sphere"/>"#, &[("never", "1")]).unwrap_err();
    assert!(e.contains("\"never\""), "{e}");
}

#[test]
fn include_is_relative_to_the_scene_folder_and_cycles_are_caught() {
    let dir = tmp_dir("include");
    std::fs::create_dir_all(dir.join("parts")).unwrap();
    write(
        &dir,
        "parts/light.xml",
        r#"<scene version="3.0.0"><emitter type="constant"><float name="radiance" value="3"/></emitter></scene>"#,
    );
    let main = write(
        &dir,
        "main.xml",
        r#"<scene version="3.0.0"><include filename="parts/light.xml"/></scene>"#,
    );
    let desc = load_file(&main, &LoadOptions::default()).unwrap();
    assert_eq!(
        prop(&desc, ObjectKind::Emitter, "radiance"),
        &Value::Float(3.0)
    );
    assert_eq!(desc.files.len(), 2);
    let cyc = write(
        &dir,
        "cycle.xml",
        r#"<scene version="3.0.0"><include filename="cycle.xml"/></scene>"#,
    );
    let e = load_file(&cyc, &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("cyclic include"), "{e}");
}

/// `<path value="DIR"/>` puts DIR in front of the search path (Mitsuba 3's resource
/// path): relative to the file it is written in (here an included one), for meshes and
/// later includes alike; a missing folder or a `<path>` below the root is an error.
#[test]
fn path_tag_adds_a_folder_to_the_search_path() {
    let dir = tmp_dir("path_tag");
    write(
        &dir,
        "assets/meshes/tri.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    );
    write(
        &dir,
        "assets/base.xml",
        r#"<scene version="3.0.0"><path value="meshes"/></scene>"#,
    );
    let main = write(
        &dir,
        "scenes/main.xml",
        &format!(
            r#"<scene version="3.0.0">{SENSOR}<path value="../assets"/><include filename="base.xml"/>
<shape type="obj"><string name="filename" value="tri.obj"/></shape></scene>"#
        ),
    );
    let desc = load_file(&main, &LoadOptions::default()).unwrap();
    // The latest <path> first, then the one before, then the scene's folder.
    let first: Vec<_> = desc.search_path[..2]
        .iter()
        .map(|d| d.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(first, ["meshes", "assets"], "{:?}", desc.search_path);
    let scene = build_desc("path_tag", &desc);
    assert_eq!(scene.geometries.len(), 1);

    let e = load("path_missing", r#"<path value="no_such_folder"/>"#, &[]).unwrap_err();
    assert!(
        e.contains(":1:") && e.contains("<path>: folder \"no_such_folder\" not found"),
        "{e}"
    );
    let e = load(
        "path_nested",
        r#"<shape type="sphere"><path value="."/></shape>"#,
        &[],
    )
    .unwrap_err();
    assert!(e.contains("<path> may only be a child of <scene>"), "{e}");
}

#[test]
fn ids_and_refs_share_objects() {
    let s = build(
        "refs",
        r#"<bsdf type="diffuse" id="red"><rgb name="reflectance" value="0.8, 0.1, 0.1"/></bsdf>
           <medium type="homogeneous" id="fog"><float name="sigma_t" value="2"/></medium>
           <shape type="sphere"><ref id="red"/><ref name="interior" id="fog"/></shape>
           <shape type="cube"><ref id="red"/></shape>"#,
    );
    assert_eq!(
        s.shapes[0].bsdf, s.shapes[1].bsdf,
        "a referenced bsdf is built once"
    );
    assert!(
        matches!(&s.bsdfs[s.shapes[0].bsdf as usize], Bsdf::Diffuse { reflectance } if *reflectance == Vec3::new(0.8, 0.1, 0.1))
    );
    assert_eq!(s.shapes[0].interior, Some(0));
    assert_eq!(s.media[0].sigma_t, Vec3::splat(2.0));
    let e = build_err(
        "badref",
        r#"<shape type="sphere"><ref id="missing"/></shape>"#,
    );
    assert!(e.contains("unknown id"), "{e}");
}

#[test]
fn old_files_are_upgraded_like_mitsuba() {
    let dir = tmp_dir("upgrade");
    let path = write(
        &dir,
        "old.xml",
        r#"<scene version="0.6.0">
        <integrator type="path"><integer name="maxDepth" value="4"/></integrator>
        <sensor type="perspective"><float name="fov" value="40"/>
            <transform name="toWorld"><lookAt origin="0,0,5" target="0,0,0" up="0,1,0"/></transform>
            <sampler type="independent"><integer name="sampleCount" value="9"/></sampler>
            <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film></sensor>
        <shape type="sphere"><bsdf type="dielectric"><float name="intIOR" value="1.33"/><float name="extIOR" value="1.0"/></bsdf></shape>
        </scene>"#,
    );
    let desc = load_file(&path, &LoadOptions::default()).unwrap();
    let s = build_scene(&desc, &BuildOverrides::default()).unwrap();
    assert_eq!(s.integrator.max_depth, 4);
    assert_eq!(s.shot.spp, 9);
    let d = s.shot.camera.to_world.transform_vector3(glam::Vec3::Z);
    assert!(
        (d - glam::Vec3::NEG_Z).length() < 1e-6,
        "lookAt upgraded to lookat: {d}"
    );
    assert!(matches!(&s.bsdfs[0], Bsdf::Dielectric(di) if (di.eta - 1.33).abs() < 1e-6));
}

#[test]
fn property_types() {
    let desc = load(
        "types",
        r#"<shape type="sphere">
            <float name="f" value="-1.5e-3"/><integer name="i" value="-7"/><boolean name="b" value="TRUE"/>
            <string name="s" value="hello world"/><point name="p" x="1" z="3"/><vector name="v" value="1 2,3"/>
            <rgb name="c1" value="0.25"/><rgb name="c3" value="0.1, 0.2, 0.3"/><spectrum name="sp" value="0.5"/>
        </shape>"#,
        &[],
    )
    .unwrap();
    let v = |n| prop(&desc, ObjectKind::Shape, n).clone();
    assert_eq!(v("f"), Value::Float(-1.5e-3));
    assert_eq!(v("i"), Value::Integer(-7));
    assert_eq!(v("b"), Value::Boolean(true));
    assert_eq!(v("s"), Value::String("hello world".into()));
    assert_eq!(v("p"), Value::Point(DVec3::new(1.0, 0.0, 3.0)));
    assert_eq!(v("v"), Value::Vector(DVec3::new(1.0, 2.0, 3.0)));
    assert_eq!(v("c1"), Value::Rgb(DVec3::splat(0.25)));
    assert_eq!(v("c3"), Value::Rgb(DVec3::new(0.1, 0.2, 0.3)));
    assert_eq!(v("sp"), Value::Spectrum(0.5));
    for (tag, value) in [
        ("float", "abc"),
        ("integer", "1.5"),
        ("boolean", "yes"),
        ("rgb", "1, 2"),
    ] {
        let e = load(
            "badtype",
            &format!(r#"<shape type="sphere"><{tag} name="x" value="{value}"/></shape>"#),
            &[],
        )
        .unwrap_err();
        assert!(e.contains("scene.xml:1:"), "{tag}: {e}");
    }
    // A sampled spectrum is kept as its (wavelength, value) pairs (converted at build).
    let d = load(
        "sampled",
        r#"<shape type="sphere"><spectrum name="x" value="400:1, 700:2"/></shape>"#,
        &[],
    )
    .unwrap();
    assert_eq!(
        prop(&d, ObjectKind::Shape, "x"),
        &Value::SampledSpectrum(vec![(400.0, 1.0), (700.0, 2.0)])
    );
}

#[test]
fn perspective_fov_axes_and_clipping() {
    // Film is 8 x 4 (aspect 2).
    let tan = |d: f64| (0.5 * d).to_radians().tan();
    for (axis, want) in [
        ("x", tan(40.0)),
        ("y", tan(40.0) * 2.0),
        ("smaller", tan(40.0) * 2.0),
        ("larger", tan(40.0)),
        ("diagonal", tan(40.0) / (1.0f64 + 0.25).sqrt()),
    ] {
        let desc = load(
            axis,
            &format!(
                r#"<sensor type="perspective"><float name="fov" value="40"/><string name="fov_axis" value="{axis}"/>
                <float name="near_clip" value="0.5"/><float name="far_clip" value="50"/>
                <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="4"/></film></sensor>"#
            ),
            &[],
        )
        .unwrap();
        let s = build_scene(&desc, &BuildOverrides::default()).unwrap();
        assert!(
            close(s.shot.camera.tan_half_fov_x as f64, want, 1e-6),
            "{axis}: {} vs {want}",
            s.shot.camera.tan_half_fov_x
        );
        assert_eq!(
            (s.shot.camera.near_clip, s.shot.camera.far_clip),
            (0.5, 50.0)
        );
        assert_eq!(s.shot.camera.aspect, 2.0);
    }
    for bad in ["0", "180"] {
        let body =
            format!(r#"<sensor type="perspective"><float name="fov" value="{bad}"/></sensor>"#);
        let desc = load("badfov", &body, &[]).unwrap();
        let e = build_scene(&desc, &BuildOverrides::default())
            .err()
            .expect("fov out of range")
            .to_string();
        assert!(e.contains("fov"), "{e}");
    }
}

#[test]
fn film_crop_and_filters() {
    let film = |tag: &str, inner: &str| -> Scene {
        let desc = load(
            tag,
            &format!(r#"<sensor type="perspective"><float name="fov" value="40"/><film type="hdrfilm">{inner}</film></sensor>"#),
            &[],
        )
        .unwrap();
        build_scene(&desc, &BuildOverrides::default()).unwrap_or_else(|e| panic!("{e}"))
    };
    let s = film("defaults", "");
    assert_eq!((s.shot.film.width, s.shot.film.height), (768, 576));
    assert_eq!(
        s.shot.film.rfilter,
        Rfilter::Gaussian { stddev: 0.5 },
        "hdrfilm defaults to a gaussian filter"
    );
    let s = film(
        "crop",
        r#"<integer name="width" value="100"/><integer name="height" value="50"/>
           <integer name="crop_offset_x" value="10"/><integer name="crop_offset_y" value="5"/>
           <integer name="crop_width" value="20"/><integer name="crop_height" value="30"/><rfilter type="box"/>"#,
    );
    assert_eq!(
        (
            s.shot.film.crop_offset,
            s.shot.film.crop_size,
            s.shot.film.rfilter
        ),
        ((10, 5), (20, 30), Rfilter::Box)
    );
    assert_eq!(
        film("tent", r#"<rfilter type="tent"/>"#).shot.film.rfilter,
        Rfilter::Tent { radius: 1.0 }
    );
    assert_eq!(
        film(
            "gauss",
            r#"<rfilter type="gaussian"><float name="stddev" value="0.3"/></rfilter>"#
        )
        .shot
        .film
        .rfilter,
        Rfilter::Gaussian { stddev: 0.3 }
    );
    for bad in [
        r#"<integer name="width" value="0"/>"#,
        r#"<integer name="crop_width" value="1000"/>"#,
    ] {
        let desc = load(
            "badfilm",
            &format!(r#"<sensor type="perspective"><film type="hdrfilm">{bad}</film></sensor>"#),
            &[],
        )
        .unwrap();
        assert!(
            build_scene(&desc, &BuildOverrides::default()).is_err(),
            "{bad}"
        );
    }
}

#[test]
fn sampler_and_integrator() {
    let desc = load(
        "sampler",
        r#"<integrator type="path"><integer name="max_depth" value="-1"/><integer name="rr_depth" value="3"/><boolean name="hide_emitters" value="true"/></integrator>
           <sensor type="perspective"><float name="fov" value="40"/><sampler type="independent"><integer name="sample_count" value="33"/><integer name="seed" value="5"/></sampler></sensor>"#,
        &[],
    )
    .unwrap();
    let s = build_scene(&desc, &BuildOverrides::default()).unwrap();
    assert_eq!((s.shot.spp, s.shot.seed), (33, 5));
    assert_eq!(s.integrator.kind, IntegratorKind::Path);
    assert_eq!(
        (
            s.integrator.max_depth,
            s.integrator.rr_depth,
            s.integrator.hide_emitters
        ),
        (u32::MAX, 3, true)
    );
    let s = build_scene(
        &desc,
        &BuildOverrides {
            spp: Some(2),
            seed: Some(9),
            crop: None,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(
        (s.shot.spp, s.shot.seed),
        (2, 9),
        "--spp and --seed override the file"
    );
    let e = build_err("volpath", r#"<integrator type="bdpt"/>"#);
    assert!(
        e.contains("unsupported integrator plugin \"bdpt\"") && e.contains("path, volpath"),
        "{e}"
    );
}

#[test]
fn shapes() {
    let s = build(
        "shapes",
        r#"<shape type="sphere"><point name="center" x="1" y="2" z="3"/><float name="radius" value="0.5"/>
               <transform name="to_world"><scale value="2"/><translate x="1"/></transform></shape>
           <shape type="rectangle"><transform name="to_world"><scale x="2" y="3" z="1"/></transform></shape>
           <shape type="disk"><boolean name="flip_normals" value="true"/></shape>
           <shape type="cube"/>"#,
    );
    let Geometry::Sphere(sp) = &s.geometries[0] else {
        panic!()
    };
    assert!(
        (sp.center - glam::Vec3A::new(3.0, 4.0, 6.0)).length() < 1e-6
            && (sp.radius - 1.0).abs() < 1e-6
    );
    let Geometry::Planar(r) = &s.geometries[1] else {
        panic!()
    };
    assert!((r.area - 24.0).abs() < 1e-5 && (r.normal - glam::Vec3A::Z).length() < 1e-6);
    let Geometry::Planar(d) = &s.geometries[2] else {
        panic!()
    };
    assert!(
        (d.area - std::f32::consts::PI).abs() < 1e-5 && (d.normal + glam::Vec3A::Z).length() < 1e-6
    );
    let Geometry::Mesh(c) = &s.geometries[3] else {
        panic!()
    };
    assert_eq!(c.triangles.len(), 12);
    assert!((c.total_area - 24.0).abs() < 1e-5);
    // Outward normals: the +x face's triangles have geometric normal +x.
    for t in 0..12 {
        let (p, n, _) = c.surface(t, 1.0 / 3.0, 1.0 / 3.0);
        assert!(n.dot(p) > 0.0, "cube triangle {t} faces inward");
    }
    assert_eq!(
        s.bsdfs.len(),
        4,
        "each shape without a bsdf gets the default diffuse"
    );
    assert!(
        matches!(&s.bsdfs[0], Bsdf::Diffuse { reflectance } if *reflectance == Vec3::splat(0.5))
    );
}

#[test]
fn bsdfs_and_named_iors() {
    let s = build(
        "bsdfs",
        r#"<shape type="sphere"><bsdf type="dielectric"/></shape>
           <shape type="sphere"><bsdf type="dielectric"><string name="int_ior" value="water"/><float name="ext_ior" value="1.0"/></bsdf></shape>
           <shape type="sphere"><bsdf type="twosided"><bsdf type="diffuse"><float name="reflectance" value="0.3"/></bsdf></bsdf></shape>
           <shape type="sphere"><bsdf type="null"/></shape>"#,
    );
    let Bsdf::Dielectric(d0) = &s.bsdfs[0] else {
        panic!()
    };
    assert!(
        (d0.eta - 1.5046 / 1.000277).abs() < 1e-6,
        "defaults bk7 / air: {}",
        d0.eta
    );
    let Bsdf::Dielectric(d1) = &s.bsdfs[1] else {
        panic!()
    };
    assert!((d1.eta - 1.333).abs() < 1e-6);
    assert!(
        matches!(&s.bsdfs[2], Bsdf::TwoSided(b) if matches!(&b[1], Bsdf::Diffuse { reflectance } if *reflectance == Vec3::splat(0.3)))
    );
    assert!(matches!(&s.bsdfs[3], Bsdf::Null));
    let e = build_err(
        "badior",
        r#"<shape type="sphere"><bsdf type="dielectric"><string name="int_ior" value="unobtainium"/></bsdf></shape>"#,
    );
    assert!(e.contains("unobtainium") && e.contains("water"), "{e}");
}

#[test]
fn emitters_and_constant_spectrum_conversion() {
    let s = build(
        "emitters",
        r#"<shape type="rectangle"><emitter type="area"><spectrum name="radiance" value="2"/></emitter></shape>
           <emitter type="point"><point name="position" x="1" y="2" z="3"/><float name="intensity" value="5"/></emitter>
           <emitter type="constant"><rgb name="radiance" value="0.1, 0.2, 0.3"/></emitter>
           <emitter type="directional"><vector name="direction" x="0" y="-2" z="0"/><spectrum name="irradiance" value="1"/></emitter>"#,
    );
    // Mitsuba 3 (RGB mode): a constant spectrum on an emitter is v · xyz_to_srgb(1, 1, 1).
    let k = Vec3::new(1.204794, 0.948291, 0.908916);
    let Emitter::Area { radiance, .. } = &s.emitters[0] else {
        panic!()
    };
    assert!(
        (*radiance - 2.0 * k).abs().max_element() < 1e-5,
        "{radiance}"
    );
    let Emitter::Point {
        position,
        intensity,
    } = &s.emitters[1]
    else {
        panic!()
    };
    assert_eq!(
        (*position, *intensity),
        (glam::Vec3A::new(1.0, 2.0, 3.0), Vec3::splat(5.0))
    );
    let Emitter::Constant { radiance } = &s.emitters[2] else {
        panic!()
    };
    assert_eq!(*radiance, Vec3::new(0.1, 0.2, 0.3));
    assert_eq!(s.environment, Some(2));
    let Emitter::Directional {
        direction,
        irradiance,
    } = &s.emitters[3]
    else {
        panic!()
    };
    assert_eq!(*direction, glam::Vec3A::NEG_Y);
    assert!((*irradiance - k).abs().max_element() < 1e-5);
    // A shape's default bsdf is black when it emits.
    assert!(
        matches!(&s.bsdfs[s.shapes[0].bsdf as usize], Bsdf::Diffuse { reflectance } if *reflectance == Vec3::ZERO)
    );
}

#[test]
fn homogeneous_medium_and_phase() {
    let s = build(
        "medium",
        r#"<medium type="homogeneous" id="a"><rgb name="albedo" value="0.9, 0.8, 0.7"/><rgb name="sigma_t" value="0.1, 0.2, 0.3"/>
               <float name="scale" value="10"/><phase type="hg"><float name="g" value="-0.3"/></phase></medium>
           <medium type="homogeneous" id="b"/>"#,
    );
    assert_eq!(s.media[0].albedo, Vec3::new(0.9, 0.8, 0.7));
    assert_eq!(
        s.media[0].sigma_t,
        Vec3::new(1.0, 2.0, 3.0),
        "sigma_t is stored times scale"
    );
    assert_eq!(s.media[0].phase, Phase::HenyeyGreenstein { g: -0.3 });
    assert_eq!(
        (s.media[1].albedo, s.media[1].sigma_t, &s.media[1].phase),
        (Vec3::splat(0.75), Vec3::ONE, &Phase::Isotropic)
    );
    for bad in [
        r#"<float name="albedo" value="1.5"/>"#,
        r#"<float name="sigma_t" value="-1"/>"#,
        r#"<float name="scale" value="0"/>"#,
        r#"<phase type="hg"><float name="g" value="1"/></phase>"#,
    ] {
        let e = build_err(
            "badmedium",
            &format!(r#"<medium type="homogeneous">{bad}</medium>"#),
        );
        assert!(e.contains("scene.xml:2:"), "{bad}: {e}");
    }
}

#[test]
fn nested_plugins_and_unreferenced_objects() {
    let e = build_err(
        "nested",
        r#"<shape type="sphere"><emitter type="point"/></shape>"#,
    );
    assert!(e.contains("area"), "{e}");
    let e = build_err(
        "extra",
        r#"<shape type="sphere"><sampler type="independent"/></shape>"#,
    );
    assert!(e.contains("unreferenced nested sampler"), "{e}");
    // A matrix with the wrong count of values.
    let e = load("matrix", r#"<shape type="sphere"><transform name="to_world"><matrix value="1 2 3"/></transform></shape>"#, &[]).unwrap_err();
    assert!(e.contains("16 (or 9) values"), "{e}");
}

/// `conductor`: material "none" (the default) is an ideal mirror (η 0, κ 1); eta and k
/// may be given; a named material table is refused with a clear message, and so is a
/// material together with eta, as in Mitsuba.
#[test]
fn conductor_parameters() {
    let shape = |bsdf: &str| format!(r#"<shape type="sphere">{bsdf}</shape>"#);
    let s = build("conductor_none", &shape(r#"<bsdf type="conductor"/>"#));
    match &s.bsdfs[0] {
        Bsdf::Conductor(c) => assert_eq!(*c, mediareg::bsdf::Conductor::ideal_mirror(Vec3::ONE)),
        b => panic!("{b:?}"),
    }
    let s = build(
        "conductor_eta_k",
        &shape(
            r#"<bsdf type="conductor"><rgb name="eta" value="0.2, 0.4, 1.4"/><float name="k" value="3"/></bsdf>"#,
        ),
    );
    match &s.bsdfs[0] {
        Bsdf::Conductor(c) => {
            assert_eq!(c.eta, Vec3::new(0.2, 0.4, 1.4));
            assert_eq!(c.k, Vec3::splat(3.0));
        }
        b => panic!("{b:?}"),
    }
    // Named materials (tests/drop_in_rest.rs checks their values); an unknown one is
    // refused with the list.
    let e = build_err(
        "conductor_gold",
        &shape(r#"<bsdf type="conductor"><string name="material" value="Gold"/></bsdf>"#),
    );
    assert!(e.contains("\"Gold\"") && e.contains("Au, Be"), "{e}");
    let e = build_err(
        "conductor_both",
        &shape(
            r#"<bsdf type="conductor"><string name="material" value="Au"/><float name="eta" value="1"/></bsdf>"#,
        ),
    );
    assert!(e.contains("not both"), "{e}");
}

/// `envmap`: the image must exist and be an image format Mitsuba reads, `to_world` a
/// rotation, and only one environment emitter may be given; each refusal says so.
#[test]
fn envmap_errors() {
    let dir = common::root().join("mitsuba_scenes/textures");
    let env = |extra: &str, file: &str| {
        format!(
            r#"<emitter type="envmap"><string name="filename" value="{}"/>{extra}</emitter>"#,
            dir.join(file).display()
        )
    };
    let e = build_err("envmap_missing", &env("", "no_such_sky.exr"));
    assert!(
        e.contains("no_such_sky.exr") && e.contains("not found"),
        "{e}"
    );
    let e = build_err("envmap_text", &env("", "../../README.md"));
    assert!(
        e.contains("README.md") && e.contains("not an image format"),
        "{e}"
    );
    let e = build_err(
        "envmap_scaled",
        &env(
            r#"<transform name="to_world"><scale value="2"/></transform>"#,
            "sky.exr",
        ),
    );
    assert!(e.contains("must be a rotation"), "{e}");
    let e = build_err(
        "envmap_two",
        &format!(r#"{}<emitter type="constant"/>"#, env("", "sky.exr")),
    );
    assert!(e.contains("only one environment emitter"), "{e}");
    let s = build(
        "envmap_ok",
        &env(r#"<float name="scale" value="2"/>"#, "sky.exr"),
    );
    assert!(s.environment.is_some());
}

/// Textures and `moment`: a checkerboard on a shape without texture coordinates here,
/// an unknown texture plugin, a bitmap without a file and a `moment` with two nested
/// integrators are refused clearly; `moment` around one integrator is that integrator, with a warning.
#[test]
fn textures_and_moment() {
    let checks = r#"<texture type="checkerboard" name="reflectance"/>"#;
    let e = build_err(
        "texture_sphere",
        &format!(r#"<shape type="sphere"><bsdf type="diffuse">{checks}</bsdf></shape>"#),
    );
    assert!(e.contains("textured bsdf on a \"sphere\""), "{e}");
    let e = build_err(
        "texture_unknown",
        r#"<shape type="rectangle"><bsdf type="diffuse"><texture type="mesh_attribute" name="reflectance"/></bsdf></shape>"#,
    );
    assert!(
        e.contains("unsupported texture plugin \"mesh_attribute\"") && e.contains("bitmap"),
        "{e}"
    );
    let e = build_err(
        "texture_bitmap",
        r#"<shape type="rectangle"><bsdf type="diffuse"><texture type="bitmap" name="reflectance"/></bsdf></shape>"#,
    );
    assert!(e.contains("bitmap needs a filename"), "{e}");
    let e = build_err(
        "moment_two",
        r#"<integrator type="moment"><integrator type="path"/><integrator type="volpath"/></integrator>"#,
    );
    assert!(e.contains("moment with 2 nested integrators"), "{e}");
    let s = build(
        "moment_one",
        r#"<integrator type="moment"><integrator type="volpath"><integer name="max_depth" value="7"/></integrator></integrator>"#,
    );
    assert_eq!(s.integrator.kind, IntegratorKind::Volpath);
    assert_eq!(s.integrator.max_depth, 7);
    assert!(s.warnings.iter().any(|w| w.contains("moment")));
}
