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
}

impl TangentialLaw for History {
    const USES_HISTORY: bool = true;

    fn with_friction(&self, mu: Real) -> Self {
        Self { mu }
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
            ft[c] = -normal.kt * shear[c] - normal.gamma_t * vt[c];
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
                shear[c] = T::select(reset, -(ft[c] + normal.gamma_t * vt[c]) * inv_kt, shear[c]);
            }
        }
        *h = shear;
        ft
    }
}
