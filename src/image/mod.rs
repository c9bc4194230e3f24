//! Images: [`Image`] (what a render produces) and its files, linear float32 RGB EXR
//! (row 0 at the top, as Mitsuba writes them) and a tonemapped sRGB PNG preview. Files are written to a temporary name and renamed, so an
//! interrupted run never leaves a corrupt image.

pub mod component_format;
pub mod merge;
pub mod stats;

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use component_format::{dequantize_uint32, quantize_uint32, ComponentFormat};

/// A rendered image: the crop window, row-major linear RGB.
#[derive(Clone, Debug)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<[f32; 3]>,
}

fn temp_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp{}", std::process::id()))
}

fn commit(tmp: &Path, path: &Path) -> Result<()> {
    std::fs::rename(tmp, path)
        .with_context(|| format!("cannot move {} to {}", tmp.display(), path.display()))
}

/// Fails now, before a long render, if `path` cannot be written: creates and removes
/// the temporary file that writing it will use.
pub fn check_writable(path: &Path) -> Result<()> {
    let tmp = temp_path(path);
    std::fs::File::create(&tmp)
        .with_context(|| format!("cannot write the output {}", path.display()))?;
    let _ = std::fs::remove_file(&tmp);
    Ok(())
}

/// Writes a linear RGB float32 EXR.
pub fn write_exr(path: &Path, img: &Image) -> Result<()> {
    write_exr_with(path, img, &[])
}

/// Writes a linear RGB float32 EXR with integer attributes in its header (e.g. the spp
/// a render reached). With more than one, the file's bytes vary between runs (exr keeps
/// them in a HashMap).
pub fn write_exr_with(path: &Path, img: &Image, attributes: &[(&str, i32)]) -> Result<()> {
    use exr::prelude::*;
    if img.pixels.iter().any(|p| p.iter().any(|c| !c.is_finite())) {
        bail!(
            "refusing to write {}: the image contains NaN or Inf",
            path.display()
        );
    }
    let tmp = temp_path(path);
    let w = img.width;
    let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
        let p = img.pixels[y * w + x];
        (p[0], p[1], p[2])
    });
    // Chunks in increasing order: with the default (unspecified) order the file's bytes
    // depend on which compression thread finished first.
    let encoding = Encoding {
        line_order: LineOrder::Increasing,
        ..Encoding::FAST_LOSSLESS
    };
    let mut image =
        exr::image::Image::from_encoded_channels((img.width, img.height), encoding, channels);
    for (name, value) in attributes {
        image
            .attributes
            .other
            .insert(Text::from(*name), AttributeValue::I32(*value));
    }
    if let Err(e) = image.write().to_file(&tmp) {
        let _ = std::fs::remove_file(&tmp);
        bail!("cannot write {}: {e}", path.display());
    }
    commit(&tmp, path)
}

/// Writes a render's EXR: [`write_exr_with`] with the samples per pixel it holds in
/// the header's `spp` (what `merge` weights it by); `None` writes no attribute. The
/// CLI and the Python module write every render through this, so equal images give
/// equal files. One attribute only: exr keeps them in a HashMap, whose order (and so
/// the file's bytes) would change from run to run.
pub fn write_render_exr(path: &Path, img: &Image, spp: Option<u64>) -> Result<()> {
    match spp {
        Some(n) => write_exr_with(path, img, &[("spp", i32::try_from(n).unwrap_or(i32::MAX))]),
        None => write_exr(path, img),
    }
}

/// Writes named float32 channels of a `width` × `height` image (e.g. `Y`, or `Y` and `A`,
/// or `R`, `G`, `B`, `A`: a film whose pixel format is not RGB), with the spp as
/// [`write_render_exr`] writes it.
pub fn write_channels_exr(
    path: &Path,
    size: (usize, usize),
    channels: Vec<(&str, Vec<f32>)>,
    spp: Option<u64>,
) -> Result<()> {
    write_channels_exr_as(path, size, channels, spp, ComponentFormat::Float32)
}

/// [`write_channels_exr`] with the film's `component_format`: float32 samples, or for
/// `uint32` unsigned 32-bit ones quantized as Mitsuba 3 writes them
/// ([`quantize_uint32`]); [`read_exr`] reads those back normalized, as Mitsuba does.
pub fn write_channels_exr_as(
    path: &Path,
    (width, height): (usize, usize),
    channels: Vec<(&str, Vec<f32>)>,
    spp: Option<u64>,
    format: ComponentFormat,
) -> Result<()> {
    use exr::prelude::*;
    if channels
        .iter()
        .any(|(_, v)| v.iter().any(|c| !c.is_finite()))
    {
        bail!(
            "refusing to write {}: the image contains NaN or Inf",
            path.display()
        );
    }
    let list = channels
        .into_iter()
        .map(|(name, v)| {
            let samples = match format {
                ComponentFormat::Uint32 => {
                    FlatSamples::U32(v.into_iter().map(quantize_uint32).collect())
                }
                ComponentFormat::Float16 | ComponentFormat::Float32 => FlatSamples::F32(v),
            };
            AnyChannel::new(name, samples)
        })
        .collect();
    let encoding = Encoding {
        line_order: LineOrder::Increasing,
        ..Encoding::FAST_LOSSLESS
    };
    let layer = Layer::new(
        (width, height),
        LayerAttributes::default(),
        encoding,
        AnyChannels::sort(list),
    );
    let mut image = exr::image::Image::from_layer(layer);
    if let Some(n) = spp {
        let n = AttributeValue::I32(i32::try_from(n).unwrap_or(i32::MAX));
        image.attributes.other.insert(Text::from("spp"), n);
    }
    let tmp = temp_path(path);
    if let Err(e) = image.write().to_file(&tmp) {
        let _ = std::fs::remove_file(&tmp);
        bail!("cannot write {}: {e}", path.display());
    }
    commit(&tmp, path)
}

/// An EXR's named channels, as f32.
type Channels = Vec<(String, Vec<f32>)>;

/// The width, height and named channels of an EXR's first layer.
fn read_exr_channels(path: &Path) -> Result<(usize, usize, Channels)> {
    use exr::prelude::*;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .with_context(|| format!("cannot read EXR {}", path.display()))?;
    let layer = image.layer_data;
    let channels = layer
        .channel_data
        .list
        .iter()
        .map(|c| {
            let values = match &c.sample_data {
                // Integer channels hold [0, 1] scaled to the full range (Mitsuba's
                // Normalized flag): not the integer's value.
                FlatSamples::U32(v) => v.iter().map(|&q| dequantize_uint32(q)).collect(),
                other => other.values_as_f32().collect(),
            };
            (c.name.to_string(), values)
        })
        .collect();
    Ok((layer.size.width(), layer.size.height(), channels))
}

/// The alpha channel `A` of an EXR (a film with `rgba` or `luminance_alpha`), if it has one.
pub fn read_exr_alpha(path: &Path) -> Result<Option<Vec<f32>>> {
    let (_, _, channels) = read_exr_channels(path)?;
    Ok(channels.into_iter().find(|(n, _)| n == "A").map(|(_, v)| v))
}

/// OUT.exr with `_suffix` added to its stem (OUT_dalbedo.exr, OUT_var.exr).
pub fn sibling(out_exr: &Path, suffix: &str) -> PathBuf {
    let stem = out_exr.file_stem().unwrap_or_default().to_string_lossy();
    out_exr.with_file_name(format!("{stem}{suffix}.exr"))
}

/// An integer attribute of an EXR's header, if present.
pub fn read_exr_int_attribute(path: &Path, name: &str) -> Result<Option<i32>> {
    use exr::meta::attribute::AttributeValue;
    let meta = exr::meta::MetaData::read_from_file(path, false)
        .with_context(|| format!("cannot read EXR header {}", path.display()))?;
    let key = exr::meta::attribute::Text::from(name);
    Ok(meta.headers.iter().find_map(|h| {
        [&h.shared_attributes.other, &h.own_attributes.other]
            .into_iter()
            .find_map(|m| match m.get(&key) {
                Some(AttributeValue::I32(v)) => Some(*v),
                _ => None,
            })
    }))
}

/// Reads the RGB channels of an EXR (any of half/float/uint channels R, G, B; uint as
/// Mitsuba reads it, [0, 1] over the integer's range: a `uint32` film's file); a
/// luminance EXR (a `Y` channel, as a `luminance` film writes) reads as grey, Y in all
/// three.
pub fn read_exr(path: &Path) -> Result<Image> {
    use exr::prelude::*;
    if let Ok((width, height, channels)) = read_exr_channels(path) {
        let get = |n: &str| channels.iter().find(|(c, _)| c == n).map(|(_, v)| v);
        if let (Some(r), Some(g), Some(b)) = (get("R"), get("G"), get("B")) {
            let pixels = (0..width * height).map(|i| [r[i], g[i], b[i]]).collect();
            return Ok(self::Image {
                width,
                height,
                pixels,
            });
        }
        if let Some(y) = get("Y") {
            return Ok(self::Image {
                width,
                height,
                pixels: y.iter().map(|&v| [v; 3]).collect(),
            });
        }
    }
    let image = read_first_rgba_layer_from_file(
        path,
        |res, _| {
            (
                res.width(),
                res.height(),
                vec![[0f32; 3]; res.width() * res.height()],
            )
        },
        |(w, _h, px): &mut (usize, usize, Vec<[f32; 3]>),
         pos,
         (r, g, b, _a): (f32, f32, f32, f32)| {
            px[pos.y() * *w + pos.x()] = [r, g, b];
        },
    )
    .with_context(|| format!("cannot read EXR {}", path.display()))?;
    let (width, height, pixels) = image.layer_data.channel_data.pixels;
    Ok(self::Image {
        width,
        height,
        pixels,
    })
}

/// sRGB transfer function of a linear value in [0, 1].
fn srgb_encode(v: f32) -> f32 {
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Writes an 8-bit sRGB PNG preview (clamped, no exposure change).
pub fn write_png(path: &Path, img: &Image) -> Result<()> {
    let data: Vec<u8> = img
        .pixels
        .iter()
        .flat_map(|p| p.map(|c| (srgb_encode(c.clamp(0.0, 1.0)) * 255.0 + 0.5) as u8))
        .collect();
    write_png_bytes(path, img.width, img.height, &data)
}

/// The 99th percentile of |value| over all channels: the `scale` of a signed preview
/// that few outliers saturate (1 for an all-zero image).
pub fn signed_scale(img: &Image) -> f32 {
    let mut v: Vec<f32> = img.pixels.iter().flatten().map(|c| c.abs()).collect();
    if v.is_empty() {
        return 1.0;
    }
    let k = ((v.len() - 1) as f64 * 0.99) as usize;
    let (_, q, _) = v.select_nth_unstable_by(k, f32::total_cmp);
    if *q > 0.0 && q.is_finite() {
        *q
    } else {
        1.0
    }
}

/// Writes a preview of a signed image (a derivative): each channel maps −scale → 0,
/// 0 → mid grey, +scale → full, linearly in sRGB values.
pub fn write_png_signed(path: &Path, img: &Image, scale: f32) -> Result<()> {
    let data: Vec<u8> = img
        .pixels
        .iter()
        .flat_map(|p| p.map(|c| ((0.5 + 0.5 * c / scale).clamp(0.0, 1.0) * 255.0 + 0.5) as u8))
        .collect();
    write_png_bytes(path, img.width, img.height, &data)
}

fn write_png_bytes(path: &Path, width: usize, height: usize, data: &[u8]) -> Result<()> {
    let tmp = temp_path(path);
    let write = || -> Result<()> {
        let file = std::fs::File::create(&tmp)?;
        let mut enc = png::Encoder::new(std::io::BufWriter::new(file), width as u32, height as u32);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut writer = enc.write_header()?;
        writer.write_image_data(data)?;
        writer.finish()?;
        Ok(())
    };
    if let Err(e) = write() {
        let _ = std::fs::remove_file(&tmp);
        return Err(e.context(format!("cannot write {}", path.display())));
    }
    commit(&tmp, path)
}
