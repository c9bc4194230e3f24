//! Mitsuba 0.6's medium `material` presets (`src/medium/materials.h`, used by every 0.6
//! medium through `lookupMaterial` and `Medium::Medium` in `src/librender/medium.cpp`).
//!
//! The table holds measured coefficients in mm⁻¹ from two papers:
//! * H. W. Jensen, S. R. Marschner, M. Levoy, P. Hanrahan, "A Practical Model for
//!   Subsurface Light Transport", SIGGRAPH 2001: its table of measured reduced
//!   scattering coefficients σ'_s and absorption coefficients σ_a (the entries "Apple" to
//!   "Wholemilk"; no anisotropy, so g = 0 and σ_s here is σ'_s);
//! * S. G. Narasimhan, M. Gupta, C. Donner, R. Ramamoorthi, S. K. Nayar, H. W. Jensen,
//!   "Acquiring Scattering Properties of Participating Media by Dilution", SIGGRAPH
//!   2006: its table of the measured media (σ_s, σ_a and the Henyey–Greenstein g per RGB
//!   channel; the entries "Lowfat Milk" to "Pacific Ocean Surface Water"). The name
//!   "Budweiser Beder" is 0.6's spelling, kept because files use it.
//!
//! What 0.6 made of a preset (and what `coefficients` returns): the values × 100, times
//! the medium's `scale`; then the reduced scattering coefficient σ_s (1 − g) with g from
//! the preset (or the medium's own `g`), since 0.6 did not use the preset's anisotropy
//! (the phase function stays the medium's nested `<phase>`, isotropic by default). The
//! names are matched without regard to case, as 0.6 does.

/// One row of the table: σ_s, σ_a (mm⁻¹) and g, per RGB channel.
pub struct Preset {
    pub name: &'static str,
    pub sigma_s: [f64; 3],
    pub sigma_a: [f64; 3],
    pub g: [f64; 3],
}

#[rustfmt::skip]
pub const PRESETS: &[Preset] = &[
    // Jensen et al. 2001: reduced scattering sigma_s' (so g = 0) and sigma_a.
    Preset { name: "Apple", sigma_s: [2.29, 2.39, 1.97], sigma_a: [0.0030, 0.0034, 0.046], g: [0.0, 0.0, 0.0] },
    Preset { name: "Chicken1", sigma_s: [0.15, 0.21, 0.38], sigma_a: [0.0015, 0.077, 0.19], g: [0.0, 0.0, 0.0] },
    Preset { name: "Chicken2", sigma_s: [0.19, 0.25, 0.32], sigma_a: [0.0018, 0.088, 0.20], g: [0.0, 0.0, 0.0] },
    Preset { name: "Cream", sigma_s: [7.38, 5.47, 3.15], sigma_a: [0.0002, 0.0028, 0.0163], g: [0.0, 0.0, 0.0] },
    Preset { name: "Ketchup", sigma_s: [0.18, 0.07, 0.03], sigma_a: [0.061, 0.97, 1.45], g: [0.0, 0.0, 0.0] },
    Preset { name: "Marble", sigma_s: [2.19, 2.62, 3.00], sigma_a: [0.0021, 0.0041, 0.0071], g: [0.0, 0.0, 0.0] },
    Preset { name: "Potato", sigma_s: [0.68, 0.70, 0.55], sigma_a: [0.0024, 0.0090, 0.12], g: [0.0, 0.0, 0.0] },
    Preset { name: "Skimmilk", sigma_s: [0.70, 1.22, 1.90], sigma_a: [0.0014, 0.0025, 0.0142], g: [0.0, 0.0, 0.0] },
    Preset { name: "Skin1", sigma_s: [0.74, 0.88, 1.01], sigma_a: [0.032, 0.17, 0.48], g: [0.0, 0.0, 0.0] },
    Preset { name: "Skin2", sigma_s: [1.09, 1.59, 1.79], sigma_a: [0.013, 0.070, 0.145], g: [0.0, 0.0, 0.0] },
    Preset { name: "Spectralon", sigma_s: [11.6, 20.4, 14.9], sigma_a: [0.00, 0.00, 0.00], g: [0.0, 0.0, 0.0] },
    Preset { name: "Wholemilk", sigma_s: [2.55, 3.21, 3.77], sigma_a: [0.0011, 0.0024, 0.014], g: [0.0, 0.0, 0.0] },
    // Narasimhan et al. 2006: sigma_s, sigma_a and the HG g per channel.
    Preset { name: "Lowfat Milk", sigma_s: [13.1157, 15.4445, 17.9572], sigma_a: [0.00287, 0.00575, 0.01150], g: [0.93200, 0.90200, 0.85900] },
    Preset { name: "Reduced Milk", sigma_s: [13.7335, 15.6003, 17.8007], sigma_a: [0.00256, 0.00511, 0.01278], g: [0.81900, 0.79700, 0.74600] },
    Preset { name: "Regular Milk", sigma_s: [18.2052, 20.3826, 22.3698], sigma_a: [0.00153, 0.00460, 0.01993], g: [0.75000, 0.71400, 0.68100] },
    Preset { name: "Espresso", sigma_s: [7.78262, 8.13050, 8.53875], sigma_a: [4.79838, 6.57512, 8.84925], g: [0.90700, 0.89600, 0.88000] },
    Preset { name: "Mint Mocha Coffee", sigma_s: [3.51133, 4.14383, 5.59667], sigma_a: [3.77200, 5.82283, 7.82000], g: [0.91000, 0.90700, 0.91400] },
    Preset { name: "Lowfat Soy Milk", sigma_s: [2.03838, 2.32875, 3.90281], sigma_a: [0.00144, 0.00719, 0.03594], g: [0.85000, 0.85300, 0.84200] },
    Preset { name: "Regular Soy Milk", sigma_s: [4.66325, 5.20183, 8.74575], sigma_a: [0.00192, 0.00958, 0.06517], g: [0.87300, 0.85800, 0.83200] },
    Preset { name: "Lowfat Chocolate Milk", sigma_s: [9.83710, 11.4954, 13.1629], sigma_a: [0.01150, 0.03680, 0.15640], g: [0.93400, 0.92700, 0.91600] },
    Preset { name: "Regular Chocolate Milk", sigma_s: [10.5685, 13.1416, 15.2202], sigma_a: [0.01006, 0.04313, 0.14375], g: [0.86200, 0.83800, 0.80600] },
    Preset { name: "Coke", sigma_s: [0.00254, 0.00299, 0.00000], sigma_a: [0.10014, 0.16503, 0.24680], g: [0.96500, 0.97200, 0.00000] },
    Preset { name: "Pepsi", sigma_s: [0.00083, 0.00203, 0.00000], sigma_a: [0.09164, 0.14158, 0.20729], g: [0.92600, 0.97900, 0.00000] },
    Preset { name: "Sprite", sigma_s: [0.00011, 0.00014, 0.00014], sigma_a: [0.00189, 0.00183, 0.00200], g: [0.94300, 0.95300, 0.95200] },
    Preset { name: "Gatorade", sigma_s: [0.03668, 0.04488, 0.05742], sigma_a: [0.02479, 0.01929, 0.00888], g: [0.93300, 0.93300, 0.93500] },
    Preset { name: "Chardonnay", sigma_s: [0.00021, 0.00033, 0.00048], sigma_a: [0.01078, 0.01186, 0.02400], g: [0.91400, 0.95800, 0.97500] },
    Preset { name: "White Zinfandel", sigma_s: [0.00022, 0.00033, 0.00046], sigma_a: [0.01207, 0.01618, 0.01984], g: [0.91900, 0.94300, 0.97200] },
    Preset { name: "Merlot", sigma_s: [0.00081, 0.00000, 0.00000], sigma_a: [0.11632, 0.25191, 0.29434], g: [0.97400, 0.00000, 0.00000] },
    Preset { name: "Budweiser Beder", sigma_s: [0.00029, 0.00055, 0.00059], sigma_a: [0.01149, 0.02491, 0.05779], g: [0.91700, 0.95600, 0.98200] },
    Preset { name: "Coors Light Beer", sigma_s: [0.00062, 0.00127, 0.00000], sigma_a: [0.00616, 0.01398, 0.03498], g: [0.91800, 0.96600, 0.00000] },
    Preset { name: "Clorox", sigma_s: [0.02731, 0.03302, 0.03695], sigma_a: [0.00335, 0.01489, 0.02630], g: [0.91200, 0.90500, 0.89200] },
    Preset { name: "Apple Juice", sigma_s: [0.00257, 0.00311, 0.00413], sigma_a: [0.01296, 0.02374, 0.05218], g: [0.94700, 0.94900, 0.94500] },
    Preset { name: "Cranberry Juice", sigma_s: [0.00196, 0.00238, 0.00301], sigma_a: [0.03944, 0.09422, 0.12426], g: [0.94700, 0.95100, 0.97400] },
    Preset { name: "Grape Juice", sigma_s: [0.00138, 0.00000, 0.00000], sigma_a: [0.10404, 0.23958, 0.29325], g: [0.96100, 0.00000, 0.00000] },
    Preset { name: "Ruby Grapefruit Juice", sigma_s: [0.15496, 0.15391, 0.15995], sigma_a: [0.08587, 0.18314, 0.25262], g: [0.92900, 0.92900, 0.93100] },
    Preset { name: "White Grapefruit Juice", sigma_s: [0.50499, 0.52742, 0.75282], sigma_a: [0.01380, 0.01883, 0.05678], g: [0.54800, 0.54500, 0.56500] },
    Preset { name: "Shampoo", sigma_s: [0.00797, 0.00874, 0.01127], sigma_a: [0.01411, 0.04569, 0.06172], g: [0.91000, 0.90500, 0.92000] },
    Preset { name: "Strawberry Shampoo", sigma_s: [0.00215, 0.00245, 0.00253], sigma_a: [0.01449, 0.05796, 0.07582], g: [0.92700, 0.93500, 0.99400] },
    Preset { name: "Head & Shoulders Shampoo", sigma_s: [0.26747, 0.27696, 0.29574], sigma_a: [0.08462, 0.15688, 0.20365], g: [0.91100, 0.89600, 0.88400] },
    Preset { name: "Lemon Tea Powder", sigma_s: [0.74489, 0.83823, 1.00158], sigma_a: [2.42881, 4.57573, 7.21270], g: [0.94600, 0.94600, 0.94900] },
    Preset { name: "Orange Juice Powder", sigma_s: [0.00193, 0.00213, 0.00226], sigma_a: [0.00145, 0.00344, 0.00786], g: [0.91900, 0.91800, 0.92200] },
    Preset { name: "Pink Lemonade Powder", sigma_s: [0.00123, 0.00133, 0.00131], sigma_a: [0.00116, 0.00237, 0.00320], g: [0.90200, 0.90200, 0.90400] },
    Preset { name: "Cappuccino Powder", sigma_s: [12.2094, 16.4659, 29.2727], sigma_a: [35.8441, 49.5470, 61.0844], g: [0.84900, 0.84300, 0.92600] },
    Preset { name: "Salt Powder", sigma_s: [0.13805, 0.15677, 0.17865], sigma_a: [0.28415, 0.32570, 0.34148], g: [0.80200, 0.79300, 0.82100] },
    Preset { name: "Sugar Powder", sigma_s: [0.00282, 0.00315, 0.00393], sigma_a: [0.01264, 0.03105, 0.05012], g: [0.92100, 0.91900, 0.93100] },
    Preset { name: "Suisse Mocha Powder", sigma_s: [30.0848, 33.4452, 38.7191], sigma_a: [17.5020, 27.0044, 35.4334], g: [0.90700, 0.89400, 0.88800] },
    Preset { name: "Pacific Ocean Surface Water", sigma_s: [0.00180, 0.00183, 0.00228], sigma_a: [0.03184, 0.03132, 0.03015], g: [0.90200, 0.82500, 0.91400] },
];

/// The preset named `name` (any case).
pub fn find(name: &str) -> Option<&'static Preset> {
    PRESETS.iter().find(|p| p.name.eq_ignore_ascii_case(name))
}

/// All names, comma-separated, for an error message.
pub fn names() -> String {
    PRESETS
        .iter()
        .map(|p| p.name)
        .collect::<Vec<_>>()
        .join(", ")
}

/// The σ_s and σ_a 0.6 renders with for `preset` (before the medium's `scale`): the
/// table × 100, σ_s reduced by (1 − g), with `g` the medium's own if it gives one.
pub fn coefficients(preset: &Preset, g: Option<[f64; 3]>) -> ([f64; 3], [f64; 3]) {
    let g = g.unwrap_or(preset.g);
    let s = std::array::from_fn(|i| preset.sigma_s[i] * 100.0 * (1.0 - g[i]));
    let a = std::array::from_fn(|i| preset.sigma_a[i] * 100.0);
    (s, a)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_as_mitsuba_0_6() {
        assert_eq!(PRESETS.len(), 47);
        let m = find("regular milk").unwrap();
        assert_eq!(m.name, "Regular Milk");
        let (s, a) = coefficients(m, None);
        assert!((s[0] - 18.2052 * 100.0 * 0.25).abs() < 1e-9);
        assert!((a[2] - 1.993).abs() < 1e-12);
        // A medium's own g replaces the preset's.
        assert_eq!(coefficients(m, Some([0.0; 3])).0[1], 20.3826 * 100.0);
        assert!(find("Skin1").is_some() && find("Milk").is_none());
        assert!(names().starts_with("Apple, Chicken1,"));
    }
}
