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
/// the index scramble and the digital shift.
#[derive(Clone, Copy, Debug)]
pub struct PaddedScrambles {
    order: [u32; STRATIFIED_DRAWS],
    shift: [[u32; 2]; STRATIFIED_DRAWS],
}

impl PaddedScrambles {
    /// The scrambles from `3 · STRATIFIED_DRAWS` random words (the pixel's own
    /// stream's, so that draws are independent of each other and of the path's).
    pub fn new(mut word: impl FnMut() -> u32) -> Self {
        let mut s = PaddedScrambles {
            order: [0; STRATIFIED_DRAWS],
            shift: [[0; 2]; STRATIFIED_DRAWS],
        };
        for k in 0..STRATIFIED_DRAWS {
            s.order[k] = word();
            s.shift[k] = [word(), word()];
        }
        s
    }

    /// Point `index` of draw `draw`: (radical inverse, Sobol's second dimension) of the
    /// scrambled index, shifted.
    #[inline]
    pub fn point(&self, draw: usize, index: u32) -> [u32; 2] {
        let j = owen_scramble(index, self.order[draw]);
        [
            j.reverse_bits() ^ self.shift[draw][0],
            sobol_second(j) ^ self.shift[draw][1],
        ]
    }
}

/// A nested uniform scramble of `x` seeded by `seed`: each bit flipped by a hash of the
/// bits above it. Laine and Karras's hash with Burley's constants (Burley 2020,
/// "Practical Hash-based Owen Scrambling") flips each bit by the bits below it, as
/// multiplication and addition carry only upwards; on the reversed bits that is above.
#[inline]
fn owen_scramble(x: u32, seed: u32) -> u32 {
    let mut v = x.reverse_bits();
    v ^= v.wrapping_mul(0x3d20_adea);
    v = v.wrapping_add(seed);
    v = v.wrapping_mul((seed >> 16) | 1);
    v ^= v.wrapping_mul(0x0552_6c56);
    v ^= v.wrapping_mul(0x53a2_2864);
    v.reverse_bits()
}

/// The second dimension of the Sobol sequence as 32 bits: the generator matrix's
/// columns are v_{k+1} = v_k ^ (v_k >> 1) from v_0 = 2^31. The product with the index
/// is the XOR of the columns of its set bits, read a byte at a time from tables of
/// every byte's XOR (`SOBOL_SECOND_BYTES`).
#[inline]
pub(super) fn sobol_second(index: u32) -> u32 {
    let t = &SOBOL_SECOND_BYTES;
    t[0][(index & 0xff) as usize]
        ^ t[1][((index >> 8) & 0xff) as usize]
        ^ t[2][((index >> 16) & 0xff) as usize]
        ^ t[3][(index >> 24) as usize]
}

/// Per byte b of an index and per value of it, the XOR of the generator columns
/// 8b..8b+8 its set bits pick.
static SOBOL_SECOND_BYTES: [[u32; 256]; 4] = sobol_second_bytes();

const fn sobol_second_bytes() -> [[u32; 256]; 4] {
    let mut columns = [0u32; 32];
    let mut v = 1u32 << 31;
    let mut k = 0;
    while k < 32 {
        columns[k] = v;
        v ^= v >> 1;
        k += 1;
    }
    let mut t = [[0u32; 256]; 4];
    let mut b = 0;
    while b < 4 {
        let mut x = 0;
        while x < 256 {
            let mut bits = 0u32;
            let mut i = 0;
            while i < 8 {
                if x & (1 << i) != 0 {
                    bits ^= columns[8 * b + i];
                }
                i += 1;
            }
            t[b][x] = bits;
            x += 1;
        }
        b += 1;
    }
    t
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

    /// The tables give the generator matrix's product bit by bit.
    #[test]
    fn sobol_second_tables_match_the_matrix() {
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
