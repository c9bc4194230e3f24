//! Bounds on a one-channel grid's lookups, cell by cell, so that delta tracking decides
//! most tentative collisions without reading the grid.
//!
//! At a tentative collision delta tracking draws u and takes the collision as real when
//! u < P(σ_t(x)) (`heterogeneous::real_probability`), P rising with σ_t. Where every
//! lookup inside a cell lies in [lo, hi], u < P(lo) means real and u ≥ P(hi) null
//! whatever the lookup would return, and for a grey σ_t neither kind of collision needs
//! the value for its weight (both weights are 1). So a lookup is made only when u falls
//! between P(lo) and P(hi): the same decisions, and the same image, with a fraction of
//! the reads. In a grid larger than the cache each read is a miss; the cells (a few per
//! side of a local majorant's) stay in the cache.
//!
//! Ratio tracking (shadow rays) weighs each tentative collision by σ_t itself: it reads
//! the grid except, in lanes, in a cell whose hi is 0 (its factor exactly 1).

use super::grid::{nearest_offset, Filter, GridData, Volume, Wrap};
use super::majorant::cell_ranges;
use crate::simd::Gather;

/// Voxels a side of a cell.
const CELL_VOXELS: usize = 8;

/// Relative margin on each bound: a trilinear lookup's weights sum to 1 only up to
/// rounding.
const MARGIN: f32 = 1e-5;

#[derive(Clone, Debug)]
pub struct LookupBounds {
    res: [usize; 3],
    /// [lo, hi] of the lookups in each cell (before the medium's scale), x fastest.
    cells: Vec<[f32; 2]>,
}

impl LookupBounds {
    /// The bounds of `volume`'s lookups where it is a one-channel grid with clamped
    /// lookups (the other volumes are read at every tentative collision).
    pub fn new(volume: &Volume) -> Option<LookupBounds> {
        let (grid, filter) = volume.clamped_grid()?;
        (grid.channels == 1).then(|| Self::of_grid(grid, filter))
    }

    fn of_grid(grid: &GridData, filter: Filter) -> LookupBounds {
        let res = grid.res.map(|n| n.div_ceil(CELL_VOXELS));
        let cells = cell_ranges(grid, res, filter)
            .into_iter()
            .map(|[lo, hi]| [lo * (1.0 - MARGIN), hi * (1.0 + MARGIN)])
            .collect();
        LookupBounds { res, cells }
    }

    /// The cells' count per axis.
    #[inline(always)]
    pub fn res(&self) -> [usize; 3] {
        self.res
    }

    /// These bounds with every hi times `f` (for tests: bounds that are wrong).
    #[cfg(test)]
    pub fn with_hi_times(&self, f: f32) -> LookupBounds {
        let cells = self.cells.iter().map(|&[lo, hi]| [lo, hi * f]).collect();
        LookupBounds {
            res: self.res,
            cells,
        }
    }

    /// [lo, hi] of the lookups at local point `q`.
    #[inline(always)]
    pub fn at(&self, q: [f32; 3]) -> [f32; 2] {
        self.at_lanes(q, true)
    }

    /// [lo, hi] of the lookups at local points `q` in the lanes of `mask` (0 in the
    /// others): [`LookupBounds::at`] over any number type.
    #[inline(always)]
    pub fn at_lanes<F: Gather>(&self, q: [F; 3], mask: F::Mask) -> [F; 2] {
        // The outer cells take everything beyond the cube, whose clamped lookups read
        // their voxels.
        let [rx, ry, rz] = self.res;
        let i = nearest_offset(q[0], rx, 1, Wrap::Clamp)
            + nearest_offset(q[1], ry, rx, Wrap::Clamp)
            + nearest_offset(q[2], rz, rx * ry, Wrap::Clamp);
        let cells = self.cells.as_flattened();
        [
            F::gather(cells, i, 2, 0, mask),
            F::gather(cells, i, 2, 1, mask),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::medium::grid::{parse_vol, write_vol};
    use crate::medium::grid::{Source, Wrap};
    use crate::sampling::Pcg32;
    use glam::{Affine3A, Vec3, Vec3A};

    /// A ramp along x with a little noise, and where `spiky` one voxel of 40.
    fn volume(res: [usize; 3], filter: Filter, spiky: bool) -> Volume {
        let mut rng = Pcg32::new(7, 9);
        let n = res[0] * res[1] * res[2];
        let data: Vec<f32> = (0..n)
            .map(|i| {
                let ramp = (i % res[0]) as f32 / res[0] as f32;
                if spiky && i == n / 2 {
                    40.0
                } else {
                    ramp + 0.1 * rng.next_1d()
                }
            })
            .collect();
        let grid = parse_vol(&write_vol(res, 1, &data)).unwrap();
        let to_world = Affine3A::from_scale_rotation_translation(
            Vec3::new(2.0, 1.0, 3.0),
            glam::Quat::from_rotation_y(0.4),
            Vec3::new(-1.0, 0.5, 0.0),
        );
        Volume::new(
            Source::Grid {
                grid,
                filter,
                wrap: Wrap::Clamp,
            },
            to_world,
        )
    }

    /// Every lookup, inside the cube, on cell faces and beyond it, lies within its
    /// cell's bounds; and the bounds are tight enough to matter (most cells' ranges
    /// are well inside [0, max]).
    #[test]
    fn every_lookup_lies_within_its_cells_bounds() {
        for (res, filter) in [
            ([19, 8, 33], Filter::Trilinear),
            ([16, 16, 16], Filter::Trilinear),
            ([9, 17, 5], Filter::Nearest),
        ] {
            let v = volume(res, filter, true);
            let b = LookupBounds::new(&v).unwrap();
            let mut rng = Pcg32::new(1, 2);
            for i in 0..200_000 {
                // A third of the points on a cell face of some axis, some outside.
                let mut q = [0f32; 3];
                for (k, qk) in q.iter_mut().enumerate() {
                    *qk = rng.next_1d() * 1.4 - 0.2;
                    if i % 3 == k {
                        *qk = (*qk * b.res()[k] as f32).round() / b.res()[k] as f32;
                    }
                }
                let world = v.to_local.inverse().transform_point3a(Vec3A::from_array(q));
                let value = v.eval(world).x;
                let local = v.to_local.transform_point3a(world);
                let [lo, hi] = b.at(local.to_array());
                assert!(
                    lo <= value && value <= hi,
                    "{q:?}: {value} not in [{lo}, {hi}]"
                );
            }
            // A cell away from the spike is bounded by its own voxels: of the grid's
            // range (0 to 40) most cells span less than their stretch of the ramp
            // and the noise.
            let narrow = b.cells.iter().filter(|c| c[1] - c[0] < 0.8).count();
            assert!(narrow * 2 > b.cells.len(), "{narrow} of {}", b.cells.len());
        }
    }

    #[test]
    fn rgb_constant_and_wrapping_volumes_get_none() {
        let grid = parse_vol(&write_vol([2, 2, 2], 3, &[1.0; 24])).unwrap();
        let rgb = Volume::new(
            Source::Grid {
                grid: grid.clone(),
                filter: Filter::Trilinear,
                wrap: Wrap::Clamp,
            },
            Affine3A::IDENTITY,
        );
        assert!(LookupBounds::new(&rgb).is_none());
        let grey = parse_vol(&write_vol([2, 2, 2], 1, &[1.0; 8])).unwrap();
        let repeat = Volume::new(
            Source::Grid {
                grid: grey,
                filter: Filter::Trilinear,
                wrap: Wrap::Repeat,
            },
            Affine3A::IDENTITY,
        );
        assert!(LookupBounds::new(&repeat).is_none());
        let constant = Volume::new(Source::Const(Vec3::ONE), Affine3A::IDENTITY);
        assert!(LookupBounds::new(&constant).is_none());
        assert!(LookupBounds::new(&volume([4, 4, 4], Filter::Trilinear, false)).is_some());
    }
}
