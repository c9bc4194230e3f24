//! The sample types an EXR's channels are written in (`hdrfilm`'s `component_format`),
//! and Mitsuba 3's normalized `uint32` samples.

/// The sample type `hdrfilm` writes (its `component_format`). mediareg writes float32
/// for `float16` too (more precision than asked, the same values); `uint32` is written
/// as Mitsuba 3 writes it: unsigned 32-bit channels holding the linear value in [0, 1]
/// ([`quantize_uint32`]), as Mitsuba 2 files sometimes ask.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ComponentFormat {
    #[default]
    Float16,
    Float32,
    Uint32,
}

impl ComponentFormat {
    pub const ALL: [ComponentFormat; 3] = [
        ComponentFormat::Float16,
        ComponentFormat::Float32,
        ComponentFormat::Uint32,
    ];

    pub fn name(self) -> &'static str {
        match self {
            ComponentFormat::Float16 => "float16",
            ComponentFormat::Float32 => "float32",
            ComponentFormat::Uint32 => "uint32",
        }
    }
}

/// The largest f32 not above u32::MAX (2^32 − 2^8): Mitsuba clamps there before the
/// conversion, since u32::MAX itself rounds up to 2^32 in f32.
pub const UINT32_CLAMP: f32 = 4_294_967_040.0;

/// A linear value as Mitsuba 3 stores it in a `uint32` channel (`Bitmap::convert` to a
/// normalized UInt32 field, in float32: struct-jit's converter): v · (2^32 − 1) in f32
/// (which is v · 2^32), rounded to nearest even, clamped to [0, [`UINT32_CLAMP`]], so
/// negative values give 0 and values ≥ 1 the top. Mitsuba also adds an ordered dither
/// in [−½, ½) before rounding; at this scale it moves a value below 2^-8 by at most one
/// step of 2^-32 and leaves larger ones alone, so it is left out.
pub fn quantize_uint32(v: f32) -> u32 {
    let scaled = (v * u32::MAX as f32).round_ties_even();
    scaled.clamp(0.0, UINT32_CLAMP) as u32
}

/// What Mitsuba 3 reads from a `uint32` channel (normalized: · 1 / (2^32 − 1) in f32).
pub fn dequantize_uint32(q: u32) -> f32 {
    q as f32 * (1.0 / u32::MAX as f64) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uint32_quantization_is_mitsubas() {
        let cases = [
            (0.5, 1u32 << 31),
            (0.25 + 2f32.powi(-24), (1 << 30) + (1 << 8)),
            (2f32.powi(-9), 1 << 23),
            (2.5 * 2f32.powi(-32), 2),
            (3.5 * 2f32.powi(-32), 4),
            (0.0, 0),
            (-1.0, 0),
            (1.0, 4_294_967_040),
            (7.0, 4_294_967_040),
        ];
        for (v, q) in cases {
            assert_eq!(quantize_uint32(v), q, "{v}");
        }
        for v in [0.5f32, 0.123_456_79, 2f32.powi(-9), 0.999] {
            assert_eq!(dequantize_uint32(quantize_uint32(v)), v);
        }
    }
}
