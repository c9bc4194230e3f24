//! Mitsuba's `independent` sampler: a PCG32 stream per pixel sample, seeded from the
//! scene seed, the pixel index and the sample index, so an image depends only on the
//! seed, never on thread count or on how the samples are split into passes. A path's
//! stream (`Pcg32::for_path`) takes its first draws from `sampling::padded`.

use glam::Vec2;

use super::padded::{PaddedPoints, PaddedScrambles, STRATIFIED_DRAWS};

/// PCG32 (O'Neill 2014), XSH-RR output, the generator Mitsuba uses.
#[derive(Clone, Debug)]
pub struct Pcg32 {
    state: u64,
    inc: u64,
    /// The first `STRATIFIED_DRAWS` draws of a path stream ([`Pcg32::for_path`]) come
    /// from the pixel's padded (0,2)-sequences: `draw` counts them (it starts at the
    /// limit in every other stream); `padded` holds the sample's points of them.
    draw: usize,
    padded: PaddedPoints,
}

const MULT: u64 = 0x5851_f42d_4c95_7f2d;

impl Pcg32 {
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut r = Pcg32 {
            state: 0,
            inc: (stream << 1) | 1,
            draw: STRATIFIED_DRAWS,
            padded: PaddedPoints::default(),
        };
        r.next_u32();
        r.state = r.state.wrapping_add(seed);
        r.next_u32();
        r
    }

    /// A stream for one pixel: the scene seed and pixel index are mixed (SplitMix64) so
    /// neighbouring pixels and seeds give unrelated streams.
    pub fn for_pixel(seed: u64, pixel: u64) -> Self {
        let s = splitmix64(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ splitmix64(pixel));
        Pcg32::new(s, splitmix64(s ^ pixel))
    }

    /// A stream for one sample of one pixel, so that a sample's value does not depend on
    /// how the samples are split into passes.
    #[inline]
    pub fn for_sample(seed: u64, pixel: u64, sample: u64) -> Self {
        let p = splitmix64(pixel ^ splitmix64(sample.wrapping_mul(0xd1b5_4a32_d192_ed03)));
        let s = splitmix64(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ p);
        Pcg32::new(s, splitmix64(s ^ p))
    }

    /// The stream of one path: [`Pcg32::for_sample`], except that its first
    /// `STRATIFIED_DRAWS` draws (one value of `next_1d`, or the pair of `next_2d`) are
    /// the sample's points of the pixel's padded (0,2)-sequences (`sampling::padded`):
    /// each draw of one sample is uniform and independent of the others, so every
    /// estimate keeps its expectation; across a pixel's samples each draw is stratified.
    #[inline(always)]
    pub fn for_path(seed: u64, pixel: u64, sample: u32, scrambles: &PaddedScrambles) -> Self {
        let mut r = Pcg32::for_sample(seed, pixel, sample as u64);
        r.draw = 0;
        r.padded = scrambles.points(sample);
        r
    }

    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(MULT).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform in [0, 1): 23 random mantissa bits.
    #[inline(always)]
    pub fn next_1d(&mut self) -> f32 {
        if self.draw < STRATIFIED_DRAWS {
            self.draw += 1;
            return unit(self.padded.x[self.draw - 1]);
        }
        unit(self.next_u32())
    }

    #[inline(always)]
    pub fn next_2d(&mut self) -> Vec2 {
        if self.draw < STRATIFIED_DRAWS {
            let k = self.draw;
            self.draw += 1;
            return Vec2::new(unit(self.padded.x[k]), unit(self.padded.y[k]));
        }
        let x = unit(self.next_u32());
        Vec2::new(x, unit(self.next_u32()))
    }
}

/// The top 23 bits as a float in [0, 1).
#[inline]
fn unit(bits: u32) -> f32 {
    f32::from_bits((bits >> 9) | 0x3f80_0000) - 1.0
}

fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_mean_and_range() {
        let mut r = Pcg32::for_pixel(7, 3);
        let n = 100_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            let x = r.next_1d();
            assert!((0.0..1.0).contains(&x));
            sum += x as f64;
        }
        // Mean of U(0,1) has std 1/sqrt(12 n) ≈ 0.0009; 5 sigma.
        assert!((sum / n as f64 - 0.5).abs() < 0.0046);
    }

    #[test]
    fn streams_differ() {
        let a = Pcg32::for_pixel(0, 0).next_u32();
        let b = Pcg32::for_pixel(0, 1).next_u32();
        let c = Pcg32::for_pixel(1, 0).next_u32();
        assert!(a != b && a != c);
    }
}
