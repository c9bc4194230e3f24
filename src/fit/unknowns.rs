//! The unknowns of a fit: each medium parameter asked for, one number where the
//! scene's value is grey (or the parameter has one value), else one per colour
//! channel; each in the coordinate the steps are taken in (the logarithm of a positive
//! one), with its valid range.

use glam::Vec3;

use crate::integrator::MediumParam;
use crate::medium::{Medium, Phase};

/// One number the fit adjusts: a parameter, all its channels or one of them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Unknown {
    pub param: MediumParam,
    /// None: the same value in every channel.
    pub channel: Option<usize>,
}

/// The largest |g| a fit may reach (p_HG's peak grows as (1 − |g|)^−2).
pub const G_LIMIT: f32 = 0.99;

impl Unknown {
    /// The unknowns of `params` for the medium `m`: a chromatic sigma_t or albedo
    /// is fitted per channel.
    pub fn of(m: &Medium, params: &[MediumParam]) -> Vec<Unknown> {
        let grey = |v: Vec3| v.x == v.y && v.y == v.z;
        let mut out = Vec::new();
        for &param in params {
            let chromatic = match param {
                MediumParam::SigmaT => !grey(m.sigma_t),
                MediumParam::Albedo => !grey(m.albedo),
                MediumParam::G | MediumParam::Scale => false,
            };
            if chromatic {
                out.extend((0..3).map(|c| Unknown {
                    param,
                    channel: Some(c),
                }));
            } else {
                out.push(Unknown {
                    param,
                    channel: None,
                });
            }
        }
        out
    }

    /// Its name in reports: `sigma_t`, or `sigma_t[1]` for one channel.
    pub fn label(&self) -> String {
        match self.channel {
            None => self.param.name().to_string(),
            Some(c) => format!("{}[{c}]", self.param.name()),
        }
    }

    /// Whether steps are taken in its logarithm (a positive parameter whose scale is
    /// unknown: the extinction and its scale).
    fn is_log(&self) -> bool {
        matches!(self.param, MediumParam::SigmaT | MediumParam::Scale)
    }

    /// The value in `m` (channel 0 of a grey one).
    pub fn value(&self, m: &Medium) -> f32 {
        let c = self.channel.unwrap_or(0);
        match self.param {
            MediumParam::SigmaT => (m.sigma_t / m.scale)[c],
            MediumParam::Albedo => m.albedo[c],
            MediumParam::G => match m.phase {
                Phase::HenyeyGreenstein { g } => g,
                _ => 0.0,
            },
            MediumParam::Scale => m.scale,
        }
    }

    /// Sets the value in `m`, clamped to the parameter's range.
    pub fn set(&self, m: &mut Medium, v: f32) {
        let channels = match self.channel {
            None => 0..3,
            Some(c) => c..c + 1,
        };
        match self.param {
            MediumParam::SigmaT => {
                let mut raw = m.sigma_t / m.scale;
                for c in channels {
                    raw[c] = v.max(1e-6);
                }
                m.sigma_t = raw * m.scale;
            }
            MediumParam::Albedo => {
                for c in channels {
                    m.albedo[c] = v.clamp(0.0, 1.0);
                }
            }
            MediumParam::G => {
                m.phase = Phase::HenyeyGreenstein {
                    g: v.clamp(-G_LIMIT, G_LIMIT),
                }
            }
            MediumParam::Scale => m.set_scale(v.max(1e-6)),
        }
    }

    /// The step coordinate x of a value v: ln v, or v.
    pub fn to_x(&self, v: f32) -> f64 {
        if self.is_log() {
            (v as f64).ln()
        } else {
            v as f64
        }
    }

    /// The value at step coordinate x.
    pub fn from_x(&self, x: f64) -> f32 {
        if self.is_log() {
            x.exp() as f32
        } else {
            x as f32
        }
    }

    /// x moved into the parameter's range (albedo in [0, 1], |g| ≤ [`G_LIMIT`]).
    pub fn clamp_x(&self, x: f64) -> f64 {
        match self.param {
            MediumParam::Albedo => x.clamp(0.0, 1.0),
            MediumParam::G => x.clamp(-G_LIMIT as f64, G_LIMIT as f64),
            MediumParam::SigmaT | MediumParam::Scale => x,
        }
    }

    /// dv/dx at value v (the chain rule from the derivative images to x).
    pub fn dv_dx(&self, v: f32) -> f64 {
        if self.is_log() {
            v as f64
        } else {
            1.0
        }
    }

    /// The largest step in x one iteration takes (a trust region: the derivatives are
    /// local, and noisy).
    pub fn max_step(&self) -> f64 {
        match self.param {
            MediumParam::SigmaT | MediumParam::Scale => 0.5,
            MediumParam::Albedo => 0.15,
            MediumParam::G => 0.25,
        }
    }

    /// Of a pixel's derivative in this parameter (per channel, `d`), the part in this
    /// unknown for channel `c`.
    pub fn derivative_in(&self, d: [f32; 3], c: usize) -> f64 {
        match self.channel {
            Some(k) if k != c => 0.0,
            _ => d[c] as f64,
        }
    }
}
