//! The derivatives in one medium's extinction and Henyey–Greenstein g in lanes, beside
//! the paths' β (volpath's `Differentiated`, `Estimand::MediumDerivatives`): forward
//! mode with the sampling detached, each weight dσ = ∂β/∂σ_t (∂β/∂scale in a
//! heterogeneous medium) and dg = ∂β/∂g scaled wherever β is, plus β times the score
//! ∂ ln f/∂θ of each factor f of the path that depends on θ (the flights in the medium,
//! its phase values, the shadow rays' transmittance through it). Where the render asks for neither, every
//! method returns at once: a plain render does none of this arithmetic.

use glam::Vec3;

use super::lanes::{L, V3};
use crate::integrator::volpath::PathSettings;

/// The derivative weights of a packet's paths and what they gathered; in the instance
/// `D = false` (a render without derivatives) none is estimated, known at compile time.
pub(super) struct Derivatives<const D: bool> {
    /// Whether the extinction's and g's derivatives are estimated.
    sigma_on: bool,
    g_on: bool,
    /// ∂β/∂σ_t and ∂β/∂g per lane.
    d_sigma: V3,
    d_g: V3,
    /// Their samples (`PathSample::d_sigma`, `d_g`).
    pub(super) sigma_result: V3,
    pub(super) g_result: V3,
}

impl<const D: bool> Derivatives<D> {
    pub(super) fn new(settings: &PathSettings) -> Self {
        let zero = V3::splat(Vec3::ZERO);
        Derivatives {
            sigma_on: settings.estimand.extinction_medium().is_some(),
            g_on: settings.estimand.g_medium().is_some(),
            d_sigma: zero,
            d_g: zero,
            sigma_result: zero,
            g_result: zero,
        }
    }

    /// Whether the extinction's derivative is estimated.
    #[inline(always)]
    pub(super) fn sigma_on(&self) -> bool {
        D && self.sigma_on
    }

    /// Whether g's derivative is estimated.
    #[inline(always)]
    pub(super) fn g_on(&self) -> bool {
        D && self.g_on
    }

    /// Whether any derivative beyond the albedo's is estimated.
    #[inline(always)]
    pub(super) fn on(&self) -> bool {
        D && (self.sigma_on | self.g_on)
    }

    /// The lanes of `mask` whose derivative weights are both 0 (all of `mask` where
    /// none is estimated).
    #[inline(always)]
    pub(super) fn zero_of(&self, mask: L) -> L {
        if !self.on() {
            return mask;
        }
        mask & self.d_sigma.is_zero() & self.d_g.is_zero()
    }

    /// The lanes of `mask` whose derivative weights are finite.
    #[inline(always)]
    pub(super) fn finite_of(&self, mask: L) -> L {
        if !self.on() {
            return mask;
        }
        mask & self.d_sigma.is_finite() & self.d_g.is_finite()
    }

    /// Both weights times `w` in the lanes of `mask` (where β takes `w`).
    #[inline(always)]
    pub(super) fn scale(&mut self, mask: L, w: V3) {
        if self.on() {
            self.d_sigma = self.d_sigma.select(mask, self.d_sigma.mul(w));
            self.d_g = self.d_g.select(mask, self.d_g.mul(w));
        }
    }

    /// Both weights over `q` in the lanes of `mask` (the roulette's survivors).
    #[inline(always)]
    pub(super) fn div(&mut self, mask: L, q: L) {
        if self.on() {
            self.d_sigma = self.d_sigma.select(mask, self.d_sigma.div(q));
            self.d_g = self.d_g.select(mask, self.d_g.div(q));
        }
    }

    /// Both weights over `k` in every lane (1 where they are to stay).
    #[inline(always)]
    pub(super) fn div_all(&mut self, k: L) {
        if self.on() {
            self.d_sigma = self.d_sigma.div(k);
            self.d_g = self.d_g.div(k);
        }
    }

    /// dσ += β v in the lanes of `mask`: where β takes a factor whose derivative in
    /// σ_t (over the detached pdf) is β v (v: the factor's score times its weight).
    #[inline(always)]
    pub(super) fn add_sigma(&mut self, mask: L, beta: V3, v: V3) {
        self.d_sigma = self.d_sigma.select(mask, self.d_sigma.add(beta.mul(v)));
    }

    /// dg += β s in the lanes of `mask` (s: a phase value's score ∂ ln p/∂g).
    #[inline(always)]
    pub(super) fn add_g_score(&mut self, mask: L, beta: V3, s: L) {
        self.d_g = self.d_g.select(mask, self.d_g.add(beta.scale(s)));
    }

    /// What β gathers as β x in the lanes of `mask` (x not depending on θ): d x.
    #[inline(always)]
    pub(super) fn gather(&mut self, mask: L, x: V3) {
        if self.on() {
            self.sigma_result = self
                .sigma_result
                .select(mask, self.sigma_result.add(self.d_sigma.mul(x)));
            self.g_result = self
                .g_result
                .select(mask, self.g_result.add(self.d_g.mul(x)));
        }
    }

    /// What β gathers as β x in the lanes of `mask`, x's scores in σ_t (`d_log`: a
    /// shadow ray's ∂ ln T, or −t for an emitter counted in expectation) and in g
    /// (`g_score`, the phase value's): (d + β score) x.
    #[inline(always)]
    pub(super) fn gather_light(&mut self, mask: L, x: V3, beta: V3, (d_log, g_score): (V3, L)) {
        if self.on() {
            let d_sigma = self.d_sigma.add(beta.mul(d_log));
            self.sigma_result = self
                .sigma_result
                .select(mask, self.sigma_result.add(x.mul(d_sigma)));
            let d_g = self.d_g.add(beta.scale(g_score));
            self.g_result = self.g_result.select(mask, self.g_result.add(x.mul(d_g)));
        }
    }
}
