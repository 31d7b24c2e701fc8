//! Cundall–Strack tangential spring with contact history, capped by Coulomb:
//!   ξ ← rotate ξ into the current tangent plane (magnitude kept), ξ += v_t Δt,
//!   F_t = −k_t ξ − γ_t v_t;  if |F_t| > μ|F_n|: F_t ← μ|F_n| F_t/|F_t|, ξ ← −(F_t + γ_t v_t)/k_t.
//! k_t is the law's (Mindlin for Hertz, k_t/k_n ratio for Hooke).

use super::{NormalOut, TangentialLaw};
use crate::dem::lanes::Num;
use crate::dem::vec3::{dot, norm2, scale, sub};
use crate::Real;

/// Parameters of the history law.
#[derive(Debug, Clone)]
pub struct History {
    /// Friction coefficient μ.
    pub mu: Real,
    /// The shear dashpot γ_t, kg/s, when the scene gives it (`contact.tangential_damping`;
    /// 0: none, as LAMMPS's `gran/hooke/history` with dampflag 0); None: the normal law's.
    pub gamma_t: Option<Real>,
}

impl TangentialLaw for History {
    const USES_HISTORY: bool = true;

    fn with_friction(&self, mu: Real) -> Self {
        Self {
            mu,
            gamma_t: self.gamma_t,
        }
    }

    #[inline(always)]
    fn force<T: Num>(
        &self,
        normal: &NormalOut<T>,
        vt: [T; 3],
        n: [T; 3],
        h: &mut [T; 3],
        dt: T,
    ) -> [T; 3] {
        // Keep the stored shear in the tangent plane as the contact rolls, without losing
        // its magnitude. Removing the normal part h·n shrinks |h|² by (h·n)²; the magnitude
        // is restored only when that exceeds 1e-12 |h|² (skipping loses < 5e-13 of |h| per
        // step). Lanes choose by select, not branches; what no lane needs is skipped.
        let gamma_t = self.gamma_t.map_or(normal.gamma_t, T::splat);
        let hn = dot(*h, n);
        let old2 = norm2(*h);
        let hn2 = hn * hn;
        let restore = T::and(hn2.gt(T::splat(1e-12) * old2), old2.gt(hn2));
        let mut in_plane = sub(*h, scale(n, hn));
        if T::any(restore) {
            let factor = T::select(restore, (old2 / (old2 - hn2)).sqrt(), T::splat(1.0));
            in_plane = scale(in_plane, factor);
        }
        let mut shear = [T::splat(0.0); 3];
        for c in 0..3 {
            shear[c] = in_plane[c] + vt[c] * dt;
        }
        let mut ft = [T::splat(0.0); 3];
        for c in 0..3 {
            ft[c] = -normal.kt * shear[c] - gamma_t * vt[c];
        }
        // Coulomb: past μ F_n the force is cut back to the cone and the spring stretched
        // only as far as that force needs.
        let limit = T::splat(self.mu) * normal.force.max(T::splat(0.0));
        let f2 = norm2(ft);
        let slips = f2.gt(limit * limit);
        if T::any(slips) {
            let cut = T::select(slips, limit / f2.sqrt(), T::splat(1.0));
            let reset = T::and(slips, normal.kt.gt(T::splat(0.0)));
            let inv_kt = T::splat(1.0) / normal.kt;
            for c in 0..3 {
                ft[c] = ft[c] * cut;
                shear[c] = T::select(reset, -(ft[c] + gamma_t * vt[c]) * inv_kt, shear[c]);
            }
        }
        *h = shear;
        ft
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The scene's γ_t replaces the normal law's: with 0 (LAMMPS's dampflag 0) a sticking
    /// contact's shear force is the spring's alone; without it the dashpot adds −γ_t v_t.
    #[test]
    fn a_given_shear_dashpot_replaces_the_normal_law_s() {
        let normal = NormalOut {
            force: 1.0,
            elastic: 1.0,
            kt: 100.0,
            gamma_n: 0.3,
            gamma_t: 0.2,
        };
        let (vt, n, dt) = ([0.01, 0.0, 0.0], [0.0, 0.0, 1.0], 1e-3);
        let undamped = History {
            mu: 10.0,
            gamma_t: Some(0.0),
        };
        let mut h = [0.0; 3];
        let f = undamped.force(&normal, vt, n, &mut h, dt);
        assert_eq!(f[0], -100.0 * 1e-5);
        let own = History {
            mu: 10.0,
            gamma_t: None,
        };
        let mut h = [0.0; 3];
        let f = own.force(&normal, vt, n, &mut h, dt);
        assert_eq!(f[0], -100.0 * 1e-5 - 0.2 * 0.01);
    }
}
