//! Linear spring–dashpot normal law (seeds 000 and 002: "Hooke's law and a viscous
//! damping"): F_n = k_n δ + γ_n v_n with γ_n = 2 ζ sqrt(m_eff k_n), ζ = |ln e|/sqrt(π²+ln²e),
//! which gives restitution e exactly and the contact time π / sqrt(k_n/m_eff − (γ_n/2m_eff)²).

use super::{hooke_damping_ratio, NormalLaw, NormalOut};
use crate::dem::lanes::Num;
use crate::Real;

/// Hooke law parameters for one kind of pair.
#[derive(Debug, Clone)]
pub struct Hooke {
    /// Normal stiffness k_n, N/m.
    pub kn: Real,
    /// Tangential stiffness k_t = ratio × k_n, N/m.
    pub kt: Real,
    /// Damping ratio ζ from restitution.
    pub zeta: Real,
    /// 2 ζ sqrt(k_n): γ_n = this × sqrt(m_eff), kg^½/s.
    gamma_n_per_sqrt_m: Real,
    /// 2 ζ sqrt(k_t): γ_t = this × sqrt(m_eff), kg^½/s.
    gamma_t_per_sqrt_m: Real,
}

impl Hooke {
    /// Law with stiffness `kn`, restitution `e`, and k_t/k_n = `kt_ratio`.
    pub fn new(kn: Real, e: Real, kt_ratio: Real) -> Self {
        let zeta = hooke_damping_ratio(e);
        let kt = kt_ratio * kn;
        Self {
            kn,
            kt,
            zeta,
            gamma_n_per_sqrt_m: 2.0 * zeta * kn.sqrt(),
            gamma_t_per_sqrt_m: 2.0 * zeta * kt.sqrt(),
        }
    }

    /// Stiffness that gives collision time `tc` for effective mass `m_eff` and restitution e.
    pub fn stiffness_for_contact_time(tc: Real, m_eff: Real, e: Real) -> Real {
        let l = e.ln();
        m_eff * (std::f64::consts::PI.powi(2) + l * l) / (tc * tc)
    }
}

impl NormalLaw for Hooke {
    #[inline(always)]
    fn evaluate<T: Num>(&self, sqrt_m_eff: T, _r_eff: T, overlap: T, vn: T) -> NormalOut<T> {
        let gamma_n = T::splat(self.gamma_n_per_sqrt_m) * sqrt_m_eff;
        // Same damping ratio in the tangential direction.
        let gamma_t = T::splat(self.gamma_t_per_sqrt_m) * sqrt_m_eff;
        let elastic = T::splat(self.kn) * overlap;
        NormalOut {
            force: elastic + gamma_n * vn,
            elastic,
            kt: T::splat(self.kt),
            gamma_n,
            gamma_t,
        }
    }

    fn contact_time(&self, m_eff: Real, _r_eff: Real, _v: Real) -> Real {
        let w0 = (self.kn / m_eff).sqrt();
        std::f64::consts::PI / (w0 * (1.0 - self.zeta * self.zeta).sqrt())
    }
}
