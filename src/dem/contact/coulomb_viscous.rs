//! The seeds' regularised Coulomb law (seed 000 §2.2, seed 002 §2.2): the tangential force
//! is viscous, γ_t |v_t|, while that is below the Coulomb limit μ|F_n|, and μ|F_n| beyond,
//! always against the slip. It keeps no history.

use super::{NormalOut, TangentialLaw};
use crate::dem::vec3::{norm, scale};
use crate::{Real, Vec3};

/// Parameters of the regularised Coulomb law.
#[derive(Debug, Clone)]
pub struct CoulombViscous {
    /// Friction coefficient μ.
    pub mu: Real,
    /// Viscous coefficient γ_t, kg/s; `None` uses the pair's normal damping coefficient.
    pub gamma_t: Option<Real>,
}

impl TangentialLaw for CoulombViscous {
    const USES_HISTORY: bool = false;

    fn with_friction(&self, mu: Real) -> Self {
        Self { mu, ..self.clone() }
    }

    #[inline(always)]
    fn force(&self, normal: &NormalOut, vt: Vec3, _n: Vec3, _h: &mut Vec3, _dt: Real) -> Vec3 {
        let speed = norm(vt);
        if speed == 0.0 {
            return [0.0; 3];
        }
        let gamma = self.gamma_t.unwrap_or(normal.gamma_n);
        let magnitude = (gamma * speed).min(self.mu * normal.force.max(0.0));
        scale(vt, -magnitude / speed)
    }
}
