//! Temporal gradient denoising (the paper, Sec. 4.2, Eq. 9–10): the gradient images of
//! the target frame (k = 0) and its N − 1 predecessors are reprojected into the target
//! frame and blended with exponential weights
//!
//!   G(i) = w_a / (1 − (1 − w_a)^N) · Σ_{k=0}^{N−1} (1 − w_a)^k · G_k(proj_k^{-1}(i)).
//!
//! A pixel that does not reproject into frame k (it leaves the image, or is disoccluded)
//! takes fewer frames: the weights of the frames it has are renormalised to sum to 1.

/// Where each target pixel is found in one earlier frame: a position in that frame's
/// pixel coordinates (pixel centres at +0.5), or `None` where it does not reproject.
pub type Reprojection = Vec<Option<(f32, f32)>>;

/// The weights of Eq. 10 for frames k = 0..n, summing to 1.
pub fn weights(n: usize, w_a: f64) -> Vec<f64> {
    let norm = w_a / (1.0 - (1.0 - w_a).powi(n as i32));
    (0..n).map(|k| norm * (1.0 - w_a).powi(k as i32)).collect()
}

/// The reprojection of Eq. 9: one screen-space motion `(dx, dy)` in pixels for the whole
/// frame (target pixel centre + motion = where it is in frame k).
pub fn screen_shift(width: usize, height: usize, dx: f32, dy: f32) -> Reprojection {
    (0..width * height)
        .map(|i| {
            let (x, y) = ((i % width) as f32 + 0.5 + dx, (i / width) as f32 + 0.5 + dy);
            (x >= 0.5 && y >= 0.5 && x <= width as f32 - 0.5 && y <= height as f32 - 0.5)
                .then_some((x, y))
        })
        .collect()
}

/// Bilinear lookup at a position inside the pixel-centre lattice.
fn bilinear(img: &[[f32; 3]], width: usize, height: usize, (x, y): (f32, f32)) -> [f32; 3] {
    let (fx, fy) = (x - 0.5, y - 0.5);
    let (x0, y0) = (fx.floor().max(0.0) as usize, fy.floor().max(0.0) as usize);
    let (x1, y1) = ((x0 + 1).min(width - 1), (y0 + 1).min(height - 1));
    let (tx, ty) = (
        (fx - x0 as f32).clamp(0.0, 1.0),
        (fy - y0 as f32).clamp(0.0, 1.0),
    );
    let at = |x: usize, y: usize| img[y * width + x];
    [0, 1, 2].map(|c| {
        let top = at(x0, y0)[c] * (1.0 - tx) + at(x1, y0)[c] * tx;
        let bottom = at(x0, y1)[c] * (1.0 - tx) + at(x1, y1)[c] * tx;
        top * (1.0 - ty) + bottom * ty
    })
}

/// Eq. 10. `frames[0]` is the target frame's gradient, `frames[k]` the k-th earlier one
/// with `maps[k - 1]` its reprojection; `w_a` the paper's blending weight (0.1).
pub fn blend(
    frames: &[&[[f32; 3]]],
    maps: &[Reprojection],
    width: usize,
    height: usize,
    w_a: f64,
) -> Vec<[f32; 3]> {
    assert_eq!(
        maps.len() + 1,
        frames.len(),
        "one reprojection per earlier frame"
    );
    let w = weights(frames.len(), w_a);
    (0..width * height)
        .map(|i| {
            let mut sum = [
                w[0] * frames[0][i][0] as f64,
                w[0] * frames[0][i][1] as f64,
                w[0] * frames[0][i][2] as f64,
            ];
            let mut total = w[0];
            for (k, map) in maps.iter().enumerate() {
                if let Some(pos) = map[i] {
                    let v = bilinear(frames[k + 1], width, height, pos);
                    for c in 0..3 {
                        sum[c] += w[k + 1] * v[c] as f64;
                    }
                    total += w[k + 1];
                }
            }
            sum.map(|s| (s / total) as f32)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn synthetic(width: usize, height: usize, ox: i64, oy: i64) -> Vec<[f32; 3]> {
        (0..width * height)
            .map(|i| {
                let (x, y) = ((i % width) as i64 + ox, (i / width) as i64 + oy);
                let v = ((x * 7 + y * 13) % 17) as f32 - 8.0;
                [v, 0.5 * v, (x - y) as f32]
            })
            .collect()
    }

    #[test]
    fn weights_sum_to_one_and_decay() {
        let w = weights(11, 0.1);
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert!((w[1] / w[0] - 0.9).abs() < 1e-12);
        // By hand: w_0 = 0.1 / (1 − 0.9^11) = 0.1 / 0.686189…
        assert!((w[0] - 0.1 / (1.0 - 0.9f64.powi(11))).abs() < 1e-15);
    }

    /// A static camera: every frame reprojects to itself, and the result is the plain
    /// weighted mean of the frames.
    #[test]
    fn static_sequence_gives_the_weighted_mean() {
        let (wd, ht, n) = (16, 12, 5);
        let frames: Vec<Vec<[f32; 3]>> =
            (0..n).map(|k| synthetic(wd, ht, k as i64 * 3, 0)).collect();
        let refs: Vec<&[[f32; 3]]> = frames.iter().map(|f| f.as_slice()).collect();
        let maps: Vec<Reprojection> = (1..n).map(|_| screen_shift(wd, ht, 0.0, 0.0)).collect();
        let out = blend(&refs, &maps, wd, ht, 0.1);
        let w = weights(n, 0.1);
        for i in 0..wd * ht {
            for c in 0..3 {
                let want: f64 = (0..n).map(|k| w[k] * frames[k][i][c] as f64).sum();
                assert!((out[i][c] as f64 - want).abs() < 1e-5, "pixel {i}");
            }
        }
    }

    /// Frame k is the target image moved by k pixels: shifting back recovers the target
    /// exactly, and pixels that leave the image use fewer frames (weights renormalised),
    /// so the blend is the target image everywhere.
    #[test]
    fn translated_images_reproject_back_exactly() {
        let (wd, ht, n) = (20, 10, 6);
        let (dx, dy) = (2i64, -1i64);
        // Frame k shows the scene moved by −k·(dx, dy): its pixel p is the target's p + k·(dx, dy).
        let frames: Vec<Vec<[f32; 3]>> = (0..n)
            .map(|k| synthetic(wd, ht, k as i64 * dx, k as i64 * dy))
            .collect();
        let refs: Vec<&[[f32; 3]]> = frames.iter().map(|f| f.as_slice()).collect();
        let maps: Vec<Reprojection> = (1..n)
            .map(|k| screen_shift(wd, ht, -(k as i64 * dx) as f32, -(k as i64 * dy) as f32))
            .collect();
        let out = blend(&refs, &maps, wd, ht, 0.1);
        for (i, (o, t)) in out.iter().zip(&frames[0]).enumerate() {
            for c in 0..3 {
                assert!(
                    (o[c] - t[c]).abs() < 1e-5,
                    "pixel {i} channel {c}: {} vs {}",
                    o[c],
                    t[c]
                );
            }
        }
        // The left border (x < 2) is not in frame 1 (it is found at x − 2): fewer frames
        // there, and still the exact value.
        assert!(maps[0][0].is_none() && maps[0][2].is_some());
    }
}
