//! What an external engine (LIGGGHTS, YADE) needs to apply the built-in engine's contact
//! laws: absolute constants per material pair for the linear laws, and for Hertz the
//! restitution to hand to the β-damping form those engines use.

use super::config::{DemConfig, LawSet, TangentialSet};
use super::contact::{impact_restitution, invert_restitution};
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
    let LawSet::Hooke(t) = &cfg.laws else {
        return None;
    };
    let (pp, pw) = t.normal();
    let gn_pp = damping(pp.zeta, pp.kn, m_pp);
    let gn_pw = damping(pw.zeta, pw.kn, m_pw);
    // The shear damping: the history law's dashpot on k_t, or the Coulomb law's γ_t.
    // (Both history laws: the scene's dashpot or the normal law's ratio on k_t.)
    let spring = |given_pp: Option<Real>, given_pw: Option<Real>, mu_pp, mu_pw| {
        (
            given_pp.unwrap_or_else(|| damping(pp.zeta, pp.kt, m_pp)),
            given_pw.unwrap_or_else(|| damping(pw.zeta, pw.kt, m_pw)),
            mu_pp,
            mu_pw,
        )
    };
    let (gt_pp, gt_pw, mu_pp, mu_pw) = match t {
        TangentialSet::History(l) => spring(
            l.pp_tangential.gamma_t,
            l.pw_tangential.gamma_t,
            l.pp_tangential.mu,
            l.pw_tangential.mu,
        ),
        TangentialSet::LiggghtsHistory(l) => spring(
            l.pp_tangential.gamma_t,
            l.pw_tangential.gamma_t,
            l.pp_tangential.mu,
            l.pw_tangential.mu,
        ),
        TangentialSet::CoulombViscous(l) => (
            l.pp_tangential.gamma_t.unwrap_or(gn_pp),
            l.pw_tangential.gamma_t.unwrap_or(gn_pw),
            l.pp_tangential.mu,
            l.pw_tangential.mu,
        ),
    };
    Some((
        LinearPair {
            kn: pp.kn,
            kt: pp.kt,
            gamma_n: gn_pp,
            gamma_t: gt_pp,
            mu: mu_pp,
        },
        LinearPair {
            kn: pw.kn,
            kt: pw.kt,
            gamma_n: gn_pw,
            gamma_t: gt_pw,
            mu: mu_pw,
        },
    ))
}

/// The restitution to give an engine whose Hertz damping is −2√(5/6) β √(S_n m*) with
/// β = ln e/√(ln²e + π²) (LIGGGHTS's `model hertz`, YADE's Mindlin law with `en`), so that
/// it damps exactly as the built-in Tsuji form α √(2/3) √(S_n m*): β = −α/√5, hence
/// e = exp(β π / √(1 − β²)). None when |β| ≥ 1 (more damping than that form expresses).
pub fn beta_form_restitution(alpha: Real) -> Option<Real> {
    let beta = -alpha / 5f64.sqrt();
    (beta > -1.0).then(|| (beta * std::f64::consts::PI / (1.0 - beta * beta).sqrt()).exp())
}

/// Damping ratio ζ of a linear spring–dashpot (F = k x + 2ζ√(k m) v) that gives
/// restitution `e` when the contact ends at zero force: what an engine that clamps
/// F_n ≥ 0 needs to reproduce the scene's e.
pub fn linear_cutoff_damping_ratio(e: Real) -> Option<Real> {
    if e >= 1.0 {
        return Some(0.0);
    }
    // YADE's ViscEl law clamps F_n ≥ 0 (its dashpot never pulls): the contact ends at zero
    // force, which keeps more energy than the built-in engine's cutoff at zero overlap.
    invert_restitution(e, |zeta| {
        impact_restitution(|x, v| x + 2.0 * zeta * v, true)
    })
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
            assert!(impact_restitution(|x, v| x + 2.0 * zeta * v, true) > e + 1e-3);
            let z = linear_cutoff_damping_ratio(e).unwrap();
            assert!(z > zeta);
            assert!((impact_restitution(|x, v| x + 2.0 * z * v, true) - e).abs() < 1e-6);
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
