//! Contact laws. Each law is one file implementing one trait; the force loop is generic over
//! the pair (normal law, tangential law) so the chosen laws are inlined into it.
//!
//! Sign conventions: `n` is the unit vector from grain i to its partner (grain j or the
//! wall), `overlap` δ > 0 in contact, `vn` = (v_i − v_j)·n > 0 while approaching.

pub mod constant_torque;
pub mod coulomb_viscous;
pub mod hertz;
pub mod history;
pub mod hooke;
pub mod liggghts_history;

pub use constant_torque::{ConstantTorque, TorqueReading};
pub use coulomb_viscous::CoulombViscous;
pub use hertz::Hertz;
pub use history::History;
pub use hooke::Hooke;
pub use liggghts_history::LiggghtsHistory;

use crate::dem::lanes::Num;
use crate::Real;

/// What the normal law hands to the tangential law, for one contact (`T` = `Real`) or a
/// group of lanes ([`Lanes`](crate::dem::lanes::Lanes)).
#[derive(Debug, Clone, Copy)]
pub struct NormalOut<T = Real> {
    /// Normal force magnitude, N, repulsive positive (elastic + viscous; may be negative at
    /// the end of a damped contact, as in LIGGGHTS' default).
    pub force: T,
    /// Its elastic part alone, N (what a rolling law's torque scales with).
    pub elastic: T,
    /// Tangential spring stiffness for this overlap, N/m.
    pub kt: T,
    /// Normal damping coefficient for this overlap, kg/s.
    pub gamma_n: T,
    /// Tangential damping coefficient, kg/s.
    pub gamma_t: T,
}

/// A normal force law for one kind of pair (grain–grain or grain–wall). Written over
/// [`Num`] so one body serves a single contact and a group of lanes; it must not branch on
/// values (use [`Num::select`]).
pub trait NormalLaw: Clone + Send + Sync {
    /// Force for overlap δ (m) and approach speed `vn` (m/s) of a pair with effective mass
    /// `m_eff` (kg), its square root `sqrt_m_eff` (passed in so a monodisperse run computes
    /// it once), and effective radius `r_eff` (m).
    fn evaluate<T: Num>(&self, sqrt_m_eff: T, r_eff: T, overlap: T, vn: T) -> NormalOut<T>;
    /// Duration of a collision at impact speed `v` (Hertz depends on it, Hooke does not), s.
    fn contact_time(&self, m_eff: Real, r_eff: Real, v: Real) -> Real;
}

/// A tangential force law for one kind of pair; like [`NormalLaw`], branch-free over [`Num`].
pub trait TangentialLaw: Clone + Send + Sync {
    /// True when the law keeps a per-contact shear displacement.
    const USES_HISTORY: bool;
    /// Tangential force on grain i for slip velocity `vt` (m/s, in the tangent plane),
    /// updating the contact's shear `history` (m) over `dt` (s).
    fn force<T: Num>(
        &self,
        normal: &NormalOut<T>,
        vt: [T; 3],
        n: [T; 3],
        history: &mut [T; 3],
        dt: T,
    ) -> [T; 3];
    /// The same law with friction coefficient `mu`.
    fn with_friction(&self, mu: Real) -> Self;
}

/// A rolling-resistance law for one kind of pair: a torque against the relative rotation.
/// Branch-free over [`Num`] like the other laws; [`NoRolling`] compiles to nothing.
pub trait RollingLaw: Clone + Send + Sync {
    /// False for [`NoRolling`]: the force loop then neither computes nor adds a torque.
    const ACTIVE: bool;
    /// Torque on grain i, N·m, from the pair's normal force (its elastic part and the whole,
    /// N, repulsive positive), effective radius R* (m), relative angular velocity ω_i − ω_j
    /// (rad/s) and unit normal `n` (i → partner). Its partner takes the opposite torque.
    fn torque<T: Num>(
        &self,
        elastic_force: T,
        normal_force: T,
        r_eff: T,
        w_rel: [T; 3],
        n: [T; 3],
    ) -> [T; 3];
}

/// No rolling resistance (the default): grains roll freely but for their tangential forces.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoRolling;

impl RollingLaw for NoRolling {
    const ACTIVE: bool = false;
    #[inline(always)]
    fn torque<T: Num>(&self, _: T, _: T, _: T, _: [T; 3], _: [T; 3]) -> [T; 3] {
        [T::splat(0.0); 3]
    }
}

/// The rolling law of a scene's grain–grain and grain–wall pairs.
#[derive(Debug, Clone)]
pub struct RollingPair<R> {
    /// Grain–grain.
    pub pp: R,
    /// Grain–wall.
    pub pw: R,
}

/// |ln e| / sqrt(π² + ln² e): the damping ratio of a linear spring–dashpot that gives
/// restitution e (exact for the undamped-cutoff Hooke contact).
pub fn hooke_damping_ratio(e: Real) -> Real {
    let l = e.ln().abs();
    l / (std::f64::consts::PI.powi(2) + l * l).sqrt()
}

/// Restitution of a unit-speed impact (m = 1, x(0) = 0, v(0) = 1) under the normal force
/// `force(x, v)`, integrated with RK4 in dimensionless time. The contact ends when the
/// overlap closes or, with `end_at_zero_force` (engines whose dashpot never pulls), as soon
/// as the force reaches zero; the exit speed is interpolated to that crossing.
pub fn impact_restitution(force: impl Fn(Real, Real) -> Real, end_at_zero_force: bool) -> Real {
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
        if t > h {
            if end_at_zero_force {
                let (f0, f1) = (force(x.max(0.0), v), force(xn.max(0.0), vn));
                if f1 <= 0.0 || xn <= 0.0 {
                    let s = if f0 > f1 { f0 / (f0 - f1) } else { 1.0 };
                    return -(v + s.clamp(0.0, 1.0) * (vn - v));
                }
            } else if xn <= 0.0 {
                let s = x / (x - xn);
                return -(v + s * (vn - v));
            }
        }
        x = xn;
        v = vn;
    }
    0.0 // over-damped: never leaves
}

/// The damping parameter that gives restitution `e`, by bisection on `restitution`
/// (decreasing in the parameter); None when even 64 leaves more than `e`. Exact to 1e-10
/// in the parameter.
pub fn invert_restitution(e: Real, restitution: impl Fn(Real) -> Real) -> Option<Real> {
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

/// Restitution of the Tsuji-damped Hertz oscillator x'' + α x^{1/4} x' + x^{3/2} = 0 with
/// unit impact speed. It depends on α alone (the model's point: e independent of speed).
pub fn tsuji_restitution(alpha: Real) -> Real {
    impact_restitution(|x, v| x * x.sqrt() + alpha * x.sqrt().sqrt() * v, false)
}

/// The Tsuji damping constant α that gives restitution `e` (bisection on
/// [`tsuji_restitution`], monotone decreasing in α).
pub fn tsuji_alpha(e: Real) -> Real {
    if e >= 1.0 {
        return 0.0;
    }
    invert_restitution(e, tsuji_restitution).unwrap_or(64.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tsuji_alpha_inverts_restitution() {
        for e in [0.1, 0.5, 0.8, 0.99] {
            let a = tsuji_alpha(e);
            assert!((tsuji_restitution(a) - e).abs() < 1e-6, "e={e} alpha={a}");
        }
        // Undamped Hertz returns its impact speed.
        assert!((tsuji_restitution(0.0) - 1.0).abs() < 1e-6);
    }
}
