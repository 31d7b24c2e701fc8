//! The seeds' regularised Coulomb law (seed 000 §2.2, seed 002 §2.2): the tangential force
//! is viscous, γ_t |v_t|, while that is below the Coulomb limit μ|F_n|, and μ|F_n| beyond,
//! always against the slip. It keeps no history.

use super::{NormalOut, TangentialLaw};
use crate::dem::lanes::Num;
use crate::dem::vec3::{norm, scale};
use crate::Real;

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
    fn force<T: Num>(
        &self,
        normal: &NormalOut<T>,
        vt: [T; 3],
        _n: [T; 3],
        _h: &mut [T; 3],
        _dt: T,
    ) -> [T; 3] {
        let speed = norm(vt);
        let gamma = match self.gamma_t {
            Some(g) => T::splat(g),
            None => normal.gamma_n,
        };
        let limit = T::splat(self.mu) * normal.force.max(T::splat(0.0));
        let viscous = gamma * speed;
        let magnitude = T::select(viscous.gt(limit), limit, viscous);
        // A grain with no slip gets no force (and no 0/0).
        let per_speed = T::select(speed.gt(T::splat(0.0)), magnitude / speed, T::splat(0.0));
        scale(vt, -per_speed)
    }
}
