//! Where in its pixel each sample falls: the points of the two-dimensional Sobol
//! sequence, a (0,2)-sequence, with a random digital shift per pixel (Kollig and
//! Keller 2002, "Efficient multidimensional sampling").
//!
//! Every point is uniform over the pixel (XOR with uniform random bits is uniform), so
//! the image's expectation is that of independent positions, as with Mitsuba's
//! `independent` sampler; but any 2^m consecutive samples from the start put one point
//! in each of the pixel's 2^m elementary intervals of every shape, so what a pixel sees
//! of an edge (a bright emitter's outline) converges much faster than at random.
//! Pixels are shifted independently, so pixel errors stay independent of each other.

use glam::Vec2;

use super::padded::sobol_second;
use super::Pcg32;

/// The sample positions of one pixel.
#[derive(Clone, Copy, Debug)]
pub struct PixelSamples {
    shift: [u32; 2],
}

impl PixelSamples {
    /// The shift is drawn from its own stream (no sample index reaches `u64::MAX`).
    pub fn new(seed: u64, pixel: u64) -> Self {
        let mut rng = Pcg32::for_sample(seed, pixel, u64::MAX);
        PixelSamples {
            shift: [rng.next_u32(), rng.next_u32()],
        }
    }

    /// Sample `index`'s position within the pixel, in [0, 1)².
    #[inline]
    pub fn get(&self, index: u32) -> Vec2 {
        Vec2::new(
            unit(index.reverse_bits() ^ self.shift[0]),
            unit(sobol_second(index) ^ self.shift[1]),
        )
    }
}

/// The top 23 bits as a float in [0, 1).
#[inline]
fn unit(bits: u32) -> f32 {
    f32::from_bits((bits >> 9) | 0x3f80_0000) - 1.0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The (0,2)-net property: the first 2^m points, shifted, put exactly one point in
    /// each elementary interval [a/2^j, (a+1)/2^j) × [b/2^(m−j), (b+1)/2^(m−j)).
    #[test]
    fn first_points_fill_every_elementary_interval_once() {
        for pixel in 0..4u64 {
            let s = PixelSamples::new(7, pixel);
            for m in 0..=10u32 {
                let points: Vec<Vec2> = (0..1u32 << m).map(|i| s.get(i)).collect();
                for j in 0..=m {
                    let (nx, ny) = (1u32 << j, 1u32 << (m - j));
                    let mut seen = vec![0u32; (nx * ny) as usize];
                    for p in &points {
                        assert!((0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y));
                        let (cx, cy) = ((p.x * nx as f32) as u32, (p.y * ny as f32) as u32);
                        seen[(cy * nx + cx) as usize] += 1;
                    }
                    assert!(seen.iter().all(|&c| c == 1), "m {m}, j {j}: {seen:?}");
                }
            }
        }
    }

    /// Over pixels, one sample's position is uniform: the mean of its coordinates and
    /// their squares match a uniform variable's (1/2, 1/3) within 5 standard errors.
    #[test]
    fn each_sample_is_uniform_over_pixels() {
        let n = 20_000u64;
        for index in [0u32, 1, 5, 100] {
            let (mut sx, mut sxx, mut sy, mut syy) = (0.0f64, 0.0, 0.0, 0.0);
            for pixel in 0..n {
                let p = PixelSamples::new(3, pixel).get(index);
                let (x, y) = (p.x as f64, p.y as f64);
                (sx, sxx, sy, syy) = (sx + x, sxx + x * x, sy + y, syy + y * y);
            }
            let nf = n as f64;
            // Standard errors: √(1/12 / n) for the mean, √(4/45 / n) for the square's.
            let (se1, se2) = ((1.0 / 12.0 / nf).sqrt(), (4.0 / 45.0 / nf).sqrt());
            for (mean, sq) in [(sx / nf, sxx / nf), (sy / nf, syy / nf)] {
                assert!(
                    (mean - 0.5).abs() < 5.0 * se1,
                    "sample {index}: mean {mean}"
                );
                assert!(
                    (sq - 1.0 / 3.0).abs() < 5.0 * se2,
                    "sample {index}: E[x²] {sq}"
                );
            }
        }
    }
}
