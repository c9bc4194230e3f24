//! The paper's Table 1 (Wu et al. 2024; `../shared/paper/METHOD.md`): equal-time MSE of
//! their method ("ours", temporal gradient denoising) and of path tracing, against a
//! 16k-spp reference, on an Intel i7-10700 (16 cores) with Mitsuba 0.5. Absolute times
//! and MSEs do not carry over to other machines and scenes; the ratio ours/PT does.

/// One scene of the paper's Table 1.
#[derive(Clone, Copy, Debug)]
pub struct PaperRow {
    pub scene: &'static str,
    pub g: f32,
    pub sigma_t: f32,
    pub albedo: [f32; 3],
    pub width: usize,
    pub height: usize,
    /// α_s = factor · α_t.
    pub factor: f32,
    pub ours_spp: u32,
    pub ours_seconds: f64,
    pub ours_mse: f64,
    pub pt_spp: u32,
    pub pt_seconds: f64,
    pub pt_mse: f64,
}

impl PaperRow {
    /// ours / PT at (about) equal time: 0.48, 0.47 and 0.34.
    pub fn mse_ratio(&self) -> f64 {
        self.ours_mse / self.pt_mse
    }
}

pub const TABLE1: [PaperRow; 3] = [
    PaperRow {
        scene: "bunny",
        g: 0.7,
        sigma_t: 10.0,
        albedo: [0.95; 3],
        width: 500,
        height: 500,
        factor: 0.95,
        ours_spp: 256,
        ours_seconds: 29.67,
        ours_mse: 1.1e-4,
        pt_spp: 200,
        pt_seconds: 29.76,
        pt_mse: 2.3e-4,
    },
    PaperRow {
        scene: "candle",
        g: 0.8,
        sigma_t: 10.0,
        albedo: [0.98, 0.94, 0.88],
        width: 256,
        height: 256,
        factor: 0.95,
        ours_spp: 2048,
        ours_seconds: 72.60,
        ours_mse: 6.1e-5,
        pt_spp: 1300,
        pt_seconds: 70.20,
        pt_mse: 1.3e-4,
    },
    PaperRow {
        scene: "lucy",
        g: 0.8,
        sigma_t: 10.0,
        albedo: [0.97; 3],
        width: 512,
        height: 512,
        factor: 0.93,
        ours_spp: 512,
        ours_seconds: 68.40,
        ours_mse: 1.5e-5,
        pt_spp: 350,
        pt_seconds: 69.60,
        pt_mse: 4.4e-5,
    },
];

/// The paper's row for a scene name, if the paper has one.
pub fn table1_row(scene: &str) -> Option<&'static PaperRow> {
    TABLE1.iter().find(|r| r.scene == scene)
}
