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

    fn with_friction(&self, mu: Real) -> Self {
        Self { mu }
    }

    #[inline(always)]
    fn force(&self, normal: &NormalOut, vt: Vec3, n: Vec3, h: &mut Vec3, dt: Real) -> Vec3 {
        // Keep the stored shear in the tangent plane as the contact rolls, without losing
        // its magnitude. Removing the normal part h·n shrinks |h|² by (h·n)²; we restore the
        // magnitude only when that exceeds 1e-12 |h|² (a static contact never pays the
        // division and square root; skipping loses < 5e-13 of |h| per step).
        let hn = dot(*h, n);
        if hn != 0.0 {
            let old2 = norm2(*h);
            *h = sub(*h, scale(n, hn));
            let hn2 = hn * hn;
            if hn2 > 1e-12 * old2 && old2 > hn2 {
                *h = scale(*h, (old2 / (old2 - hn2)).sqrt());
            }
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
