//! LIGGGHTS's shear spring with history (`tangential history`, its
//! `tangential_model_history.h`), for cross-validation against LIGGGHTS term for term:
//!   ξ += v_t Δt, then ξ ← ξ − (ξ·n) n (projected, its magnitude not restored);
//!   F_el = −k_t ξ;  if |F_el| > μ |F_n|: F_t = μ|F_n| F_el/|F_el|, ξ = −F_t/k_t (sliding:
//!   no dashpot);  else F_t = F_el − γ_t v_t.
//! It differs from [`History`](super::History) (LAMMPS's `gran/hooke/history`, Cundall–
//! Strack with the dashpot inside the Coulomb cap) in three places: the cap compares the
//! spring alone with μ|F_n|, |F_n| of the whole normal force (spring and dashpot, so a
//! separating, damped contact still rubs); a sliding contact loses its dashpot; and the
//! stretched spring keeps −F_t/k_t. A sliding, rolling contact ends differently: measured on
//! an oblique collision with μ = 0.5, exit v_x −0.0256 m/s and spin 157 rad/s under `history`,
//! −0.0238 and 145.6 under this law, LIGGGHTS −0.0232 and 146.6 (tests/cross_code.rs (g)).

use super::{NormalOut, TangentialLaw};
use crate::dem::lanes::Num;
use crate::dem::vec3::{dot, norm2};
use crate::Real;

/// Parameters of LIGGGHTS's history law.
#[derive(Debug, Clone)]
pub struct LiggghtsHistory {
    /// Friction coefficient μ.
    pub mu: Real,
    /// The shear dashpot γ_t, kg/s, when the scene gives it; None: the normal law's.
    pub gamma_t: Option<Real>,
}

impl TangentialLaw for LiggghtsHistory {
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
        let gamma_t = self.gamma_t.map_or(normal.gamma_t, T::splat);
        let mut shear = [T::splat(0.0); 3];
        for c in 0..3 {
            shear[c] = h[c] + vt[c] * dt;
        }
        let sn = dot(shear, n);
        for c in 0..3 {
            shear[c] = shear[c] - sn * n[c];
        }
        let mut elastic = [T::splat(0.0); 3];
        for c in 0..3 {
            elastic[c] = T::splat(0.0) - normal.kt * shear[c];
        }
        // μ |F_n|: the normal force's magnitude, dashpot included, whatever its sign.
        let fn_abs = normal.force.max(T::splat(0.0) - normal.force);
        let limit = T::splat(self.mu) * fn_abs;
        let f2 = norm2(elastic);
        let slips = f2.gt(limit * limit);
        let cut = T::select(slips, limit / f2.sqrt(), T::splat(1.0));
        let inv_kt = T::splat(1.0) / normal.kt;
        let mut ft = [T::splat(0.0); 3];
        for c in 0..3 {
            let capped = elastic[c] * cut;
            ft[c] = T::select(slips, capped, elastic[c] - gamma_t * vt[c]);
            shear[c] = T::select(slips, T::splat(0.0) - capped * inv_kt, shear[c]);
        }
        *h = shear;
        ft
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn normal(force: Real) -> NormalOut {
        NormalOut {
            force,
            elastic: force,
            kt: 100.0,
            gamma_n: 0.0,
            gamma_t: 0.5,
        }
    }

    /// Sticking: spring and dashpot; sliding: the spring alone, cut to μ|F_n| (compared
    /// without the dashpot), the stretch kept at −F_t/k_t; a separating contact (F_n < 0)
    /// still rubs with μ|F_n| — LIGGGHTS's three conventions, by hand.
    #[test]
    fn sticks_with_its_dashpot_and_slides_without() {
        let law = LiggghtsHistory {
            mu: 0.5,
            gamma_t: None,
        };
        let n = [0.0, 0.0, 1.0];
        // Sticking: ξ = 1e-3 → spring 0.1 N < μ F_n = 0.5 N; dashpot 0.5 × 0.2.
        let mut h = [0.0; 3];
        let f = law.force(&normal(1.0), [0.2, 0.0, 0.0], n, &mut h, 5e-3);
        assert!((f[0] - (-0.1 - 0.1)).abs() < 1e-15, "{f:?}");
        assert!((h[0] - 1e-3).abs() < 1e-18);
        // The spring alone (0.4 N) under the cap though with the dashpot it would exceed it.
        let mut h = [3e-3, 0.0, 0.0];
        let f = law.force(&normal(1.0), [0.2, 0.0, 0.0], n, &mut h, 5e-3);
        assert!((f[0] - (-0.4 - 0.1)).abs() < 1e-15, "{f:?}");
        // Sliding: spring 1 N > 0.5 N: cut to 0.5 N, no dashpot, ξ = 5e-3.
        let mut h = [9e-3, 0.0, 0.0];
        let f = law.force(&normal(1.0), [0.2, 0.0, 0.0], n, &mut h, 5e-3);
        assert!(
            (f[0] + 0.5).abs() < 1e-15 && (h[0] - 5e-3).abs() < 1e-18,
            "{f:?} {h:?}"
        );
        // Separating and damped (F_n = −1 N): still μ |F_n| = 0.5 N.
        let mut h = [9e-3, 0.0, 0.0];
        let f = law.force(&normal(-1.0), [0.2, 0.0, 0.0], n, &mut h, 5e-3);
        assert!((f[0] + 0.5).abs() < 1e-15, "{f:?}");
        // The stored shear leaves the tangent plane's normal part behind.
        let mut h = [1e-3, 0.0, 1e-3];
        law.force(&normal(1.0), [0.0; 3], n, &mut h, 5e-3);
        assert_eq!(h[2], 0.0);
    }
}
