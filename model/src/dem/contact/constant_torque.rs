//! Constant directional torque rolling resistance (Ai et al., Powder Technol. 206, 2011,
//! "model A"), in the two readings the peers implement ([`TorqueReading`]):
//!
//! - LIGGGHTS's `rolling_friction cdt` (`constant_torque`):
//!   M_i = −μ_r R* F_n,el (ω − (ω·n) n) / |ω|,   ω = ω_i − ω_j,
//!   F_n,el the elastic part of the normal force (k_n δ for Hooke, 4/3 Y* √(R*δ) δ for
//!   Hertz); the torque's part along n is removed after normalising by the whole relative
//!   rotation (LIGGGHTS's default `torsionTorque off`: twisting is not resisted, and a
//!   contact that rolls and twists feels less than μ_r R* F_n,el).
//! - Lethe's `constant_resistance` (`rolling_torque.h`): M_i = −μ_r R* |F_n| ω / |ω|, with
//!   the whole normal force (elastic and damping) and the whole relative rotation, twist
//!   included.
//!
//! The two agree for pure rolling under a static load. On grain i, −M_i on its partner;
//! R* = R_i R_j/(R_i + R_j) between grains, R_i against a wall. The torque does not vanish
//! as ω_r → 0, so a grain at rest chatters with |Δω| ≤ M Δt / I per step (the model's known
//! trait; it stops a rolling grain in the distance the torque predicts, `tests/dem_analytic.rs`).

use super::RollingLaw;
use crate::dem::lanes::Num;
use crate::dem::vec3::{dot, norm2, scale, sub};
use crate::Real;

/// Which normal force the torque scales with and which rotation it resists.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TorqueReading {
    /// LIGGGHTS's `cdt`: the elastic normal force; twisting about n not resisted.
    ElasticNoTwist,
    /// Lethe's `constant_resistance`: |F_n| (elastic + damping); the whole relative rotation.
    WholeForceAndRotation,
}

/// The constant-torque law with its coefficient of rolling friction μ_r (dimensionless: the
/// lever arm of the normal force in units of R*).
#[derive(Debug, Clone)]
pub struct ConstantTorque {
    /// Coefficient of rolling friction μ_r ≥ 0.
    pub mu_r: Real,
    /// LIGGGHTS's reading or Lethe's.
    pub reading: TorqueReading,
}

impl RollingLaw for ConstantTorque {
    const ACTIVE: bool = true;

    #[inline(always)]
    fn torque<T: Num>(
        &self,
        elastic_force: T,
        normal_force: T,
        r_eff: T,
        w_rel: [T; 3],
        n: [T; 3],
    ) -> [T; 3] {
        let (force, w) = match self.reading {
            TorqueReading::ElasticNoTwist => (
                elastic_force.max(T::splat(0.0)),
                sub(w_rel, scale(n, dot(w_rel, n))),
            ),
            TorqueReading::WholeForceAndRotation => {
                (normal_force.max(T::splat(0.0) - normal_force), w_rel)
            }
        };
        let w2 = norm2(w_rel);
        // No rotation, no torque (and no 0/0): the factor is selected to zero.
        let rolls = w2.gt(T::splat(0.0));
        let magnitude = T::splat(self.mu_r) * r_eff * force;
        let factor = T::select(rolls, -magnitude / w2.sqrt(), T::splat(0.0));
        scale(w, factor)
    }
}
