//! Reading a `bitmap` texture's file as Mitsuba 3 reads it (`src/core/bitmap.cpp`,
//! `Bitmap::read`): the format is told by the file's first bytes, not its name, and
//! each format keeps Mitsuba's meaning:
//!
//! | format | detected by | data |
//! |---|---|---|
//! | PNG | signature | 8/16-bit, grey, grey+alpha, RGB(A), palette: sRGB-encoded |
//! | JPEG | `FF D8` | 8-bit grey or RGB (4:2:0 etc. upsampled as libjpeg): sRGB |
//! | BMP | `BM` | 24-bit uncompressed only here (below): sRGB |
//! | TGA | the v2 footer `TRUEVISION-XFILE.` | 8-bit grey, 24/32-bit RGB(A), RLE or not: sRGB |
//! | PPM | `P6` | 8-bit RGB: sRGB |
//! | OpenEXR | magic | float: linear |
//! | RGBE (`.hdr`) | `#?` | `32-bit_rle_rgbe`: linear, v = m · 2^(e − 136) |
//! | PFM | `PF` / `Pf` | f32 RGB / grey, rows bottom to top, times \|scale\|: linear |
//!
//! Grey images are grey in every channel and alpha is dropped (Mitsuba's bitmap texture
//! keeps Y or RGB). 8- and 16-bit data is sRGB-decoded unless `raw`; float data never is.
//! What Mitsuba reads with a meaning of its own is refused rather than guessed: an 8- or
//! 16-bit BMP (Mitsuba takes the palette indices as grey levels), a 32-bit BMP (read as
//! premultiplied alpha), compressed BMPs and RGBE files in XYZ (Mitsuba refuses some of
//! these too). A TGA without the v2 footer is not recognised, as in Mitsuba.
//!
//! Decoding is libjpeg-turbo's for JPEG (the `mozjpeg` crate: the same bytes as
//! Mitsuba's), the `image` crate's (BMP, TGA, PPM, RGBE), the `png` crate's, the `exr`
//! crate's (through `crate::image`) and, for PFM, the few lines below.

use std::path::Path;

use glam::Vec3;
use image::{DynamicImage, ImageFormat};

/// Width, height and linear RGB texels, row-major from the image's top row.
pub type Texels = (usize, usize, Vec<Vec3>);

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Format {
    Png,
    Jpeg,
    Bmp,
    Tga,
    Ppm,
    Exr,
    Rgbe,
    Pfm,
}

const FORMATS: &str =
    "PNG, JPEG, OpenEXR, RGBE (.hdr), PFM, PPM (P6), TGA (with the v2 footer) or 24-bit BMP";

/// Mitsuba's `Bitmap::detect_file_format`: by the first bytes, and for TGA the footer.
fn detect(bytes: &[u8]) -> Option<Format> {
    let b = |i: usize| bytes.get(i).copied().unwrap_or(0);
    Some(match (b(0), b(1)) {
        (b'B', b'M') => Format::Bmp,
        (b'#', b'?') => Format::Rgbe,
        (b'P', b'F' | b'f') => Format::Pfm,
        (b'P', b'6') => Format::Ppm,
        (0xFF, 0xD8) => Format::Jpeg,
        _ if bytes.starts_with(b"\x89PNG\r\n\x1a\n") => Format::Png,
        _ if bytes.starts_with(&[0x76, 0x2f, 0x31, 0x01]) => Format::Exr,
        _ if bytes.len() >= 18 && bytes[bytes.len() - 18..] == *b"TRUEVISION-XFILE.\0" => {
            Format::Tga
        }
        _ => return None,
    })
}

/// Reads `path` as linear RGB texels; `raw` skips the sRGB decoding of 8/16-bit data.
/// Errors are one sentence naming the file (the caller adds the scene's file:line).
pub fn read_texels(path: &Path, raw: bool) -> Result<Texels, String> {
    let name = path.display();
    let bytes = std::fs::read(path).map_err(|e| format!("{name}: {e}"))?;
    let format = detect(&bytes).ok_or_else(|| {
        format!("\"{name}\" is not an image format Mitsuba 3 reads as a bitmap ({FORMATS})")
    })?;
    let decode = |fmt: ImageFormat| {
        image::load_from_memory_with_format(&bytes, fmt)
            .map_err(|e| format!("\"{name}\": corrupt or unsupported {fmt:?} data: {e}"))
    };
    match format {
        Format::Png => read_png(path, raw),
        Format::Exr => {
            let img = crate::image::read_exr(path).map_err(|e| format!("{e:#}"))?;
            let texels = img.pixels.iter().map(|p| Vec3::from(*p)).collect();
            Ok((img.width, img.height, texels))
        }
        Format::Pfm => read_pfm(&bytes).map_err(|e| format!("\"{name}\": {e}")),
        Format::Rgbe => {
            check_rgbe(&bytes).map_err(|e| format!("\"{name}\": {e}"))?;
            read_rgbe(&bytes).map_err(|e| format!("\"{name}\": corrupt RGBE data: {e}"))
        }
        Format::Bmp => {
            check_bmp(&bytes).map_err(|e| format!("\"{name}\": {e}"))?;
            Ok(from_dynamic(decode(ImageFormat::Bmp)?, raw))
        }
        Format::Tga => {
            check_tga(&bytes).map_err(|e| format!("\"{name}\": {e}"))?;
            Ok(from_dynamic(decode(ImageFormat::Tga)?, raw))
        }
        Format::Ppm => {
            let img = decode(ImageFormat::Pnm)?;
            if !matches!(img, DynamicImage::ImageRgb8(_)) {
                return Err(format!("\"{name}\": only 8-bit binary PPM (P6, maxval 255) is read (Mitsuba 3 reads 16-bit PPM data in the machine's byte order)"));
            }
            Ok(from_dynamic(img, raw))
        }
        Format::Jpeg => read_jpeg(&bytes, raw).map_err(|e| format!("\"{name}\": {e}")),
    }
}

/// sRGB decoding of an encoded value in [0, 1] (IEC 61966-2-1).
pub fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// Reads a PNG (8 or 16 bits, grey or RGB, palette expanded, alpha dropped) as linear
/// RGB texels; `raw` skips the sRGB decoding. Returns (width, height, texels).
fn read_png(path: &Path, raw: bool) -> Result<(usize, usize, Vec<Vec3>), String> {
    let file = std::fs::File::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut decoder = png::Decoder::new(std::io::BufReader::new(file));
    // Palettes and low bit depths become 8-bit; 16-bit data is kept.
    decoder.set_transformations(png::Transformations::EXPAND);
    let mut reader = decoder
        .read_info()
        .map_err(|e| format!("{}: not a readable PNG: {e}", path.display()))?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| format!("{}: image too large", path.display()))?;
    let mut buf = vec![0u8; size];
    let info = reader
        .next_frame(&mut buf)
        .map_err(|e| format!("{}: corrupt PNG data: {e}", path.display()))?;
    let (w, h) = (info.width as usize, info.height as usize);
    let channels = info.color_type.samples();
    let sixteen = info.bit_depth == png::BitDepth::Sixteen;
    let bytes = if sixteen { 2 } else { 1 };
    let value = |i: usize| -> f32 {
        let v = if sixteen {
            u16::from_be_bytes([buf[2 * i], buf[2 * i + 1]]) as f32 / 65535.0
        } else {
            buf[i] as f32 / 255.0
        };
        if raw {
            v
        } else {
            srgb_to_linear(v)
        }
    };
    let line = info.line_size / bytes;
    let mut texels = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let i = y * line + x * channels;
            texels.push(match channels {
                1 | 2 => Vec3::splat(value(i)),
                _ => Vec3::new(value(i), value(i + 1), value(i + 2)),
            });
        }
    }
    Ok((w, h, texels))
}

/// JPEG by libjpeg-turbo's decoder (the `mozjpeg` crate, a libjpeg-turbo fork), which
/// Mitsuba 3 links: the same integer IDCT and "fancy" chroma upsampling, so the same
/// bytes (`image`'s pure-Rust decoder differs by up to 3/255 in chroma-upsampled
/// texels, which a render against Mitsuba detects). libjpeg reports errors by
/// unwinding (`resume_unwind`, no panic message), caught here. Grey or RGB, as Mitsuba;
/// CMYK is refused, as by Mitsuba.
fn read_jpeg(bytes: &[u8], raw: bool) -> Result<Texels, String> {
    let decode = || -> std::io::Result<Result<Texels, String>> {
        let d = mozjpeg::Decompress::new_mem(bytes)?;
        let (w, h) = (d.width(), d.height());
        let grey = match d.color_space() {
            mozjpeg::ColorSpace::JCS_GRAYSCALE => true,
            mozjpeg::ColorSpace::JCS_YCbCr | mozjpeg::ColorSpace::JCS_RGB => false,
            c => return Ok(Err(format!("JPEG in colour space {c:?}, which Mitsuba 3 does not read (grey or RGB only); save it as RGB"))),
        };
        let value = |v: u8| {
            let v = v as f32 / 255.0;
            if raw {
                v
            } else {
                srgb_to_linear(v)
            }
        };
        let texels = if grey {
            let mut s = d.grayscale()?;
            let px: Vec<u8> = s.read_scanlines()?;
            s.finish()?;
            px.into_iter().map(|v| Vec3::splat(value(v))).collect()
        } else {
            let mut s = d.rgb()?;
            let px: Vec<[u8; 3]> = s.read_scanlines()?;
            s.finish()?;
            px.into_iter()
                .map(|p| Vec3::new(value(p[0]), value(p[1]), value(p[2])))
                .collect::<Vec<_>>()
        };
        if texels.len() != w * h {
            return Ok(Err(format!(
                "truncated JPEG data ({} of {w}×{h} pixels)",
                texels.len()
            )));
        }
        Ok(Ok((w, h, texels)))
    };
    match std::panic::catch_unwind(decode) {
        Ok(Ok(r)) => r,
        Ok(Err(e)) => Err(format!("corrupt JPEG data: {e}")),
        Err(payload) => {
            let msg = payload
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| payload.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "libjpeg error".into());
            Err(format!("corrupt JPEG data: {msg}"))
        }
    }
}

/// RGBE as Mitsuba's `read_rgbe`: rows top to bottom ("-Y H +X W"), (m + 0) · 2^(e − 136)
/// per channel, EXPOSURE not applied (Mitsuba ignores it).
fn read_rgbe(bytes: &[u8]) -> Result<Texels, String> {
    let d = image::codecs::hdr::HdrDecoder::new(std::io::Cursor::new(bytes))
        .map_err(|e| e.to_string())?;
    let meta = d.metadata();
    if meta.orientation != ((1, 0), (0, 1)) {
        return Err(
            "RGBE orientation other than \"-Y H +X W\", which Mitsuba 3 does not read".into(),
        );
    }
    let (w, h) = (meta.width as usize, meta.height as usize);
    let px = d.read_image_hdr().map_err(|e| e.to_string())?;
    Ok((w, h, px.into_iter().map(|p| Vec3::from(p.0)).collect()))
}

/// Texels of a decoded image: grey replicated, alpha dropped; integer data sRGB-decoded
/// unless `raw` (Mitsuba's `srgb_gamma` of 8/16-bit files), float data kept.
fn from_dynamic(img: DynamicImage, raw: bool) -> Texels {
    let float = matches!(
        img,
        DynamicImage::ImageRgb32F(_) | DynamicImage::ImageRgba32F(_)
    );
    let decode = !(raw || float);
    let rgb = img.into_rgb32f();
    let (w, h) = (rgb.width() as usize, rgb.height() as usize);
    let texels = rgb
        .pixels()
        .map(|p| {
            let c = Vec3::from(p.0);
            if decode {
                Vec3::new(
                    srgb_to_linear(c.x),
                    srgb_to_linear(c.y),
                    srgb_to_linear(c.z),
                )
            } else {
                c
            }
        })
        .collect();
    (w, h, texels)
}

fn le_u16(b: &[u8], i: usize) -> u16 {
    b.get(i..i + 2)
        .map_or(0, |s| u16::from_le_bytes([s[0], s[1]]))
}

fn le_u32(b: &[u8], i: usize) -> u32 {
    b.get(i..i + 4)
        .map_or(0, |s| u32::from_le_bytes([s[0], s[1], s[2], s[3]]))
}

/// The BMPs Mitsuba reads with the usual meaning: a 40-byte info header, one plane,
/// uncompressed, 24 bits (Mitsuba's `read_bmp` takes 8-bit palette indices as grey and
/// 32-bit data as premultiplied RGBA).
fn check_bmp(b: &[u8]) -> Result<(), String> {
    let (header, planes, bpp, compression) =
        (le_u32(b, 14), le_u16(b, 26), le_u16(b, 28), le_u32(b, 30));
    if header != 40 || planes != 1 {
        return Err("BMP with an info header Mitsuba 3 does not read (it needs the 40-byte BITMAPINFOHEADER); save it as PNG".into());
    }
    if compression != 0 {
        return Err(
            "compressed BMP, which Mitsuba 3 does not read; save it uncompressed or as PNG".into(),
        );
    }
    if bpp != 24 {
        return Err(format!("{bpp}-bit BMP: only 24-bit BMP is read (Mitsuba 3 takes 8-bit palette indices as grey levels and 32-bit data as premultiplied alpha); save it as 24-bit BMP or PNG"));
    }
    Ok(())
}

/// Mitsuba's `read_tga`: no colour map, grey or true-colour (RLE or not), 8-bit grey or
/// 24/32-bit colour.
fn check_tga(b: &[u8]) -> Result<(), String> {
    let (map, kind, bpp) = (
        b.get(1).copied().unwrap_or(0),
        b.get(2).copied().unwrap_or(0),
        b.get(16).copied().unwrap_or(0),
    );
    if map != 0 || !matches!(kind, 2 | 3 | 10 | 11) {
        return Err(
            "indexed (colour-mapped) TGA, which Mitsuba 3 does not read; save it as RGB".into(),
        );
    }
    let grey = matches!(kind, 3 | 11);
    if (grey && bpp != 8) || (!grey && bpp != 24 && bpp != 32) {
        return Err(format!("TGA of {bpp} bits per pixel, which Mitsuba 3 does not read (8-bit grey, 24- or 32-bit colour)"));
    }
    Ok(())
}

/// Mitsuba's `read_rgbe` knows `32-bit_rle_rgbe` and `32-bit_rle_xyze`; only the first
/// is read here.
fn check_rgbe(b: &[u8]) -> Result<(), String> {
    let head = &b[..b.len().min(4096)];
    let text = String::from_utf8_lossy(head);
    if text
        .lines()
        .any(|l| l.starts_with("FORMAT=32-bit_rle_xyze"))
    {
        return Err("RGBE file in XYZ (FORMAT=32-bit_rle_xyze) is not supported; save it as RGB (32-bit_rle_rgbe) or OpenEXR".into());
    }
    if !text
        .lines()
        .any(|l| l.starts_with("FORMAT=32-bit_rle_rgbe"))
    {
        return Err("RGBE header without FORMAT=32-bit_rle_rgbe, which Mitsuba 3 refuses".into());
    }
    Ok(())
}

/// PFM as Mitsuba's `read_pfm`: "PF" (RGB) or "Pf" (grey), width, height and a scale
/// whose sign gives the byte order (negative: little-endian) and whose magnitude
/// multiplies every value; then f32 rows from the bottom of the image up.
fn read_pfm(b: &[u8]) -> Result<Texels, String> {
    // Three whitespace-separated tokens after the two-byte magic, then one whitespace.
    let mut pos = 2;
    let mut tokens = Vec::new();
    while tokens.len() < 3 {
        while pos < b.len() && b[pos].is_ascii_whitespace() {
            pos += 1;
        }
        let start = pos;
        while pos < b.len() && !b[pos].is_ascii_whitespace() {
            pos += 1;
        }
        if start == pos {
            return Err("truncated PFM header".into());
        }
        tokens.push(String::from_utf8_lossy(&b[start..pos]).into_owned());
    }
    pos += 1;
    let parse_err = || format!("could not parse the PFM header {tokens:?}");
    let w: usize = tokens[0].parse().map_err(|_| parse_err())?;
    let h: usize = tokens[1].parse().map_err(|_| parse_err())?;
    let scale: f32 = tokens[2].parse().map_err(|_| parse_err())?;
    let channels = if b[1] == b'F' { 3 } else { 1 };
    let n = w
        .checked_mul(h)
        .and_then(|p| p.checked_mul(channels * 4))
        .ok_or_else(parse_err)?;
    let data = b
        .get(pos..pos + n)
        .ok_or_else(|| format!("PFM data truncated: {w}×{h}×{channels} floats expected"))?;
    let little = scale <= 0.0;
    let factor = scale.abs();
    let value = |i: usize| {
        let q = [
            data[4 * i],
            data[4 * i + 1],
            data[4 * i + 2],
            data[4 * i + 3],
        ];
        let v = if little {
            f32::from_le_bytes(q)
        } else {
            f32::from_be_bytes(q)
        };
        if factor != 1.0 {
            v * factor
        } else {
            v
        }
    };
    let mut texels = Vec::with_capacity(w * h);
    for y in (0..h).rev() {
        for x in 0..w {
            let i = (y * w + x) * channels;
            texels.push(if channels == 3 {
                Vec3::new(value(i), value(i + 1), value(i + 2))
            } else {
                Vec3::splat(value(i))
            });
        }
    }
    Ok((w, h, texels))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn detects_as_mitsuba() {
        assert_eq!(detect(b"\x89PNG\r\n\x1a\n...."), Some(Format::Png));
        assert_eq!(detect(&[0xFF, 0xD8, 0xFF, 0xE0]), Some(Format::Jpeg));
        assert_eq!(detect(b"#?RADIANCE\n"), Some(Format::Rgbe));
        assert_eq!(detect(b"Pf 1 1 -1\n"), Some(Format::Pfm));
        assert_eq!(detect(b"P6 1 1 255\n"), Some(Format::Ppm));
        assert_eq!(detect(b"BM......"), Some(Format::Bmp));
        // A TGA is known only by its v2 footer; P3 (ASCII PPM) is not read.
        let mut tga = vec![0u8; 30];
        tga.extend_from_slice(b"TRUEVISION-XFILE.\0");
        assert_eq!(detect(&tga), Some(Format::Tga));
        assert_eq!(detect(&tga[..30]), None);
        assert_eq!(detect(b"P3 1 1 255\n"), None);
        assert_eq!(detect(b""), None);
    }

    #[test]
    fn pfm_rows_bottom_up_scaled_both_byte_orders() {
        // 1 × 2 grey: the file's first row is the image's bottom.
        for (scale, le) in [("-2.0", true), ("2.0", false)] {
            let mut f = format!("Pf\n1 2\n{scale}\n").into_bytes();
            for v in [0.25f32, 0.5] {
                f.extend(if le { v.to_le_bytes() } else { v.to_be_bytes() });
            }
            let (w, h, t) = read_pfm(&f).unwrap();
            assert_eq!((w, h), (1, 2));
            assert_eq!(t, vec![Vec3::splat(1.0), Vec3::splat(0.5)]);
        }
        assert!(read_pfm(b"PF\n2 2\n-1\n\0\0")
            .unwrap_err()
            .contains("truncated"));
        assert!(read_pfm(b"PF\nx 2\n-1\n").unwrap_err().contains("parse"));
    }
}
