//! Hertz normal law with Tsuji damping (seed 004 eqs. 5–9) and the Mindlin tangential
//! stiffness (eq. 8):
//!   F_n = K_n δ^{3/2} + α sqrt(m K_n) δ^{1/4} v_n,  K_n = 4/3 Y* sqrt(r*),
//!   k_t = 8 G* sqrt(r* δ),
//! with α chosen so the restitution is exactly e ([`super::tsuji_alpha`]), rather than the
//! approximate closed form LIGGGHTS uses. Tangential damping uses the same prefactor on
//! sqrt(m k_t) as the normal one does on sqrt(m dF_n/dδ).

use super::{NormalLaw, NormalOut};
use crate::dem::lanes::Num;
use crate::Real;

/// Hertz law parameters for one kind of pair.
#[derive(Debug, Clone)]
pub struct Hertz {
    /// Effective modulus Y* = 1/((1−ν₁²)/E₁ + (1−ν₂²)/E₂), Pa.
    pub y_star: Real,
    /// Effective shear modulus G* = 1/((2−ν₁)/G₁ + (2−ν₂)/G₂), Pa.
    pub g_star: Real,
    /// Tsuji damping constant α.
    pub alpha: Real,
    /// α sqrt(2/3) sqrt(2 Y*): γ_n = this × sqrt(m*) (r* δ)^{1/4}.
    gamma_n_coeff: Real,
    /// sqrt(4 G*/Y*) = γ_t / γ_n (k_t over dF_n/dδ is constant).
    gamma_t_ratio: Real,
}

impl Hertz {
    /// Law for two bodies of one material (a wall counts as a body of the grains'
    /// material, as LIGGGHTS' walls do; its infinite mass and radius enter via m*, r*).
    pub fn new(youngs: Real, poisson: Real, e: Real) -> Self {
        let shear = youngs / (2.0 * (1.0 + poisson));
        let one_y = (1.0 - poisson * poisson) / youngs;
        let one_g = (2.0 - poisson) / shear;
        let (y_star, g_star) = (1.0 / (2.0 * one_y), 1.0 / (2.0 * one_g));
        let alpha = super::tsuji_alpha(e);
        Self {
            y_star,
            g_star,
            alpha,
            gamma_n_coeff: alpha * (2.0_f64 / 3.0).sqrt() * (2.0 * y_star).sqrt(),
            gamma_t_ratio: (4.0 * g_star / y_star).sqrt(),
        }
    }
}

impl NormalLaw for Hertz {
    #[inline(always)]
    fn evaluate<T: Num>(&self, sqrt_m_eff: T, r_eff: T, overlap: T, vn: T) -> NormalOut<T> {
        let sqrt_rd = (r_eff * overlap).sqrt();
        // F = 4/3 Y* sqrt(r* δ) δ;  dF/dδ = 2 Y* sqrt(r* δ);  k_t = 8 G* sqrt(r* δ).
        // α sqrt(m K_n) δ^{1/4} = α/sqrt(1.5) · sqrt(m dF/dδ) = gamma_n_coeff sqrt(m) (r* δ)^{1/4}.
        let gamma_n = T::splat(self.gamma_n_coeff) * sqrt_m_eff * sqrt_rd.sqrt();
        let elastic = T::splat((4.0 / 3.0) * self.y_star) * sqrt_rd * overlap;
        NormalOut {
            force: elastic + gamma_n * vn,
            elastic,
            kt: T::splat(8.0 * self.g_star) * sqrt_rd,
            gamma_n,
            gamma_t: gamma_n * T::splat(self.gamma_t_ratio),
        }
    }

    fn contact_time(&self, m_eff: Real, r_eff: Real, v: Real) -> Real {
        // Elastic Hertz collision time 2.868 (m*² / (r* Y*² v))^{1/5}.
        2.868 * (m_eff * m_eff / (r_eff * self.y_star * self.y_star * v)).powf(0.2)
    }
}
