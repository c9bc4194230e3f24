//! The rows of a table run: what was rendered (`Method`), what its seconds charge
//! (`Accounting`), and one image's measurements (`Row`).

use serde::{Deserialize, Serialize};

#[derive(Serialize, Deserialize, Clone, Copy, PartialEq, Eq, Debug, PartialOrd, Ord)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Plain volpath at the target albedo.
    Volpath,
    /// The same through Open Image Denoise (`render --denoise oidn`), its time charged.
    VolpathOidn,
    /// The control: plain radiance through the very reprojection, blend and filter the
    /// default method uses (`regularize::Method::Radiance`).
    VolpathFiltered,
    /// The paper's predictor (Eq. 11–12) over the sequence.
    RegularizedPaper,
    /// One frame, the paper's predictor with the gradient filtered spatially.
    RegularizedSpatial,
    /// What `mediareg regularize` does by default: the difference predictor with the
    /// factor chosen by the pilot, temporal and spatial filtering.
    Regularized,
    /// The same at a fixed factor (`TableOptions::difference_factors`).
    RegularizedDifference,
    MitsubaVolpath,
}

impl Method {
    pub fn as_str(self) -> &'static str {
        match self {
            Method::Volpath => "volpath",
            Method::VolpathOidn => "volpath_oidn",
            Method::VolpathFiltered => "volpath_filtered",
            Method::RegularizedPaper => "regularized_paper",
            Method::RegularizedSpatial => "regularized_spatial",
            Method::Regularized => "regularized",
            Method::RegularizedDifference => "regularized_difference",
            Method::MitsubaVolpath => "mitsuba_volpath",
        }
    }

    /// The rows a method is compared with: the best of these is the baseline.
    pub fn is_baseline(self) -> bool {
        matches!(
            self,
            Method::Volpath | Method::VolpathOidn | Method::VolpathFiltered
        )
    }
}

/// What a row's seconds charge (issue 41).
#[derive(Serialize, Deserialize, Clone, Copy, PartialEq, Eq, Debug, Default, PartialOrd, Ord)]
#[serde(rename_all = "snake_case")]
pub enum Accounting {
    /// An animation: a sequence's target frame and its share of the pilot (the paper's).
    #[default]
    Frame,
    /// One image: every frame of a sequence and the whole pilot; the baselines get the
    /// same time.
    Still,
}

impl Accounting {
    pub fn as_str(self) -> &'static str {
        match self {
            Accounting::Frame => "frame",
            Accounting::Still => "still",
        }
    }
}

/// One image of a table run (`table1_seeds.json`; `table1.json` summarizes them over
/// seeds, `summary::Summary`).
#[derive(Serialize, Deserialize, Clone, Debug)]
pub struct Row {
    pub scene: String,
    pub method: Method,
    #[serde(default)]
    pub accounting: Accounting,
    #[serde(default)]
    pub seed: u64,
    /// Samples per pixel (per frame for `regularized`).
    pub spp: u32,
    /// The cost counted (one frame for `regularized`).
    pub seconds: f64,
    pub mse: f64,
    pub mse_corrected: f64,
    /// The image, relative to the JSON file.
    pub image: String,
    /// The reference, relative to the JSON file.
    pub reference: String,
    /// The regularized rows: the source factor α_s / α_t per channel.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub factor: Option<[f32; 3]>,
    /// `regularized`: frames rendered, and the seconds of the whole sequence.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sequence_frames: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sequence_seconds: Option<f64>,
}
