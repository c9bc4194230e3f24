//! Plugins and readings that published scene files need (issue 30, part A): `bitmap`
//! in every image format Mitsuba 3 reads, the `rayleigh` phase function, `homogeneous`
//! media with nested `constvolume`s, 0.6 medium `material` presets and 0.5's
//! three-value `<spectrum>`.
//!
//! Renders against Mitsuba 3 follow tests/volpath_equivalence.rs (independent chunks,
//! per-pixel z-scores, a false-alarm probability of 1e-6), each with a power test that
//! the same comparison fails on a small change.

mod common;

use std::path::Path;

use common::scene_text::{load_or_build_error, load_text, tmp_dir, SENSOR};
use common::{check_against_reference, root};
use glam::Vec3;
use mediareg::texture::bitmap_file::read_texels;

const CHUNKS: usize = 16;
const SPP: u32 = 128;

// ---------------------------------------------------------------------------------
// bitmap: image formats
// ---------------------------------------------------------------------------------

/// A small 8-bit RGB test image with every kind of value (dark, mid, bright, 0, 255).
fn test_rgb8() -> (u32, u32, Vec<u8>) {
    let (w, h) = (7u32, 5u32);
    let data = (0..w * h * 3)
        .map(|i| ((i * 37 + (i / 3) * 11) % 256) as u8)
        .collect::<Vec<u8>>();
    (w, h, data)
}

fn write_png(
    path: &Path,
    w: u32,
    h: u32,
    color: png::ColorType,
    depth: png::BitDepth,
    data: &[u8],
    palette: Option<&[u8]>,
) {
    let f = std::fs::File::create(path).unwrap();
    let mut e = png::Encoder::new(std::io::BufWriter::new(f), w, h);
    e.set_color(color);
    e.set_depth(depth);
    if let Some(p) = palette {
        e.set_palette(p.to_vec());
    }
    e.write_header().unwrap().write_image_data(data).unwrap();
}

fn texels(path: &Path, raw: bool) -> (usize, usize, Vec<Vec3>) {
    read_texels(path, raw).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn assert_same(what: &str, a: &(usize, usize, Vec<Vec3>), b: &(usize, usize, Vec<Vec3>)) {
    assert_eq!((a.0, a.1), (b.0, b.1), "{what}: size");
    for (i, (x, y)) in a.2.iter().zip(&b.2).enumerate() {
        assert_eq!(x, y, "{what}: texel {i} differs");
    }
}

/// The TGA v2 footer, without which Mitsuba 3 does not recognise a TGA.
fn tga_footer(bytes: &mut Vec<u8>) {
    bytes.extend_from_slice(&[0; 8]);
    bytes.extend_from_slice(b"TRUEVISION-XFILE.\0");
}

/// BMP (24-bit), TGA (RGB and grey, plain and RLE, with the footer), PPM (P6) and PNG
/// in palette, grey, grey+alpha, RGBA and 16-bit form decode to exactly the texels of
/// the plain 8-bit PNG of the same image, sRGB-decoded and `raw`.
#[test]
fn integer_formats_decode_to_the_png_texels() {
    use image::{ColorType, ImageEncoder};
    let dir = tmp_dir("drop_in", "formats");
    let (w, h, rgb) = test_rgb8();
    let png = dir.join("ref.png");
    write_png(
        &png,
        w,
        h,
        png::ColorType::Rgb,
        png::BitDepth::Eight,
        &rgb,
        None,
    );

    let bmp = dir.join("a.bmp");
    image::save_buffer(&bmp, &rgb, w, h, ColorType::Rgb8).unwrap();
    let ppm = dir.join("a.ppm");
    let mut buf = Vec::new();
    image::codecs::pnm::PnmEncoder::new(&mut buf)
        .with_subtype(image::codecs::pnm::PnmSubtype::Pixmap(
            image::codecs::pnm::SampleEncoding::Binary,
        ))
        .write_image(&rgb, w, h, ColorType::Rgb8)
        .unwrap();
    std::fs::write(&ppm, &buf).unwrap();
    let tga = dir.join("a.tga");
    let mut buf = Vec::new();
    image::codecs::tga::TgaEncoder::new(&mut buf)
        .write_image(&rgb, w, h, ColorType::Rgb8)
        .unwrap();
    tga_footer(&mut buf);
    std::fs::write(&tga, &buf).unwrap();
    // The same TGA without its footer is not a format Mitsuba 3 recognises.
    let tga_bare = dir.join("bare.tga");
    std::fs::write(&tga_bare, &buf[..buf.len() - 26]).unwrap();
    let e = read_texels(&tga_bare, false).unwrap_err();
    assert!(e.contains("not an image format Mitsuba 3 reads"), "{e}");

    // RGBA PNG (alpha dropped) and 16-bit PNG (v · 257).
    let rgba: Vec<u8> = rgb
        .chunks(3)
        .flat_map(|c| [c[0], c[1], c[2], 100])
        .collect();
    let png_rgba = dir.join("rgba.png");
    write_png(
        &png_rgba,
        w,
        h,
        png::ColorType::Rgba,
        png::BitDepth::Eight,
        &rgba,
        None,
    );
    let rgb16: Vec<u8> = rgb
        .iter()
        .flat_map(|&v| (v as u16 * 257).to_be_bytes())
        .collect();
    let png16 = dir.join("rgb16.png");
    write_png(
        &png16,
        w,
        h,
        png::ColorType::Rgb,
        png::BitDepth::Sixteen,
        &rgb16,
        None,
    );
    // Palette PNG: each pixel its own palette entry.
    let n = (w * h) as usize;
    let indexed: Vec<u8> = (0..n as u8).collect();
    let png_pal = dir.join("pal.png");
    write_png(
        &png_pal,
        w,
        h,
        png::ColorType::Indexed,
        png::BitDepth::Eight,
        &indexed,
        Some(&rgb),
    );

    for raw in [false, true] {
        let want = texels(&png, raw);
        for f in [&bmp, &ppm, &tga, &png_rgba, &png16, &png_pal] {
            assert_same(
                &format!("{} raw={raw}", f.display()),
                &texels(f, raw),
                &want,
            );
        }
    }

    // Grey: a grey PNG, grey+alpha PNG and grey TGA (RLE) are grey in every channel.
    let grey: Vec<u8> = rgb.iter().step_by(3).copied().collect();
    let png_grey = dir.join("grey.png");
    write_png(
        &png_grey,
        w,
        h,
        png::ColorType::Grayscale,
        png::BitDepth::Eight,
        &grey,
        None,
    );
    let ga: Vec<u8> = grey.iter().flat_map(|&g| [g, 7]).collect();
    let png_ga = dir.join("ga.png");
    write_png(
        &png_ga,
        w,
        h,
        png::ColorType::GrayscaleAlpha,
        png::BitDepth::Eight,
        &ga,
        None,
    );
    // A run-length-encoded grey TGA, written by hand (type 11, 8 bits, top-left origin):
    // raw packets of one pixel each.
    let mut t = vec![0u8, 0, 11, 0, 0, 0, 0, 0, 0, 0, 0, 0];
    t.extend_from_slice(&(w as u16).to_le_bytes());
    t.extend_from_slice(&(h as u16).to_le_bytes());
    t.extend_from_slice(&[8, 0x20]);
    for &g in &grey {
        t.extend_from_slice(&[0, g]);
    }
    tga_footer(&mut t);
    let tga_grey = dir.join("grey.tga");
    std::fs::write(&tga_grey, &t).unwrap();
    for raw in [false, true] {
        let want = texels(&png_grey, raw);
        assert!(want.2.iter().all(|t| t.x == t.y && t.y == t.z));
        assert_eq!(want.2[1].x, texels(&png, raw).2[1].x);
        for f in [&png_ga, &tga_grey] {
            assert_same(
                &format!("{} raw={raw}", f.display()),
                &texels(f, raw),
                &want,
            );
        }
    }
}

/// RGBE (.hdr) and PFM (RGB and grey) decode to exactly the texels of an OpenEXR of the
/// same float image: linear, never sRGB-decoded, PFM rows bottom-up. The values are
/// m/256 with each pixel's largest component in [½, 1), which RGBE stores exactly.
#[test]
fn float_formats_decode_to_the_exr_texels() {
    let dir = tmp_dir("drop_in", "float_formats");
    let (w, h) = (6usize, 4usize);
    let px: Vec<[f32; 3]> = (0..w * h)
        .map(|i| {
            let m = |k: usize| ((i * 29 + k * 53) % 128) as f32 / 256.0;
            [0.5 + m(0), m(1), m(2)]
        })
        .collect();
    let exr = dir.join("ref.exr");
    let img = mediareg::image::Image {
        width: w,
        height: h,
        pixels: px.clone(),
    };
    mediareg::image::write_exr(&exr, &img).unwrap();

    let hdr = dir.join("a.hdr");
    let pixels: Vec<image::Rgb<f32>> = px.iter().map(|p| image::Rgb(*p)).collect();
    image::codecs::hdr::HdrEncoder::new(std::fs::File::create(&hdr).unwrap())
        .encode(&pixels, w, h)
        .unwrap();

    // PFM, little-endian (negative scale), bottom row first.
    let pfm = dir.join("a.pfm");
    let mut f = format!("PF\n{w} {h}\n-1.0\n").into_bytes();
    for y in (0..h).rev() {
        for x in 0..w {
            for c in px[y * w + x] {
                f.extend(c.to_le_bytes());
            }
        }
    }
    std::fs::write(&pfm, &f).unwrap();
    let want = texels(&exr, false);
    for raw in [false, true] {
        for p in [&hdr, &pfm] {
            assert_same(
                &format!("{} raw={raw}", p.display()),
                &texels(p, raw),
                &want,
            );
        }
    }

    // Grey PFM, big-endian with scale 2: every value doubled, in all three channels.
    let pfm_grey = dir.join("grey.pfm");
    let mut f = format!("Pf\n{w} {h}\n2\n").into_bytes();
    for y in (0..h).rev() {
        for x in 0..w {
            f.extend(px[y * w + x][1].to_be_bytes());
        }
    }
    std::fs::write(&pfm_grey, &f).unwrap();
    let g = texels(&pfm_grey, false);
    for (t, p) in g.2.iter().zip(&px) {
        assert_eq!(*t, Vec3::splat(2.0 * p[1]));
    }
}

/// The JPEG of bitmap_jpeg.xml (4:2:0 chroma, written by libjpeg) decodes to the texels
/// Mitsuba 3 decodes it to (libjpeg's), stored losslessly as
/// tests/fixtures/tiles_jpg_decoded_by_mitsuba.png (`scripts/mitsuba_fixtures.py jpeg`
/// writes it): the decoders' IDCTs and chroma upsampling are libjpeg-turbo's on both
/// sides, so every byte is the same.
#[test]
fn jpeg_decodes_as_mitsuba() {
    let jpg = root().join("mitsuba_scenes/textures/tiles.jpg");
    let fixture = root().join("tests/fixtures/tiles_jpg_decoded_by_mitsuba.png");
    assert_same(
        "JPEG against Mitsuba's decode",
        &texels(&jpg, true),
        &texels(&fixture, true),
    );
}

fn bitmap_scene(file: &str) -> String {
    format!(
        r#"<scene version="3.0.0">{SENSOR}
    <shape type="rectangle">
        <bsdf type="diffuse">
            <texture type="bitmap" name="reflectance">
                <string name="filename" value="{file}"/>
            </texture>
        </bsdf>
    </shape>
</scene>"#
    )
}

/// A corrupt JPEG, an unknown format and an 8-bit BMP are errors naming the scene's
/// file and the line of the filename, and what to do.
#[test]
fn unreadable_bitmaps_are_refused_with_file_and_line() {
    let dir = tmp_dir("drop_in", "bad_bitmaps");
    std::fs::write(
        dir.join("broken.jpg"),
        [0xFF, 0xD8, 0xFF, 0xE0, 0, 16, b'J', b'F'],
    )
    .unwrap();
    std::fs::write(dir.join("notes.png"), b"just some text").unwrap();
    // An 8-bit (palette) BMP: Mitsuba 3 would read the indices as grey levels.
    let mut bmp = Vec::new();
    image::codecs::bmp::BmpEncoder::new(&mut bmp)
        .encode(&[10, 20, 30, 40], 2, 2, image::ColorType::L8)
        .unwrap();
    std::fs::write(dir.join("grey8.bmp"), &bmp).unwrap();
    for (file, needle) in [
        ("broken.jpg", "corrupt JPEG data"),
        ("notes.png", "not an image format Mitsuba 3 reads"),
        ("grey8.bmp", "8-bit BMP"),
    ] {
        let path = dir.join(file);
        let text = bitmap_scene(&path.display().to_string());
        let e = load_or_build_error(
            file,
            load_text("drop_in", &format!("bad_{file}"), &text, &[]),
        );
        assert!(e.contains("scene.xml:6:"), "{file}: no file:line in\n{e}");
        assert!(e.contains(needle), "{file}: {needle:?} not in\n{e}");
    }
}

/// bitmap_jpeg.xml (a JPEG texture, bilinear, repeated) against Mitsuba 3.
#[test]
fn bitmap_jpeg_matches_mitsuba() {
    let c = check_against_reference("bitmap_jpeg", "bitmap_jpeg", &[], CHUNKS, SPP, 31);
    assert!(c.passed, "{c}");
}

/// The same comparison fails when the texture is moved by a quarter texel along u.
#[test]
fn bitmap_jpeg_comparison_detects_a_quarter_texel_shift() {
    let du = format!("{}", 0.25 / 48.0);
    let c = check_against_reference(
        "bitmap_jpeg",
        "bitmap_jpeg",
        &[("du", &du)],
        CHUNKS,
        SPP,
        32,
    );
    assert!(!c.passed, "a quarter-texel shift went unnoticed: {c}");
}

// ---------------------------------------------------------------------------------
// phase rayleigh
// ---------------------------------------------------------------------------------

/// rayleigh.xml (a medium cube lit from the side, `rayleigh` phase) against Mitsuba 3.
#[test]
fn rayleigh_matches_mitsuba() {
    let c = check_against_reference("rayleigh", "rayleigh", &[], CHUNKS, SPP, 41);
    assert!(c.passed, "{c}");
}

/// The same comparison tells Rayleigh from isotropic scattering (same mean cosine 0).
#[test]
fn rayleigh_comparison_detects_isotropic() {
    let c = check_against_reference(
        "rayleigh",
        "rayleigh",
        &[("phase", "isotropic")],
        CHUNKS,
        SPP,
        42,
    );
    assert!(!c.passed, "isotropic scattering went unnoticed: {c}");
}

// ---------------------------------------------------------------------------------
// homogeneous media with nested constvolumes
// ---------------------------------------------------------------------------------

/// A small medium scene (a cube of `medium` behind a null boundary, an area light) in
/// format `version`, rendered once at a fixed seed.
fn medium_scene(version: &str, medium: &str) -> String {
    format!(
        r#"<scene version="{version}">
    <integrator type="volpath"/>
    <sensor type="perspective"><float name="fov" value="40"/>
        <transform name="to_world"><lookat origin="2, 1.5, 3" target="0, 0, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="8"/></sampler>
        <film type="hdrfilm"><integer name="width" value="24"/><integer name="height" value="16"/></film>
    </sensor>
    {medium}
    <shape type="cube">
        <transform name="to_world"><scale value="0.5"/></transform>
        <bsdf type="null"/>
        <ref name="interior" id="m"/>
    </shape>
    <shape type="sphere">
        <point name="center" x="-1" y="1.5" z="0.5"/><float name="radius" value="0.3"/>
        <emitter type="area"><rgb name="radiance" value="10, 9, 8"/></emitter>
    </shape>
</scene>"#
    )
}

fn render_text(tag: &str, text: &str, params: &[(&str, &str)]) -> Vec<[f32; 3]> {
    let desc = load_text("drop_in", tag, text, params).unwrap_or_else(|e| panic!("{tag}: {e}"));
    let s = common::scene_text::build_desc(tag, &desc);
    mediareg::integrator::render(&s, &s.shot, &Default::default())
        .image
        .pixels
}

/// albedo and sigma_t as nested `constvolume`s (an rgb above 1 is fine there: Mitsuba 3
/// reads `value` as an unbounded texture) render bit for bit as the same constants
/// given as plain properties.
#[test]
fn constvolume_renders_as_plain_properties() {
    let nested = medium_scene(
        "3.0.0",
        r#"<medium type="homogeneous" id="m">
        <volume type="constvolume" name="albedo"><spectrum name="value" value="0.9"/></volume>
        <volume type="constvolume" name="sigma_t">
            <rgb name="value" value="4, 2, 1"/>
            <transform name="to_world"><scale value="2"/></transform>
        </volume>
        <phase type="rayleigh"/>
    </medium>"#,
    );
    let plain = medium_scene(
        "3.0.0",
        r#"<medium type="homogeneous" id="m">
        <float name="albedo" value="0.9"/>
        <rgb name="sigma_t" value="0.5, 0.25, 0.125"/>
        <float name="scale" value="8"/>
        <phase type="rayleigh"/>
    </medium>"#,
    );
    let (a, b) = (
        render_text("cv_nested", &nested, &[]),
        render_text("cv_plain", &plain, &[]),
    );
    assert!(a.iter().flatten().any(|v| *v > 0.0), "black image");
    assert_eq!(a, b, "nested constvolume and plain properties differ");
    // The default value of a constvolume is 1.
    let default = medium_scene(
        "3.0.0",
        r#"<medium type="homogeneous" id="m"><volume type="constvolume" name="sigma_t"/></medium>"#,
    );
    let one = medium_scene(
        "3.0.0",
        r#"<medium type="homogeneous" id="m"><float name="sigma_t" value="1"/></medium>"#,
    );
    assert_eq!(
        render_text("cv_default", &default, &[]),
        render_text("cv_one", &one, &[])
    );
}

/// A grid volume (heterogeneous) is refused at its line, with what to do.
#[test]
fn gridvolume_is_refused() {
    let text = medium_scene(
        "3.0.0",
        r#"<medium type="homogeneous" id="m">
        <volume type="gridvolume" name="sigma_t"><string name="filename" value="smoke.vol"/></volume>
    </medium>"#,
    );
    let e = load_or_build_error("grid", load_text("drop_in", "grid", &text, &[]));
    assert!(e.contains("scene.xml:9:"), "no file:line in\n{e}");
    assert!(
        e.contains("gridvolume") && e.contains("heterogeneous"),
        "{e}"
    );
}

// ---------------------------------------------------------------------------------
// 0.6 medium material presets
// ---------------------------------------------------------------------------------

fn load_v06(
    tag: &str,
    text: &str,
    strict: bool,
) -> Result<mediareg::xml::SceneDescription, String> {
    let path = common::scene_text::write(&tmp_dir("drop_in", tag), "scene.xml", text);
    let opts = mediareg::xml::LoadOptions {
        strict_v3: strict,
        ..Default::default()
    };
    mediareg::xml::load_file(&path, &opts).map_err(|e| e.to_string())
}

fn render_desc(tag: &str, desc: &mediareg::xml::SceneDescription) -> Vec<[f32; 3]> {
    let s = common::scene_text::build_desc(tag, desc);
    mediareg::integrator::render(&s, &s.shot, &Default::default())
        .image
        .pixels
}

/// A 0.6 file with `material="Regular Milk"` and a `scale` renders bit for bit as the
/// same file with the coefficients 0.6 used written out: Narasimhan et al. 2006's
/// σ_s = (18.2052, 20.3826, 22.3698), σ_a = (0.00153, 0.00460, 0.01993) mm⁻¹ and
/// g = (0.750, 0.714, 0.681), × 100, σ_s reduced by (1 − g); one warning line, which
/// names the preset. A preset name in another case is the same preset, as in 0.6.
#[test]
fn v06_material_preset_renders_as_its_coefficients() {
    let medium = |inner: &str| {
        format!(
            r#"<medium type="homogeneous" id="m">{inner}<float name="scale" value="0.002"/><phase type="isotropic"/></medium>"#
        )
    };
    let preset = medium_scene(
        "0.6.0",
        &medium(r#"<string name="material" value="regular milk"/>"#),
    );
    let (s, a, g) = (
        [18.2052f64, 20.3826, 22.3698],
        [0.00153f64, 0.00460, 0.01993],
        [0.75f64, 0.714, 0.681],
    );
    let s: Vec<String> = (0..3)
        .map(|i| format!("{:?}", s[i] * 100.0 * (1.0 - g[i])))
        .collect();
    let a: Vec<String> = (0..3).map(|i| format!("{:?}", a[i] * 100.0)).collect();
    let explicit = medium_scene(
        "0.6.0",
        &medium(&format!(
            r#"<rgb name="sigmaS" value="{}"/><rgb name="sigmaA" value="{}"/>"#,
            s.join(", "),
            a.join(", ")
        )),
    );
    let (dp, de) = (
        load_v06("preset", &preset, false).unwrap(),
        load_v06("explicit", &explicit, false).unwrap(),
    );
    let notes: Vec<&String> = dp.notes.iter().filter(|n| n.contains("0.6 file")).collect();
    assert_eq!(notes.len(), 1, "{notes:?}");
    assert!(
        notes[0].contains("material \"Regular Milk\""),
        "{}",
        notes[0]
    );
    println!("{}", notes[0]);
    let (ip, ie) = (render_desc("preset", &dp), render_desc("explicit", &de));
    assert!(ip.iter().flatten().any(|v| *v > 0.0), "black image");
    assert_eq!(ip, ie, "the preset and its coefficients render differently");
}

/// `--strict-v3` refuses the preset (Mitsuba 3 does not read it); an unknown name lists
/// the presets; a preset with explicit coefficients is refused, as by 0.6.
#[test]
fn v06_material_preset_refusals() {
    let scene = |inner: &str| {
        medium_scene(
            "0.6.0",
            &format!(
                r#"<medium type="homogeneous" id="m">
        {inner}
    </medium>"#
            ),
        )
    };
    let e = load_v06(
        "strict",
        &scene(r#"<string name="material" value="Ketchup"/>"#),
        true,
    )
    .unwrap_err();
    assert!(
        e.contains("scene.xml:8:") && e.contains("strict-v3") && e.contains("Ketchup"),
        "{e}"
    );
    let e = load_v06(
        "unknown",
        &scene(r#"<string name="material" value="Gravy"/>"#),
        false,
    )
    .unwrap_err();
    assert!(e.contains("scene.xml:9:") && e.contains("\"Gravy\""), "{e}");
    assert!(
        e.contains("Regular Milk") && e.contains("Pacific Ocean Surface Water"),
        "{e}"
    );
    let e = load_v06(
        "both",
        &scene(r#"<string name="material" value="Skin1"/><float name="sigmaT" value="2"/>"#),
        false,
    )
    .unwrap_err();
    assert!(e.contains("scene.xml:9:") && e.contains("not both"), "{e}");
}

// ---------------------------------------------------------------------------------
// 0.5 three-value spectra
// ---------------------------------------------------------------------------------

/// In a 0.5 file `<spectrum value="r, g, b"/>` is RGB (0.5's RGB mode): it renders bit
/// for bit as `<rgb>`, with one warning line per such spectrum; `--strict-v3` refuses it
/// at its line, and a 3.0 file still does not accept it.
#[test]
fn v05_three_value_spectrum_is_rgb() {
    let medium = |tag: &str| {
        format!(
            r#"<medium type="homogeneous" id="m">
        <{tag} name="sigmaS" value="0.5, 1.0, 1.5"/>
        <{tag} name="sigmaA" value="0.25, 0.125, 0"/>
    </medium>"#
        )
    };
    let spectra = medium_scene("0.5.0", &medium("spectrum"));
    let rgb = medium_scene("0.5.0", &medium("rgb"));
    let (ds, dr) = (
        load_v06("v05_spectrum", &spectra, false).unwrap(),
        load_v06("v05_rgb", &rgb, false).unwrap(),
    );
    let notes: Vec<&String> = ds.notes.iter().filter(|n| n.contains("0.5 file")).collect();
    assert_eq!(notes.len(), 2, "{notes:?}");
    assert!(
        notes[0].contains("scene.xml:9:") && notes[0].contains("<rgb value=\"0.5, 1, 1.5\">"),
        "{}",
        notes[0]
    );
    println!("{}", notes[0]);
    assert!(!dr.notes.iter().any(|n| n.contains("0.5 file")));
    let (a, b) = (
        render_desc("v05_spectrum", &ds),
        render_desc("v05_rgb", &dr),
    );
    assert!(a.iter().flatten().any(|v| *v > 0.0), "black image");
    assert_eq!(a, b, "<spectrum r, g, b> and <rgb> render differently");

    let e = load_v06("v05_strict", &spectra, true).unwrap_err();
    assert!(e.contains("scene.xml:9:") && e.contains("strict-v3"), "{e}");
    let v3 = medium_scene(
        "3.0.0",
        r#"<medium type="homogeneous" id="m"><spectrum name="albedo" value="0.5, 0.6, 0.7"/></medium>"#,
    );
    let e = load_v06("v3_triplet", &v3, false).unwrap_err();
    assert!(e.contains("could not parse spectrum value"), "{e}");
}

/// Damaged image files (bytes overwritten, or cut short) are read or refused with an
/// error, never a panic or an abort: 300 deterministic mutations of the JPEG and of the
/// PNG, BMP, TGA, PFM and RGBE forms of a small image.
#[test]
fn damaged_images_never_panic() {
    use image::ImageEncoder;
    let dir = tmp_dir("drop_in", "damaged");
    let (w, h, rgb) = test_rgb8();
    let mut files: Vec<Vec<u8>> =
        vec![std::fs::read(root().join("mitsuba_scenes/textures/tiles.jpg")).unwrap()];
    let mut bmp = Vec::new();
    image::codecs::bmp::BmpEncoder::new(&mut bmp)
        .encode(&rgb, w, h, image::ColorType::Rgb8)
        .unwrap();
    files.push(bmp);
    let mut tga = Vec::new();
    image::codecs::tga::TgaEncoder::new(&mut tga)
        .write_image(&rgb, w, h, image::ColorType::Rgb8)
        .unwrap();
    tga_footer(&mut tga);
    files.push(tga);
    let png = dir.join("ref.png");
    write_png(
        &png,
        w,
        h,
        png::ColorType::Rgb,
        png::BitDepth::Eight,
        &rgb,
        None,
    );
    files.push(std::fs::read(&png).unwrap());
    let mut pfm = format!("PF\n{w} {h}\n-1\n").into_bytes();
    pfm.extend(rgb.iter().flat_map(|&v| (v as f32 / 255.0).to_le_bytes()));
    files.push(pfm);
    let mut hdr = Vec::new();
    let px: Vec<image::Rgb<f32>> = rgb
        .chunks(3)
        .map(|c| image::Rgb([c[0] as f32, c[1] as f32, c[2] as f32]))
        .collect();
    image::codecs::hdr::HdrEncoder::new(&mut hdr)
        .encode(&px, w as usize, h as usize)
        .unwrap();
    files.push(hdr);

    let mut state = 0x853c_49e6_748f_ea9bu64;
    let mut next = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 33) as usize
    };
    let path = dir.join("damaged.img");
    let (mut read, mut refused) = (0, 0);
    for case in 0..300 {
        let mut b = files[case % files.len()].clone();
        if case % 3 == 0 {
            b.truncate(next() % b.len());
        } else {
            // Keep the first two bytes (the format's magic), damage the rest.
            for _ in 0..1 + next() % 8 {
                let i = 2 + next() % (b.len() - 2);
                b[i] = next() as u8;
            }
        }
        std::fs::write(&path, &b).unwrap();
        match read_texels(&path, false) {
            Ok((w, h, t)) => {
                assert_eq!(t.len(), w * h, "case {case}");
                read += 1;
            }
            Err(e) => {
                assert!(e.contains("damaged.img"), "case {case}: {e}");
                refused += 1;
            }
        }
    }
    println!("damaged images: {read} read, {refused} refused");
}

/// `envmap` reads the same formats as `bitmap`: the sky of envmap.xml written as a PFM
/// (the same f32 values) lights a scene bit for bit as the OpenEXR does.
#[test]
fn envmap_from_pfm_renders_as_from_exr() {
    let exr = root().join("mitsuba_scenes/textures/sky.exr");
    let sky = mediareg::image::read_exr(&exr).unwrap();
    let dir = tmp_dir("drop_in", "envmap_pfm");
    let pfm = dir.join("sky.pfm");
    let mut f = format!("PF\n{} {}\n-1\n", sky.width, sky.height).into_bytes();
    for y in (0..sky.height).rev() {
        for p in &sky.pixels[y * sky.width..(y + 1) * sky.width] {
            f.extend(p.iter().flat_map(|c| c.to_le_bytes()));
        }
    }
    std::fs::write(&pfm, &f).unwrap();
    let scene = |file: &Path| {
        format!(
            r#"<scene version="3.0.0">{SENSOR}
    <shape type="sphere"><point name="center" x="0" y="0" z="4"/><bsdf type="diffuse"/></shape>
    <emitter type="envmap"><string name="filename" value="{}"/></emitter>
</scene>"#,
            file.display()
        )
    };
    let a = render_text("env_exr", &scene(&exr), &[]);
    let b = render_text("env_pfm", &scene(&pfm), &[]);
    assert!(a.iter().flatten().any(|v| *v > 0.0), "black image");
    assert_eq!(a, b);
}
