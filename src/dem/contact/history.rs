//! Cundall–Strack tangential spring with contact history, capped by Coulomb:
//!   ξ ← rotate ξ into the current tangent plane (magnitude kept), ξ += v_t Δt,
//!   F_t = −k_t ξ − γ_t v_t;  if |F_t| > μ|F_n|: F_t ← μ|F_n| F_t/|F_t|, ξ ← −(F_t + γ_t v_t)/k_t.
//! k_t is the law's (Mindlin for Hertz, k_t/k_n ratio for Hooke).

use super::{NormalOut, TangentialLaw};
use crate::dem::vec3::{dot, norm2, scale, sub};
use crate::{Real, Vec3};

/// Parameters of the history law.
#[derive(Debug, Clone)]
pub struct History {
    /// Friction coefficient μ.
    pub mu: Real,
}

impl TangentialLaw for History {
    const USES_HISTORY: bool = true;

    #[inline(always)]
    fn force(&self, normal: &NormalOut, vt: Vec3, n: Vec3, h: &mut Vec3, dt: Real) -> Vec3 {
        // Keep the stored shear in the tangent plane as the contact rolls, without losing
        // its magnitude.
        let old2 = norm2(*h);
        if old2 > 0.0 {
            let proj = sub(*h, scale(n, dot(*h, n)));
            let new2 = norm2(proj);
            // The normal turns little per step, so old2/new2 = 1 + ε with tiny ε; then
            // sqrt(1 + ε) = 1 + ε/2 to O(ε²) spares a square root per contact.
            let ratio = if new2 > 0.0 { old2 / new2 } else { 0.0 };
            let eps = ratio - 1.0;
            let factor = if eps.abs() < 1e-6 {
                1.0 + 0.5 * eps
            } else {
                ratio.sqrt()
            };
            *h = scale(proj, factor);
        }
        h[0] += vt[0] * dt;
        h[1] += vt[1] * dt;
        h[2] += vt[2] * dt;
        let mut ft = [
            -normal.kt * h[0] - normal.gamma_t * vt[0],
            -normal.kt * h[1] - normal.gamma_t * vt[1],
            -normal.kt * h[2] - normal.gamma_t * vt[2],
        ];
        let limit = self.mu * normal.force.max(0.0);
        let f2 = norm2(ft);
        if f2 > limit * limit {
            let s = if f2 > 0.0 { limit / f2.sqrt() } else { 0.0 };
            ft = scale(ft, s);
            if normal.kt > 0.0 {
                let inv = 1.0 / normal.kt;
                *h = [
                    -(ft[0] + normal.gamma_t * vt[0]) * inv,
                    -(ft[1] + normal.gamma_t * vt[1]) * inv,
                    -(ft[2] + normal.gamma_t * vt[2]) * inv,
                ];
            }
        }
        ft
    }
}
