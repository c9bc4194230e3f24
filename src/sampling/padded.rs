//! The first draws of each path from padded (0,2)-sequences (pbrt-v4's padded Sobol
//! sampler): per pixel and per draw, sample i takes point π(i) of the two-dimensional
//! Sobol sequence, digitally shifted by a random XOR, where π is a nested uniform
//! (Owen) scramble of the index of the draw's own.
//!
//! π maps every aligned block of 2^m indices onto an aligned block of 2^m (each bit is
//! flipped by a hash of the bits above it), and every aligned block of the sequence is
//! a (0,m,2)-net: so the first 2^m samples of a pixel put one point of each draw in
//! each elementary interval, whatever the spp, and a sample's draws depend on its index
//! alone (an interrupted render is the render of the samples it reached). π is not
//! linear, so the draws are not tied to each other (the sequence is linear over GF(2):
//! with an XOR of the index every draw would be a shift of every other).
//!
//! Each draw of one sample is uniform (the shift is) and independent of the sample's
//! other draws (their scrambles and shifts are), so every estimator keeps its
//! expectation; across a pixel's samples each draw is stratified, and the first draws
//! of a path (the hero channel, the first flights, the emitter and phase samples)
//! converge faster than at random.

/// How many draws of a path come from padded (0,2)-sequences (see `Pcg32::for_path`).
pub const STRATIFIED_DRAWS: usize = 8;

/// The random choices of a pixel's padded (0,2)-sequences, one per draw: the seed of
/// the index scramble and the digital shift of each coordinate.
#[derive(Clone, Copy, Debug)]
pub struct PaddedScrambles {
    order: [u32; STRATIFIED_DRAWS],
    shift_x: [u32; STRATIFIED_DRAWS],
    shift_y: [u32; STRATIFIED_DRAWS],
}

/// One sample's points of all the draws, coordinate by coordinate.
#[derive(Clone, Copy, Debug, Default)]
pub struct PaddedPoints {
    pub x: [u32; STRATIFIED_DRAWS],
    pub y: [u32; STRATIFIED_DRAWS],
}

impl PaddedScrambles {
    /// The scrambles from `3 · STRATIFIED_DRAWS` random words (the pixel's own
    /// stream's, so that draws are independent of each other and of the path's).
    pub fn new(mut word: impl FnMut() -> u32) -> Self {
        let mut s = PaddedScrambles {
            order: [0; STRATIFIED_DRAWS],
            shift_x: [0; STRATIFIED_DRAWS],
            shift_y: [0; STRATIFIED_DRAWS],
        };
        for k in 0..STRATIFIED_DRAWS {
            s.order[k] = word();
            s.shift_x[k] = word();
            s.shift_y[k] = word();
        }
        s
    }

    /// Point `index` of draw `draw`: (radical inverse, Sobol's second dimension) of the
    /// scrambled index, shifted.
    #[cfg(test)]
    fn point(&self, draw: usize, index: u32) -> [u32; 2] {
        let p = self.points(index);
        [p.x[draw], p.y[draw]]
    }

    /// Point `index` of every draw, all at once (a path draws most of them, and the
    /// draws' hashes run side by side in vector registers). The scramble works on the
    /// index's reversed bits and reverses its result, and the radical inverse reverses
    /// it back: so the hash's output is the first coordinate as it is, and the second
    /// is computed from it as it is (`sobol_second_reversed`). No bit reversal per draw.
    #[inline(always)]
    pub fn points(&self, index: u32) -> PaddedPoints {
        let prepared = hash_prepared(index);
        let mut p = PaddedPoints::default();
        for (((x, y), &order), (&shift_x, &shift_y)) in
            p.x.iter_mut()
                .zip(&mut p.y)
                .zip(&self.order)
                .zip(self.shift_x.iter().zip(&self.shift_y))
        {
            let h = owen_hash(prepared, order);
            *x = h ^ shift_x;
            *y = sobol_second_reversed(h) ^ shift_y;
        }
        p
    }
}

/// A nested uniform scramble of `x` seeded by `seed`: each bit flipped by a hash of the
/// bits above it. Laine and Karras's hash with Burley's constants (Burley 2020,
/// "Practical Hash-based Owen Scrambling") flips each bit by the bits below it, as
/// multiplication and addition carry only upwards; on the reversed bits that is above.
#[cfg(test)]
fn owen_scramble(x: u32, seed: u32) -> u32 {
    owen_hash(hash_prepared(x), seed).reverse_bits()
}

/// The hash's first step, on the index's reversed bits: it does not depend on the
/// seed, so [`PaddedScrambles::points`] takes it once for all draws.
#[inline]
fn hash_prepared(index: u32) -> u32 {
    let v = index.reverse_bits();
    v ^ v.wrapping_mul(0x3d20_adea)
}

/// The hash's seeded steps, after [`hash_prepared`].
#[inline]
fn owen_hash(prepared: u32, seed: u32) -> u32 {
    let mut v = prepared.wrapping_add(seed);
    v = v.wrapping_mul((seed >> 16) | 1);
    v ^= v.wrapping_mul(0x0552_6c56);
    v ^ v.wrapping_mul(0x53a2_2864)
}

/// The second dimension of the Sobol sequence as 32 bits: the generator matrix's
/// columns are v_{k+1} = v_k ^ (v_k >> 1) from v_0 = 2^31, so column k sets output bit
/// 31 − j where the binomial C(k, j) is odd (Pascal's triangle mod 2), by Lucas's
/// theorem where the bits of j are a subset of those of k.
#[inline]
pub(super) fn sobol_second(index: u32) -> u32 {
    sobol_second_reversed(index.reverse_bits())
}

/// `sobol_second(h.reverse_bits())`. With the index's bits reversed, input bit 31 − k
/// reaches output bit 31 − j where j ⊆ k, that is where 31 − k ⊆ 31 − j: each output
/// bit m is the XOR of the input bits at the subsets of m: the subset-sum (zeta)
/// transform over GF(2), taken one bit of m at a time in five shift-and-mask steps.
/// No tables, so the draws of a sample compute side by side in vector registers.
#[inline]
fn sobol_second_reversed(mut h: u32) -> u32 {
    h ^= (h << 1) & 0xaaaa_aaaa;
    h ^= (h << 2) & 0xcccc_cccc;
    h ^= (h << 4) & 0xf0f0_f0f0;
    h ^= (h << 8) & 0xff00_ff00;
    h ^ ((h << 16) & 0xffff_0000)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scrambles(seed: u32, pixel: u32) -> PaddedScrambles {
        // Any random words: a small hash stands in for the pixel's stream.
        let mut state = (seed as u64) << 32 | pixel as u64;
        PaddedScrambles::new(|| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 32) as u32
        })
    }

    /// The shift-and-mask steps give the generator matrix's product bit by bit.
    #[test]
    fn sobol_second_matches_the_matrix() {
        let by_bits = |mut index: u32| {
            let (mut v, mut bits) = (1u32 << 31, 0u32);
            while index != 0 {
                if index & 1 != 0 {
                    bits ^= v;
                }
                index >>= 1;
                v ^= v >> 1;
            }
            bits
        };
        let mut state = 7u64;
        let mut random = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 32) as u32
        };
        for i in (0..4096).chain((0..4096).map(|_| random())) {
            assert_eq!(sobol_second(i), by_bits(i), "index {i}");
        }
    }

    /// The scramble is a bijection on every aligned block of 2^m indices.
    #[test]
    fn scramble_maps_blocks_onto_blocks() {
        for seed in [0u32, 1, 0xdead_beef, 12345] {
            for (start, m) in [(0u32, 8u32), (256, 8), (4096, 10), (0, 12)] {
                let n = 1u32 << m;
                let mut seen = vec![false; n as usize];
                let block = owen_scramble(start, seed) >> m;
                for i in start..start + n {
                    let j = owen_scramble(i, seed);
                    assert_eq!(j >> m, block, "seed {seed}: {i} left its block");
                    assert!(
                        !seen[(j & (n - 1)) as usize],
                        "seed {seed}: {i} -> {j} twice"
                    );
                    seen[(j & (n - 1)) as usize] = true;
                }
            }
        }
    }

    /// With the first 2^m samples (and any later aligned 2^m), every draw's points fill
    /// each elementary interval of area 2^-m once.
    #[test]
    fn each_draw_is_a_net() {
        let m = 8u32;
        let n = 1u32 << m;
        let s = scrambles(11, 5);
        for start in [0, n, 5 * n] {
            for draw in 0..STRATIFIED_DRAWS {
                for j in 0..=m {
                    let (nx, ny) = (1u32 << j, 1u32 << (m - j));
                    let mut seen = vec![0u32; (nx * ny) as usize];
                    for i in start..start + n {
                        let [x, y] = s.point(draw, i);
                        let cx = if j == 0 { 0 } else { x >> (32 - j) };
                        let cy = if j == m { 0 } else { y >> (32 - (m - j)) };
                        seen[(cy * nx + cx) as usize] += 1;
                    }
                    assert!(seen.iter().all(|&c| c == 1), "draw {draw}, {nx}x{ny}");
                }
            }
        }
    }

    /// Two draws of the same samples are not tied to each other: the pairs (draw k,
    /// draw l) of 256 samples fall in about as many of 16 × 16 cells as random pairs
    /// would (162 expected). An XOR of the index (the sequence is linear) would put
    /// them on 16 cells only.
    #[test]
    fn draws_are_not_tied_to_each_other() {
        let n = 256u32;
        for pixel in 0..8 {
            let s = scrambles(3, pixel);
            for (k, l) in [(0, 1), (1, 2), (0, 7), (3, 5)] {
                let mut cells = vec![false; 256];
                for i in 0..n {
                    let (a, b) = (s.point(k, i)[0] >> 28, s.point(l, i)[0] >> 28);
                    cells[(a * 16 + b) as usize] = true;
                }
                let met = cells.iter().filter(|&&c| c).count();
                assert!(met > 120, "pixel {pixel}, draws {k} {l}: {met} cells");
            }
        }
    }

    /// Over pixels, a draw of one sample is uniform: mean 1/2 and E[x²] 1/3 within 5
    /// standard errors.
    #[test]
    fn each_draw_is_uniform_over_pixels() {
        let pixels = 20_000u32;
        for index in [0u32, 37, 1000] {
            for draw in [0, 3, STRATIFIED_DRAWS - 1] {
                let (mut s1, mut s2) = (0.0f64, 0.0f64);
                for pixel in 0..pixels {
                    let [x, _] = scrambles(9, pixel).point(draw, index);
                    let x = x as f64 / 4_294_967_296.0;
                    (s1, s2) = (s1 + x, s2 + x * x);
                }
                let nf = pixels as f64;
                let (se1, se2) = ((1.0 / 12.0 / nf).sqrt(), (4.0 / 45.0 / nf).sqrt());
                assert!(
                    (s1 / nf - 0.5).abs() < 5.0 * se1,
                    "sample {index} draw {draw}"
                );
                assert!(
                    (s2 / nf - 1.0 / 3.0).abs() < 5.0 * se2,
                    "sample {index} draw {draw}"
                );
            }
        }
    }
}
