//! Mitsuba 3's volume data sources (`src/volumes/grid.cpp`, `src/volumes/const.cpp`):
//! a value per point of space, constant or interpolated in a 3D grid read from
//! Mitsuba's binary `.vol` file (`src/render/volumegrid.cpp`).
//!
//! A volume lives in its local unit cube [0, 1]³, placed in the world by its
//! `to_world`; its bounding box is that cube's image (`Volume::update_bbox`), which a
//! `heterogeneous` medium uses as the extent of its extinction.
//!
//! Lookups follow Dr.Jit's `Texture3f` (`drjit/texture.h`): for `trilinear`, the local
//! point scaled to voxel units less one half, `x = p · res − 0.5`, is split into
//! `⌊x⌋` and weights `x − ⌊x⌋`, and the 8 voxel indices are wrapped (`clamp`, `repeat`,
//! `mirror`) before fetching; for `nearest`, the voxel `⌊p · res⌋`, wrapped.

use glam::{Affine3A, Vec3, Vec3A};

use crate::simd::{Gather, Vector3};

/// The `.vol` header's size: "VOL", version, encoding, 3 resolutions, channels, bbox.
pub const VOL_HEADER_BYTES: usize = 3 + 1 + 4 + 3 * 4 + 4 + 6 * 4;

/// How a lookup between voxels is filtered (Mitsuba's `filter_type`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Filter {
    Trilinear,
    Nearest,
}

/// What a lookup outside [0, 1]³ reads (Mitsuba's `wrap_mode`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Wrap {
    Clamp,
    Repeat,
    Mirror,
}

impl Wrap {
    /// The offset (index times `stride`) of the voxel that integral coordinate `i`
    /// reads along an axis of `n` voxels, on the axis in every mode: a NaN coordinate
    /// (a point at infinity) reads a voxel of the grid, never outside it.
    #[inline(always)]
    fn index<F: Gather>(self, i: F, n: usize, stride: usize) -> F::Index {
        match self {
            Wrap::Clamp => i.clamp_index(n, stride),
            Wrap::Repeat => i.repeat_index(n, stride),
            Wrap::Mirror => i.mirror_index(n, stride),
        }
    }
}

/// Voxel data of a `.vol` file: `data[((z · ny + y) · nx + x) · channels + c]`.
#[derive(Clone, Debug)]
pub struct GridData {
    pub res: [usize; 3],
    /// 1 (a scalar, read as grey) or 3 (RGB).
    pub channels: usize,
    pub data: Vec<f32>,
    /// The bounding box stored in the file (used with `use_grid_bbox`).
    pub file_bbox: [Vec3; 2],
}

impl GridData {
    /// The largest value over all voxels and channels (Mitsuba's `VolumeGrid::max`).
    pub fn max(&self) -> f32 {
        self.data.iter().copied().fold(f32::NEG_INFINITY, f32::max)
    }
}

/// Why a `.vol` file cannot be read.
#[derive(Debug, PartialEq)]
pub enum VolError {
    NotVol,
    Version(u8),
    Encoding(i32),
    Size { res: [i64; 3], channels: i64 },
    Truncated { expected: u64, found: u64 },
    BadValue { index: usize, value: f32 },
}

impl std::fmt::Display for VolError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            VolError::NotVol => write!(f, "not a Mitsuba volume file (it does not start with \"VOL\")"),
            VolError::Version(v) => write!(f, "version {v}: only version 3 is supported"),
            VolError::Encoding(e) => write!(f, "encoding {e}: only 1 (float32) is supported"),
            VolError::Size { res, channels } => write!(
                f,
                "header gives {}×{}×{} voxels of {channels} channels: each resolution must be ≥ 1, the channels 1 or 3, and the grid at most 2^30 values",
                res[0], res[1], res[2]
            ),
            VolError::Truncated { expected, found } => write!(
                f,
                "truncated: the header promises {expected} bytes, the file has {found}"
            ),
            VolError::BadValue { index, value } => write!(
                f,
                "value #{index} is {value}: volume values must be finite and nonnegative"
            ),
        }
    }
}

/// The most values a grid may hold (4 GiB of f32): a header asking for more is refused
/// before anything is allocated.
pub const MAX_GRID_VALUES: u64 = 1 << 30;

/// Parses a `.vol` file's bytes. The header is checked against the file's length
/// before the voxel buffer is allocated, so a corrupt header cannot ask for gigabytes.
pub fn parse_vol(bytes: &[u8]) -> Result<GridData, VolError> {
    if bytes.len() < 4 || &bytes[..3] != b"VOL" {
        return Err(VolError::NotVol);
    }
    if bytes[3] != 3 {
        return Err(VolError::Version(bytes[3]));
    }
    if bytes.len() < VOL_HEADER_BYTES {
        return Err(VolError::Truncated {
            expected: VOL_HEADER_BYTES as u64,
            found: bytes.len() as u64,
        });
    }
    let i32_at = |o: usize| i32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
    let f32_at = |o: usize| f32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
    let encoding = i32_at(4);
    if encoding != 1 {
        return Err(VolError::Encoding(encoding));
    }
    let res = [i32_at(8) as i64, i32_at(12) as i64, i32_at(16) as i64];
    let channels = i32_at(20) as i64;
    let count = res.iter().product::<i64>().saturating_mul(channels.max(0));
    if res.iter().any(|&r| r < 1)
        || !(channels == 1 || channels == 3)
        || count as u64 > MAX_GRID_VALUES
    {
        return Err(VolError::Size { res, channels });
    }
    let expected = VOL_HEADER_BYTES as u64 + 4 * count as u64;
    if (bytes.len() as u64) < expected {
        return Err(VolError::Truncated {
            expected,
            found: bytes.len() as u64,
        });
    }
    let b: Vec<f32> = (0..6).map(|k| f32_at(24 + 4 * k)).collect();
    let mut data = Vec::with_capacity(count as usize);
    for (index, c) in bytes[VOL_HEADER_BYTES..expected as usize]
        .chunks_exact(4)
        .enumerate()
    {
        let value = f32::from_le_bytes(c.try_into().unwrap());
        if !(value.is_finite() && value >= 0.0) {
            return Err(VolError::BadValue { index, value });
        }
        data.push(value);
    }
    Ok(GridData {
        res: res.map(|r| r as usize),
        channels: channels as usize,
        data,
        file_bbox: [Vec3::new(b[0], b[1], b[2]), Vec3::new(b[3], b[4], b[5])],
    })
}

/// Where a volume's values come from.
#[derive(Clone, Debug)]
pub enum Source {
    /// `constvolume` (or a plain `<float>`/`<rgb>`): one value everywhere.
    Const(Vec3),
    Grid {
        grid: GridData,
        filter: Filter,
        wrap: Wrap,
    },
}

/// A volume: its values and where its unit cube lies.
#[derive(Clone, Debug)]
pub struct Volume {
    pub source: Source,
    /// World → the volume's unit cube (Mitsuba's `m_to_local`).
    pub to_local: Affine3A,
    /// World-space bounding box of the unit cube's image.
    pub bbox: [Vec3; 2],
    /// The largest value over space and channels (Mitsuba's `Volume::max`).
    pub max: f32,
}

impl Volume {
    /// A volume placed by `to_world` (the unit cube's image is its box).
    pub fn new(source: Source, to_world: Affine3A) -> Self {
        let mut lo = Vec3::INFINITY;
        let mut hi = Vec3::NEG_INFINITY;
        for k in 0..8 {
            let c = Vec3::new((k & 1) as f32, ((k >> 1) & 1) as f32, ((k >> 2) & 1) as f32);
            let w = to_world.transform_point3(c);
            lo = lo.min(w);
            hi = hi.max(w);
        }
        let max = match &source {
            Source::Const(v) => v.max_element(),
            Source::Grid { grid, .. } => grid.max(),
        };
        Volume {
            source,
            to_local: to_world.inverse(),
            bbox: [lo, hi],
            max,
        }
    }

    /// The grid and its filter where the volume is a grid with clamped lookups
    /// (Mitsuba's default), whose lookups outside the cube read its edge voxels.
    pub fn clamped_grid(&self) -> Option<(&GridData, Filter)> {
        match &self.source {
            Source::Grid {
                grid,
                filter,
                wrap: Wrap::Clamp,
            } => Some((grid, *filter)),
            _ => None,
        }
    }

    /// How many values the volume stores (1 for a constant).
    pub fn values(&self) -> usize {
        match &self.source {
            Source::Const(_) => 1,
            Source::Grid { grid, .. } => grid.data.len(),
        }
    }

    /// Whether every point has equal channels (a 1-channel grid or a grey constant).
    pub fn is_grey(&self) -> bool {
        match &self.source {
            Source::Const(v) => v.x == v.y && v.y == v.z,
            Source::Grid { grid, .. } => grid.channels == 1,
        }
    }

    /// The value at world point `p`.
    #[inline]
    pub fn eval(&self, p: Vec3A) -> Vec3 {
        match &self.source {
            Source::Const(v) => *v,
            Source::Grid { grid, filter, wrap } => {
                let q = self.to_local.transform_point3a(p).to_array();
                let v = lookup(grid, *filter, *wrap, q, true);
                Vec3::new(v.x, v.y, v.z)
            }
        }
    }

    /// The values at world points `p` in the lanes of `mask` (0 in the others, or the
    /// constant): [`Volume::eval`] over any number type.
    #[inline(always)]
    pub fn eval_at<F: Gather>(&self, p: Vector3<F>, mask: F::Mask) -> Vector3<F> {
        match &self.source {
            Source::Const(v) => Vector3::splat(*v),
            Source::Grid { .. } => self.eval_local(self.local_point(F::point(p)), mask),
        }
    }

    /// The values at points `q` of the unit cube (`local_point`), as `eval_at`.
    #[inline(always)]
    pub fn eval_local<F: Gather>(&self, q: [F; 3], mask: F::Mask) -> Vector3<F> {
        match &self.source {
            Source::Const(v) => Vector3::splat(*v),
            Source::Grid { grid, filter, wrap } => lookup(grid, *filter, *wrap, q, mask),
        }
    }

    /// World points `p` in the volume's unit cube (`Gather::transform_point`).
    #[inline(always)]
    pub fn local_point<F: Gather>(&self, p: F::Point) -> [F; 3] {
        F::transform_point(&self.to_local, p)
    }

    /// The same volume (placement, filter, wrap, channels) holding `data` at resolution
    /// `res` instead; None for a constant.
    pub fn with_grid(&self, res: [usize; 3], data: Vec<f32>) -> Option<Volume> {
        let Source::Grid { grid, filter, wrap } = &self.source else {
            return None;
        };
        assert_eq!(data.len(), res.iter().product::<usize>() * grid.channels);
        let grid = GridData {
            res,
            channels: grid.channels,
            data,
            file_bbox: grid.file_bbox,
        };
        let source = Source::Grid {
            grid,
            filter: *filter,
            wrap: *wrap,
        };
        Some(Volume::new(source, self.to_local.inverse()))
    }

    /// The grid's values resampled at resolution `res`: each new voxel takes the value
    /// at its centre, by `filter` (nearest: Dr.Jit's `upsample` of a tensor; trilinear:
    /// the lookup's). None for a constant.
    pub fn resampled(&self, res: [usize; 3], filter: Filter) -> Option<Vec<f32>> {
        let Source::Grid { grid, wrap, .. } = &self.source else {
            return None;
        };
        let mut out = Vec::with_capacity(res.iter().product::<usize>() * grid.channels);
        for z in 0..res[2] {
            for y in 0..res[1] {
                for x in 0..res[0] {
                    let q = Vec3::new(
                        (x as f32 + 0.5) / res[0] as f32,
                        (y as f32 + 0.5) / res[1] as f32,
                        (z as f32 + 0.5) / res[2] as f32,
                    );
                    let v = lookup(grid, filter, *wrap, q.to_array(), true);
                    out.extend_from_slice(&[v.x, v.y, v.z][..grid.channels]);
                }
            }
        }
        Some(out)
    }

    /// The adjoint of [`Volume::eval`]: adds `w_c` times each stored value's weight in
    /// the lookup at `p` to `grad` (laid out as the grid's data), so that
    /// Σ grad · data changes as Σ_c w_c eval(p)_c does. A 1-channel grid's value is
    /// every channel's: it takes the sum of `w`. Nothing for a constant.
    #[inline]
    pub fn scatter(&self, p: Vec3A, w: Vec3, grad: &mut [f32]) {
        let Source::Grid { grid, filter, wrap } = &self.source else {
            return;
        };
        let q = self.to_local.transform_point3a(p).to_array();
        let mut add = |i: usize, k: f32| {
            if grid.channels == 1 {
                grad[i] += (w.x + w.y + w.z) * k;
            } else {
                for c in 0..3 {
                    grad[i * 3 + c] += w[c] * k;
                }
            }
        };
        match filter {
            Filter::Nearest => add(nearest_voxel(grid, *wrap, q), 1.0),
            Filter::Trilinear => {
                let (index, weight) = trilinear_corners(grid, *wrap, q);
                for k in 0..8 {
                    add(index[k], weight[k]);
                }
            }
        }
    }
}

// The voxels a lookup reads and their weights, for the lookup to sum along and its
// adjoint (`Volume::scatter`) to add along, so that the two agree by construction;
// written once over the number type (`simd::Gather`): one path, or lanes.

/// The voxel (its data offset over the channel count) that `nearest` reads at local
/// point `q`.
#[inline(always)]
fn nearest_voxel<F: Gather>(g: &GridData, wrap: Wrap, q: [F; 3]) -> F::Index {
    let [nx, ny, nz] = g.res;
    nearest_offset(q[0], nx, 1, wrap)
        + nearest_offset(q[1], ny, nx, wrap)
        + nearest_offset(q[2], nz, nx * ny, wrap)
}

/// Along one axis of `n` cells, the offset (the index times `stride`) of the cell that
/// local coordinate `q` falls in, ⌊q · n⌋ wrapped: `nearest`'s voxel, and the lookup
/// bounds' cell (clamped).
#[inline(always)]
pub(super) fn nearest_offset<F: Gather>(q: F, n: usize, stride: usize, wrap: Wrap) -> F::Index {
    wrap.index((q * F::of(n as f64)).floor(), n, stride)
}

/// The 8 voxels `trilinear` reads at local point `q` and their weights, x fastest, then
/// y, then z (the order the lookup sums in): `x = q · res − 0.5` split into ⌊x⌋ and
/// weights `x − ⌊x⌋`.
#[inline(always)]
fn trilinear_corners<F: Gather>(g: &GridData, wrap: Wrap, q: [F; 3]) -> ([F::Index; 8], [F; 8]) {
    // Per axis: the two voxels' offsets (the voxel index times its stride) and weights.
    #[inline(always)]
    fn axis<F: Gather>(q: F, n: usize, stride: usize, wrap: Wrap) -> ([F::Index; 2], [F; 2]) {
        let x = q * F::of(n as f64) - F::of(0.5);
        let f = x.floor();
        let w1 = x - f;
        let i0 = wrap.index(f, n, stride);
        let i1 = wrap.index(f + F::one(), n, stride);
        ([i0, i1], [F::one() - w1, w1])
    }
    let (ix, wx) = axis(q[0], g.res[0], 1, wrap);
    let (iy, wy) = axis(q[1], g.res[1], g.res[0], wrap);
    let (iz, wz) = axis(q[2], g.res[2], g.res[0] * g.res[1], wrap);
    let mut index = [ix[0]; 8];
    let mut weight = [F::zero(); 8];
    for c in 0..2 {
        for b in 0..2 {
            for a in 0..2 {
                index[4 * c + 2 * b + a] = iz[c] + iy[b] + ix[a];
                weight[4 * c + 2 * b + a] = wx[a] * wy[b] * wz[c];
            }
        }
    }
    (index, weight)
}

/// The grid's value at local point `q` (unit cube coordinates), in the lanes of `mask`
/// (0 in the others).
#[inline(always)]
fn lookup<F: Gather>(
    g: &GridData,
    filter: Filter,
    wrap: Wrap,
    q: [F; 3],
    mask: F::Mask,
) -> Vector3<F> {
    let value = |i: F::Index| match g.channels {
        1 => Vector3::all(F::gather(&g.data, i, 1, 0, mask)),
        _ => Vector3::new(
            F::gather(&g.data, i, 3, 0, mask),
            F::gather(&g.data, i, 3, 1, mask),
            F::gather(&g.data, i, 3, 2, mask),
        ),
    };
    match filter {
        Filter::Nearest => value(nearest_voxel(g, wrap, q)),
        Filter::Trilinear => {
            let (index, weight) = trilinear_corners(g, wrap, q);
            if g.channels == 1 {
                // A scalar grid (the common density): one channel summed in the same
                // order as the three below, so the value is the same to the bit.
                let mut v = F::zero();
                for k in 0..8 {
                    v = v + F::gather(&g.data, index[k], 1, 0, mask) * weight[k];
                }
                return Vector3::all(v);
            }
            let mut v = Vector3::all(F::zero());
            for k in 0..8 {
                v = v.add(value(index[k]).scale(weight[k]));
            }
            v
        }
    }
}

/// A `.vol` file's bytes (for tests and scripts' fixtures): 1 or 3 channels, bbox
/// [0, 1]³.
pub fn write_vol(res: [usize; 3], channels: usize, data: &[f32]) -> Vec<u8> {
    write_vol_in(res, channels, data, [Vec3::ZERO, Vec3::ONE])
}

/// The `.vol` bytes of `data` laid out as `grid`'s (its resolution, channels and the
/// bounding box its file had): what Mitsuba 3 reads as a volume of the same shape.
pub fn write_vol_like(grid: &GridData, data: &[f32]) -> Vec<u8> {
    write_vol_in(grid.res, grid.channels, data, grid.file_bbox)
}

fn write_vol_in(res: [usize; 3], channels: usize, data: &[f32], bbox: [Vec3; 2]) -> Vec<u8> {
    let mut out = b"VOL".to_vec();
    out.push(3);
    out.extend_from_slice(&1i32.to_le_bytes());
    for r in res {
        out.extend_from_slice(&(r as i32).to_le_bytes());
    }
    out.extend_from_slice(&(channels as i32).to_le_bytes());
    for v in bbox[0].to_array().into_iter().chain(bbox[1].to_array()) {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(res: [usize; 3], data: Vec<f32>) -> Volume {
        let g = parse_vol(&write_vol(res, 1, &data)).unwrap();
        Volume::new(
            Source::Grid {
                grid: g,
                filter: Filter::Trilinear,
                wrap: Wrap::Clamp,
            },
            Affine3A::IDENTITY,
        )
    }

    #[test]
    fn trilinear_interpolates_between_voxel_centres_and_clamps() {
        // 2 voxels along x: centres at 0.25 and 0.75.
        let v = grid([2, 1, 1], vec![1.0, 3.0]);
        let at = |x: f32| v.eval(Vec3A::new(x, 0.5, 0.5)).x;
        assert_eq!(at(0.25), 1.0);
        assert_eq!(at(0.75), 3.0);
        assert!((at(0.5) - 2.0).abs() < 1e-6);
        assert_eq!(at(0.0), 1.0);
        assert_eq!(at(1.5), 3.0);
        assert_eq!(v.max, 3.0);
    }

    /// `eval_at` in lanes reads what `eval` reads on one path, to the bit: each filter
    /// and wrap, one and three channels, points inside the cube, beyond it and far
    /// out; a lane that is off reads 0. Power: the lanes looked up with another wrap
    /// than the one path's are told apart.
    #[test]
    fn lanes_look_up_what_one_path_does() {
        use wide::{f32x8, CmpEq};
        let mut rng = crate::sampling::Pcg32::new(5, 6);
        let to_world = Affine3A::from_scale_rotation_translation(
            Vec3::new(2.0, 1.0, 3.0),
            glam::Quat::from_rotation_y(0.4),
            Vec3::new(-1.0, 0.5, 0.0),
        );
        let wraps = [Wrap::Clamp, Wrap::Repeat, Wrap::Mirror];
        let on = f32x8::from([1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.0]).cmp_eq(f32x8::ONE);
        for channels in [1, 3] {
            let res = [5, 3, 4];
            let data: Vec<f32> = (0..60 * channels).map(|_| rng.next_1d()).collect();
            let g = parse_vol(&write_vol(res, channels, &data)).unwrap();
            for filter in [Filter::Trilinear, Filter::Nearest] {
                let volume = |wrap| {
                    let grid = g.clone();
                    Volume::new(Source::Grid { grid, filter, wrap }, to_world)
                };
                for (w, &wrap) in wraps.iter().enumerate() {
                    let (v, other) = (volume(wrap), volume(wraps[(w + 1) % 3]));
                    let mut told_apart = false;
                    for i in 0..400 {
                        let far = if i % 4 == 0 { 300.0 } else { 4.0 };
                        let p: [Vec3A; 8] = std::array::from_fn(|_| {
                            Vec3A::new(rng.next_1d(), rng.next_1d(), rng.next_1d()) * far
                                - far / 2.0
                        });
                        let lanes = Vector3 {
                            x: f32x8::from(p.map(|q| q.x)),
                            y: f32x8::from(p.map(|q| q.y)),
                            z: f32x8::from(p.map(|q| q.z)),
                        };
                        let split = |u: Vector3<f32x8>| {
                            let (x, y, z) = (u.x.to_array(), u.y.to_array(), u.z.to_array());
                            std::array::from_fn::<_, 8, _>(|k| Vec3::new(x[k], y[k], z[k]))
                        };
                        let got = split(v.eval_at(lanes, on));
                        for k in 0..7 {
                            let want = v.eval(p[k]);
                            assert_eq!(got[k], want, "{channels} {filter:?} {wrap:?} {:?}", p[k]);
                        }
                        assert_eq!(got[7], Vec3::ZERO);
                        let wrong = split(other.eval_at(lanes, on));
                        told_apart |= (0..7).any(|k| wrong[k] != got[k]);
                    }
                    assert!(told_apart, "{channels} {filter:?} {wrap:?}: wraps alike");
                }
            }
        }
    }

    #[test]
    fn bad_files_are_refused_before_allocating() {
        let ok = write_vol([2, 2, 2], 1, &[1.0; 8]);
        assert!(parse_vol(&ok).is_ok());
        assert!(matches!(
            parse_vol(&ok[..ok.len() - 1]),
            Err(VolError::Truncated { .. })
        ));
        let mut huge = ok.clone();
        huge[8..12].copy_from_slice(&(1i32 << 30).to_le_bytes());
        assert!(matches!(parse_vol(&huge), Err(VolError::Size { .. })));
        let mut nan = ok.clone();
        nan[VOL_HEADER_BYTES..VOL_HEADER_BYTES + 4].copy_from_slice(&f32::NAN.to_le_bytes());
        assert!(matches!(
            parse_vol(&nan),
            Err(VolError::BadValue { index: 0, .. })
        ));
        assert!(matches!(parse_vol(b"VOX\x03"), Err(VolError::NotVol)));
    }

    /// scatter is the adjoint of eval: for random points and weights,
    /// Σ grad · data = Σ_c w_c eval(p)_c, for 1- and 3-channel grids, trilinear and
    /// nearest, inside and outside the cube (clamped and repeated).
    #[test]
    fn scatter_is_the_adjoint_of_eval() {
        let mut rng = crate::sampling::Pcg32::new(3, 4);
        for (channels, filter, wrap) in [
            (1, Filter::Trilinear, Wrap::Clamp),
            (3, Filter::Trilinear, Wrap::Repeat),
            (1, Filter::Nearest, Wrap::Mirror),
        ] {
            let res = [3, 4, 2];
            let data: Vec<f32> = (0..24 * channels).map(|_| rng.next_1d()).collect();
            let g = parse_vol(&write_vol(res, channels, &data)).unwrap();
            let v = Volume::new(
                Source::Grid {
                    grid: g,
                    filter,
                    wrap,
                },
                Affine3A::IDENTITY,
            );
            for _ in 0..50 {
                let p = Vec3A::new(rng.next_1d(), rng.next_1d(), rng.next_1d()) * 1.6 - 0.3;
                let w = Vec3::new(rng.next_1d(), rng.next_1d(), rng.next_1d()) - 0.5;
                let mut grad = vec![0.0; data.len()];
                v.scatter(p, w, &mut grad);
                let lhs: f32 = grad.iter().zip(&data).map(|(a, b)| a * b).sum();
                let rhs = w.dot(v.eval(p));
                assert!(
                    (lhs - rhs).abs() < 1e-5,
                    "{channels} {filter:?}: {lhs} vs {rhs}"
                );
            }
        }
    }
}
