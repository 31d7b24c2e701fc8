//! What an external engine (LIGGGHTS, YADE) needs to apply the built-in engine's contact
//! laws: absolute constants per material pair for the linear laws, and for Hertz the
//! restitution to hand to the β-damping form those engines use.

use super::config::{DemConfig, LawSet};
use crate::Real;

/// Absolute contact constants of one pair kind (grain–grain or grain–wall) under the
/// linear spring–dashpot law, valid while every grain has the scene's one size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearPair {
    /// Normal stiffness, N/m.
    pub kn: Real,
    /// Tangential stiffness, N/m.
    pub kt: Real,
    /// Normal damping coefficient, kg/s.
    pub gamma_n: Real,
    /// Tangential damping coefficient, kg/s.
    pub gamma_t: Real,
    /// Friction coefficient.
    pub mu: Real,
}

/// Mass of one grain of the scene's single size, kg (None for several sizes).
pub fn single_grain_mass(cfg: &DemConfig) -> Option<Real> {
    let r = cfg.radius_min;
    ((cfg.radius_max - r).abs() <= 1e-15 * cfg.radius_max)
        .then(|| cfg.density * 4.0 / 3.0 * std::f64::consts::PI * r * r * r)
}

/// (grain–grain, grain–wall) constants of a Hooke scene with one grain size, as the
/// built-in engine evaluates them (effective mass m/2 for a pair, m against a wall; the
/// regularised Coulomb law's γ_t is the pair's γ_n unless the scene gives it). None for
/// Hertz scenes or several grain sizes.
pub fn linear_pairs(cfg: &DemConfig) -> Option<(LinearPair, LinearPair)> {
    let m = single_grain_mass(cfg)?;
    let (m_pp, m_pw) = (0.5 * m, m);
    let damping = |zeta: Real, k: Real, m: Real| 2.0 * zeta * (k * m).sqrt();
    match &cfg.laws {
        LawSet::HookeHistory(l) => Some((
            LinearPair {
                kn: l.pp_normal.kn,
                kt: l.pp_normal.kt,
                gamma_n: damping(l.pp_normal.zeta, l.pp_normal.kn, m_pp),
                gamma_t: damping(l.pp_normal.zeta, l.pp_normal.kt, m_pp),
                mu: l.pp_tangential.mu,
            },
            LinearPair {
                kn: l.pw_normal.kn,
                kt: l.pw_normal.kt,
                gamma_n: damping(l.pw_normal.zeta, l.pw_normal.kn, m_pw),
                gamma_t: damping(l.pw_normal.zeta, l.pw_normal.kt, m_pw),
                mu: l.pw_tangential.mu,
            },
        )),
        LawSet::HookeCoulomb(l) => {
            let gn_pp = damping(l.pp_normal.zeta, l.pp_normal.kn, m_pp);
            let gn_pw = damping(l.pw_normal.zeta, l.pw_normal.kn, m_pw);
            Some((
                LinearPair {
                    kn: l.pp_normal.kn,
                    kt: l.pp_normal.kt,
                    gamma_n: gn_pp,
                    gamma_t: l.pp_tangential.gamma_t.unwrap_or(gn_pp),
                    mu: l.pp_tangential.mu,
                },
                LinearPair {
                    kn: l.pw_normal.kn,
                    kt: l.pw_normal.kt,
                    gamma_n: gn_pw,
                    gamma_t: l.pw_tangential.gamma_t.unwrap_or(gn_pw),
                    mu: l.pw_tangential.mu,
                },
            ))
        }
        LawSet::HertzHistory(_) | LawSet::HertzCoulomb(_) => None,
    }
}

/// The restitution to give an engine whose Hertz damping is −2√(5/6) β √(S_n m*) with
/// β = ln e/√(ln²e + π²) (LIGGGHTS's `model hertz`, YADE's Mindlin law with `en`), so that
/// it damps exactly as the built-in Tsuji form α √(2/3) √(S_n m*): β = −α/√5, hence
/// e = exp(β π / √(1 − β²)). None when |β| ≥ 1 (more damping than that form expresses).
pub fn beta_form_restitution(alpha: Real) -> Option<Real> {
    let beta = -alpha / 5f64.sqrt();
    (beta > -1.0).then(|| (beta * std::f64::consts::PI / (1.0 - beta * beta).sqrt()).exp())
}

/// Restitution of a unit-speed impact (m = 1, x(0) = 0, v(0) = 1) under the normal force
/// `force(x, v)` when the contact ends as soon as that force reaches zero, as in engines
/// whose dashpot never pulls (YADE's ViscEl law clamps F_n ≥ 0). The built-in
/// engine lets the dashpot pull until the overlap closes; cutting it off earlier loses
/// less energy, so the same damping gives a higher restitution. RK4, dimensionless.
fn cutoff_restitution(force: impl Fn(Real, Real) -> Real) -> Real {
    let h = 2e-4;
    let (mut x, mut v) = (0.0_f64, 1.0_f64);
    let acc = |x: Real, v: Real| -force(x.max(0.0), v);
    let mut t = 0.0;
    while t < 100.0 {
        let (k1x, k1v) = (v, acc(x, v));
        let (k2x, k2v) = (v + 0.5 * h * k1v, acc(x + 0.5 * h * k1x, v + 0.5 * h * k1v));
        let (k3x, k3v) = (v + 0.5 * h * k2v, acc(x + 0.5 * h * k2x, v + 0.5 * h * k2v));
        let (k4x, k4v) = (v + h * k3v, acc(x + h * k3x, v + h * k3v));
        let xn = x + h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
        let vn = v + h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
        t += h;
        let (f0, f1) = (force(x.max(0.0), v), force(xn.max(0.0), vn));
        if t > h && (f1 <= 0.0 || xn <= 0.0) {
            // Interpolate the exit speed linearly to the zero of the force.
            let s = if f0 > f1 { f0 / (f0 - f1) } else { 1.0 };
            return -(v + s.clamp(0.0, 1.0) * (vn - v));
        }
        x = xn;
        v = vn;
    }
    0.0
}

/// Largest damping parameter on a bisection: restitution(p) decreases with p; the p that
/// gives `e`, or None when even p = 64 leaves more than `e`.
fn invert_restitution(e: Real, restitution: impl Fn(Real) -> Real) -> Option<Real> {
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    while restitution(hi) > e {
        hi *= 2.0;
        if hi > 64.0 {
            return None;
        }
    }
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if restitution(mid) > e {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo < 1e-10 {
            break;
        }
    }
    Some(0.5 * (lo + hi))
}

/// Damping ratio ζ of a linear spring–dashpot (F = k x + 2ζ√(k m) v) that gives
/// restitution `e` when the contact ends at zero force: what an engine that clamps
/// F_n ≥ 0 needs to reproduce the scene's e.
pub fn linear_cutoff_damping_ratio(e: Real) -> Option<Real> {
    if e >= 1.0 {
        return Some(0.0);
    }
    invert_restitution(e, |zeta| cutoff_restitution(|x, v| x + 2.0 * zeta * v))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dem::contact::hooke_damping_ratio;

    /// Cutting the contact off at zero force keeps more energy: the damping that gives e
    /// with the pulling dashpot gives more than e with the cutoff, and the cutoff damping
    /// found by inversion gives e back (to the bisection's 1e-6).
    #[test]
    fn cutoff_damping_gives_the_restitution_back() {
        for e in [0.1, 0.5, 0.9] {
            let zeta = hooke_damping_ratio(e);
            assert!(cutoff_restitution(|x, v| x + 2.0 * zeta * v) > e + 1e-3);
            let z = linear_cutoff_damping_ratio(e).unwrap();
            assert!(z > zeta);
            assert!((cutoff_restitution(|x, v| x + 2.0 * z * v) - e).abs() < 1e-6);
        }
    }

    /// The β-form restitution inverts the Tsuji constant: β = −α/√5 with β from e.
    #[test]
    fn beta_form_restitution_matches_beta() {
        let alpha = 1.2;
        let e = beta_form_restitution(alpha).unwrap();
        let beta = e.ln() / (e.ln().powi(2) + std::f64::consts::PI.powi(2)).sqrt();
        assert!((beta + alpha / 5f64.sqrt()).abs() < 1e-12);
    }
}
