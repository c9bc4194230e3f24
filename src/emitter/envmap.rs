//! Mitsuba 3's `envmap` emitter (`src/emitters/envmap.cpp`): a latitude-longitude
//! image of radiance at infinity.
//!
//! Lookup, as Mitsuba: a local direction v = to_world⁻¹ d has
//!   u = atan2(v.x, −v.z) / 2π,  w = acos(v.y) / π,
//! and the radiance is the bilinear interpolation of the image at grid coordinates
//!   (u · W − ½ (mod W),  w · (H − 1)),
//! i.e. pixel column x sits at u = (x + ½)/W (periodic: column W repeats column 0) and
//! row y at w = y / (H − 1) (rows 0 and H − 1 on the poles); times `scale`.
//!
//! Sampling is this renderer's own (only the expectation must match Mitsuba): cells
//! between grid points are picked with probability ∝ max(corner luminance) · sin θ_centre
//! (> 0 wherever the bilinear radiance can be), and a point uniformly within the cell:
//!   pdf(ω) = p_cell · W (H − 1) / (2π² sin θ).

use std::f32::consts::PI;

use glam::{Mat3, Vec2, Vec3, Vec3A};

#[derive(Clone, Debug)]
pub struct EnvMap {
    /// The image's width W and height H.
    width: usize,
    height: usize,
    /// (W + 1) × H linear RGB, the last column a copy of the first.
    data: Vec<Vec3>,
    scale: f32,
    to_world: Mat3,
    to_local: Mat3,
    /// Cells: W × (H − 1). Marginal CDF over cell rows, conditional CDFs per row.
    row_cdf: Vec<f32>,
    col_cdf: Vec<f32>,
    /// Probability of each cell.
    cell_p: Vec<f32>,
    /// Every [`BLOCK`]-th entry of each row's `col_cdf` (the first of each block):
    /// a sample's column search reads this small table, then one block of the row,
    /// instead of stepping through the whole row (a cache miss a step on a large map).
    col_coarse: Vec<f32>,
}

/// Entries of a row's column CDF per block of the two-level search (a cache line).
const BLOCK: usize = 16;

/// Entries of each row's coarse table: a row of the column CDF has W + 1 entries.
fn coarse_blocks(width: usize) -> usize {
    (width + 1).div_ceil(BLOCK)
}

/// The first index i of the ascending `row` with row[i] > s (`partition_point`),
/// found through `coarse` = row[0], row[BLOCK], row[2 BLOCK], …: the block where
/// coarse first exceeds s bounds it, and only that block of `row` is searched.
fn first_above(row: &[f32], coarse: &[f32], s: f32) -> usize {
    let b = coarse.partition_point(|&c| c <= s);
    if b == 0 {
        return 0;
    }
    // row[BLOCK (b − 1)] ≤ s, and row[BLOCK b] > s where that exists.
    let start = BLOCK * (b - 1);
    let end = (BLOCK * b + 1).min(row.len());
    start + row[start..end].partition_point(|&c| c <= s)
}

/// Mitsuba's `luminance` of linear sRGB.
fn luminance(c: Vec3) -> f32 {
    0.212_671 * c.x + 0.715_160 * c.y + 0.072_169 * c.z
}

impl EnvMap {
    /// `pixels`: row-major W × H linear RGB (row 0 at the top = the +y pole).
    /// `to_world` must be a rotation (checked by the caller).
    pub fn new(
        width: usize,
        height: usize,
        pixels: &[[f32; 3]],
        scale: f32,
        to_world: Mat3,
    ) -> Self {
        let w1 = width + 1;
        let mut data = Vec::with_capacity(w1 * height);
        for y in 0..height {
            let row = &pixels[y * width..(y + 1) * width];
            data.extend(row.iter().map(|p| Vec3::from(*p)));
            data.push(Vec3::from(row[0]));
        }
        let cells_y = height - 1;
        let mut weight = vec![0f32; width * cells_y];
        for cy in 0..cells_y {
            let sin_centre = (((cy as f32 + 0.5) / cells_y as f32) * PI).sin();
            for cx in 0..width {
                let corner = |x: usize, y: usize| luminance(data[y * w1 + x]).max(0.0);
                let m = corner(cx, cy)
                    .max(corner(cx + 1, cy))
                    .max(corner(cx, cy + 1))
                    .max(corner(cx + 1, cy + 1));
                weight[cy * width + cx] = m * sin_centre;
            }
        }
        let total: f64 = weight.iter().map(|&x| x as f64).sum();
        // An all-black map: sample uniformly (it contributes nothing anyway).
        if total <= 0.0 {
            weight.iter_mut().for_each(|x| *x = 1.0);
        }
        let total: f64 = weight.iter().map(|&x| x as f64).sum();
        let cell_p: Vec<f32> = weight.iter().map(|&x| (x as f64 / total) as f32).collect();
        let mut row_cdf = vec![0f32; cells_y + 1];
        let mut col_cdf = vec![0f32; (width + 1) * cells_y];
        let mut acc_rows = 0f64;
        for cy in 0..cells_y {
            let row: f64 = weight[cy * width..(cy + 1) * width]
                .iter()
                .map(|&x| x as f64)
                .sum();
            let mut acc = 0f64;
            for cx in 0..width {
                acc += weight[cy * width + cx] as f64;
                col_cdf[cy * (width + 1) + cx + 1] = if row > 0.0 {
                    (acc / row) as f32
                } else {
                    (cx + 1) as f32 / width as f32
                };
            }
            acc_rows += row;
            row_cdf[cy + 1] = (acc_rows / total) as f32;
        }
        let blocks = coarse_blocks(width);
        let col_coarse = (0..cells_y)
            .flat_map(|cy| {
                let row = &col_cdf[cy * (width + 1)..(cy + 1) * (width + 1)];
                (0..blocks).map(move |b| row[b * BLOCK])
            })
            .collect();
        EnvMap {
            width,
            height,
            data,
            scale,
            to_world,
            to_local: to_world.transpose(),
            row_cdf,
            col_cdf,
            cell_p,
            col_coarse,
        }
    }

    /// Local direction → (u, w) in [0, 1]².
    fn uv(v: Vec3) -> (f32, f32) {
        let u = v.x.atan2(-v.z) * (0.5 / PI);
        let w = v.y.clamp(-1.0, 1.0).acos() / PI;
        (u - u.floor(), w)
    }

    /// (u, w) → grid coordinates (gx ∈ [0, W), gy ∈ [0, H − 1]).
    fn grid(&self, u: f32, w: f32) -> (f32, f32) {
        let gx = u * self.width as f32 - 0.5;
        let gx = gx - (gx / self.width as f32).floor() * self.width as f32;
        (gx.max(0.0), w * (self.height - 1) as f32)
    }

    /// The mean radiance over the sphere of directions (rows weighted by sin θ, the
    /// solid angle they cover).
    pub fn mean_radiance(&self) -> Vec3 {
        let w1 = self.width + 1;
        let (mut sum, mut weight) = (Vec3::ZERO, 0.0f32);
        for y in 0..self.height {
            let sin_theta = (y as f32 / (self.height - 1).max(1) as f32 * PI).sin();
            for x in 0..self.width {
                sum += self.data[y * w1 + x] * sin_theta;
            }
            weight += sin_theta * self.width as f32;
        }
        if weight > 0.0 {
            sum / weight * self.scale
        } else {
            Vec3::ZERO
        }
    }

    /// Radiance arriving along a ray travelling in world direction `d`.
    pub fn eval(&self, d: Vec3A) -> Vec3 {
        let (_, gx, gy) = self.locate(d);
        self.at_grid(gx, gy)
    }

    /// World direction `d` → its local direction and grid coordinates (gx, gy).
    fn locate(&self, d: Vec3A) -> (Vec3, f32, f32) {
        let v = self.to_local * Vec3::from(d);
        let (u, w) = Self::uv(v);
        let (gx, gy) = self.grid(u, w);
        (v, gx, gy)
    }

    /// The bilinear radiance at grid coordinates (gx, gy), times `scale`.
    fn at_grid(&self, gx: f32, gy: f32) -> Vec3 {
        let w1 = self.width + 1;
        let x = (gx as usize).min(self.width - 1);
        let y = (gy as usize).min(self.height - 2);
        let (fx, fy) = (gx - x as f32, gy - y as f32);
        let at = |x: usize, y: usize| self.data[y * w1 + x];
        let top = at(x, y) * (1.0 - fx) + at(x + 1, y) * fx;
        let bottom = at(x, y + 1) * (1.0 - fx) + at(x + 1, y + 1) * fx;
        (top * (1.0 - fy) + bottom * fy) * self.scale
    }

    /// Samples a world direction toward the environment; (direction, solid-angle pdf,
    /// radiance from it). The radiance is looked up at the sampled grid point, which
    /// is where [`EnvMap::eval`] of the direction looks (to rounding), without the
    /// direction's atan2 and acos.
    pub fn sample(&self, s: Vec2) -> Option<(Vec3A, f32, Vec3)> {
        let cells_y = self.height - 1;
        let cy = self
            .row_cdf
            .partition_point(|&c| c <= s.x)
            .clamp(1, cells_y)
            - 1;
        let (r0, r1) = (self.row_cdf[cy], self.row_cdf[cy + 1]);
        let fy = if r1 > r0 {
            ((s.x - r0) / (r1 - r0)).clamp(0.0, 1.0)
        } else {
            0.5
        };
        let row = &self.col_cdf[cy * (self.width + 1)..(cy + 1) * (self.width + 1)];
        let blocks = coarse_blocks(self.width);
        let coarse = &self.col_coarse[cy * blocks..(cy + 1) * blocks];
        let cx = first_above(row, coarse, s.y).clamp(1, self.width) - 1;
        let (c0, c1) = (row[cx], row[cx + 1]);
        let fx = if c1 > c0 {
            ((s.y - c0) / (c1 - c0)).clamp(0.0, 1.0)
        } else {
            0.5
        };
        let p = self.cell_p[cy * self.width + cx];
        if p <= 0.0 {
            return None;
        }
        let (gx, gy) = (cx as f32 + fx, cy as f32 + fy);
        let u = (gx + 0.5) / self.width as f32;
        let w = gy / cells_y as f32;
        let (theta, phi) = (w * PI, u * 2.0 * PI);
        let (st, ct) = theta.sin_cos();
        let (sp, cp) = phi.sin_cos();
        if st <= 0.0 {
            return None;
        }
        let local = Vec3::new(sp * st, ct, -cp * st);
        let pdf = p * (self.width * cells_y) as f32 / (2.0 * PI * PI * st);
        Some((
            Vec3A::from(self.to_world * local).normalize(),
            pdf,
            self.at_grid(gx, gy),
        ))
    }

    /// The solid-angle pdf with which `sample` produces world direction `d`.
    pub fn pdf(&self, d: Vec3A) -> f32 {
        let (v, gx, gy) = self.locate(d);
        self.pdf_at(v, gx, gy)
    }

    /// [`EnvMap::eval`] and [`EnvMap::pdf`] of one direction (a ray that escapes after
    /// a BSDF or phase sample needs both), its texel found once: the same values.
    pub fn eval_and_pdf(&self, d: Vec3A) -> (Vec3, f32) {
        let (v, gx, gy) = self.locate(d);
        (self.at_grid(gx, gy), self.pdf_at(v, gx, gy))
    }

    /// The pdf of the local direction `v` at grid coordinates (gx, gy).
    fn pdf_at(&self, v: Vec3, gx: f32, gy: f32) -> f32 {
        let cells_y = self.height - 1;
        let cx = (gx as usize).min(self.width - 1);
        let cy = (gy as usize).min(cells_y - 1);
        let st = (v.x * v.x + v.z * v.z).sqrt();
        if st <= 0.0 {
            return 0.0;
        }
        self.cell_p[cy * self.width + cx] * (self.width * cells_y) as f32 / (2.0 * PI * PI * st)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn test_map() -> EnvMap {
        // Wider than a block of the column search.
        let (w, h) = (40, 5);
        let px: Vec<[f32; 3]> = (0..w * h)
            .map(|i| [(i % 7) as f32 * 0.3 + 0.1, (i % 3) as f32, 0.5])
            .collect();
        EnvMap::new(w, h, &px, 2.0, Mat3::from_rotation_y(0.4))
    }

    /// ∫ pdf dω = 1 and E[L / pdf] = ∫ L dω, against a fine quadrature over the sphere.
    #[test]
    fn sampling_density_integrates_to_one_and_is_consistent() {
        let m = test_map();
        let n = 400;
        let (mut norm, mut integral) = (0f64, Vec3::ZERO.as_dvec3());
        for i in 0..n {
            for j in 0..2 * n {
                let theta = (i as f64 + 0.5) / n as f64 * std::f64::consts::PI;
                let phi = (j as f64 + 0.5) / (2 * n) as f64 * 2.0 * std::f64::consts::PI;
                let d = Vec3A::new(
                    (theta.sin() * phi.cos()) as f32,
                    theta.cos() as f32,
                    (theta.sin() * phi.sin()) as f32,
                );
                let dw = theta.sin()
                    * (std::f64::consts::PI / n as f64)
                    * (std::f64::consts::PI / n as f64);
                norm += m.pdf(d) as f64 * dw;
                integral += m.eval(d).as_dvec3() * dw;
            }
        }
        assert!((norm - 1.0).abs() < 5e-3, "∫pdf = {norm}");
        let mut est = Vec3::ZERO.as_dvec3();
        let k = 400;
        for i in 0..k {
            for j in 0..k {
                let s = Vec2::new((i as f32 + 0.5) / k as f32, (j as f32 + 0.5) / k as f32);
                if let Some((d, pdf, radiance)) = m.sample(s) {
                    assert!(
                        (m.pdf(d) - pdf).abs() <= 2e-3 * pdf,
                        "pdf {pdf} vs {}",
                        m.pdf(d)
                    );
                    // The sample's radiance is the lookup of its direction.
                    let looked_up = m.eval(d);
                    assert!(
                        (radiance - looked_up).abs().max_element()
                            <= 1e-3 * looked_up.max_element().max(1e-3),
                        "sampled {radiance} vs looked up {looked_up}"
                    );
                    est += (radiance / pdf).as_dvec3();
                }
            }
        }
        est /= (k * k) as f64;
        let rel = ((est - integral) / integral).abs().max_element();
        assert!(rel < 5e-3, "E[L/pdf] = {est:?}, ∫L = {integral:?}");
    }

    /// The two-level column search finds what a search of the whole row finds, on rows
    /// of every length around the block size, with flat runs (cells of zero weight)
    /// and searched values equal to entries.
    #[test]
    fn column_search_matches_partition_point() {
        let mut rng = crate::sampling::Pcg32::new(7, 3);
        for len in 1..4 * BLOCK + 3 {
            for _ in 0..50 {
                let mut acc = 0.0f32;
                let row: Vec<f32> = (0..len)
                    .map(|i| {
                        if i > 0 && rng.next_1d() < 0.6 {
                            acc += rng.next_1d();
                        }
                        acc
                    })
                    .collect();
                let coarse: Vec<f32> = row.iter().step_by(BLOCK).copied().collect();
                for k in 0..40 {
                    let s = if k % 2 == 0 {
                        row[(rng.next_1d() * len as f32) as usize % len]
                    } else {
                        (rng.next_1d() * 1.2 - 0.1) * acc.max(1.0)
                    };
                    assert_eq!(
                        first_above(&row, &coarse, s),
                        row.partition_point(|&c| c <= s),
                        "row {row:?}, s {s}"
                    );
                }
            }
        }
    }

    /// Pixel centres: column x at u = (x + ½)/W, row 0 at the +y pole.
    #[test]
    fn lookup_hits_pixel_centres() {
        let (w, h) = (4, 3);
        let px: Vec<[f32; 3]> = (0..w * h).map(|i| [i as f32, 0.0, 0.0]).collect();
        let m = EnvMap::new(w, h, &px, 1.0, Mat3::IDENTITY);
        // Row 1 (the equator), column 2: u = 2.5 / 4 → φ = 1.25 π.
        let phi = 2.5 / 4.0 * 2.0 * PI;
        let d = Vec3A::new(phi.sin(), 0.0, -phi.cos());
        assert!((m.eval(d).x - 6.0).abs() < 1e-4, "{}", m.eval(d).x);
        assert!(
            (m.eval(Vec3A::Y).x - 1.5).abs() < 1e-4,
            "pole: {}",
            m.eval(Vec3A::Y).x
        );
    }
}
