//! Constant directional torque rolling resistance (Ai et al., Powder Technol. 206, 2011,
//! "model A"; LIGGGHTS's `rolling_friction cdt`, Lethe's `constant_resistance`):
//!
//!   M_i = −μ_r R* F_n,el (ω − (ω·n) n) / |ω|,   ω = ω_i − ω_j,
//!
//! on grain i, −M_i on its partner. F_n,el is the elastic part of the normal force (k_n δ for
//! Hooke, 4/3 Y* √(R*δ) δ for Hertz), as LIGGGHTS takes it; the torque's part along n is
//! removed after normalising by the whole relative rotation, as LIGGGHTS's `cdt` does with its
//! default `torsionTorque off` (twisting is not resisted; a contact that rolls and twists
//! feels less than μ_r R* F_n,el). For pure rolling this is Lethe's −μ_r R* |F_n| ω̂.
//! R* = R_i R_j/(R_i + R_j) between grains, R_i against a wall. The torque does not vanish
//! as ω_r → 0, so a grain at rest chatters with |Δω| ≤ M Δt / I per step (the model's known
//! trait; it stops a rolling grain in the distance the torque predicts, `tests/dem_analytic.rs`).

use super::RollingLaw;
use crate::dem::lanes::Num;
use crate::dem::vec3::{dot, norm2, scale, sub};
use crate::Real;

/// The constant-torque law with its coefficient of rolling friction μ_r (dimensionless: the
/// lever arm of the normal force in units of R*).
#[derive(Debug, Clone)]
pub struct ConstantTorque {
    /// Coefficient of rolling friction μ_r ≥ 0.
    pub mu_r: Real,
}

impl RollingLaw for ConstantTorque {
    const ACTIVE: bool = true;

    #[inline(always)]
    fn torque<T: Num>(&self, elastic_force: T, r_eff: T, w_rel: [T; 3], n: [T; 3]) -> [T; 3] {
        let w = sub(w_rel, scale(n, dot(w_rel, n)));
        let w2 = norm2(w_rel);
        // No rotation, no torque (and no 0/0): the factor is selected to zero.
        let rolls = w2.gt(T::splat(0.0));
        let magnitude = T::splat(self.mu_r) * r_eff * elastic_force.max(T::splat(0.0));
        let factor = T::select(rolls, -magnitude / w2.sqrt(), T::splat(0.0));
        scale(w, factor)
    }
}
