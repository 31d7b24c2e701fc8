//! Velocity-Verlet over one chunk of grains: half kicks v += F/m · dt/2, the drift
//! x += v · dt, and the velocities the dashpots of the next force pass see (see
//! [`NativeDem`](super::NativeDem)'s `predict_velocities` for why they are predicted).
//!
//! Every step passes over all grains, so the pass is written for the vector units: the only
//! reductions are boolean ORs and ANDs (a running maximum of the displacement would chain
//! every grain on the latency of one `max`), and on x86-64 CPUs with AVX2 the same code is
//! compiled for 4-wide registers and chosen at run time. No FMA: both paths round alike.

use super::vec3::norm2;
use crate::{Real, Vec3};

/// A speed no grain of a conveying run reaches, m/s: above it a run is declared blown up.
/// 10 km/s, and a diverging integration passes it long before reaching infinity or NaN.
pub const BLOWUP_SPEED: Real = 1e4;

/// The columns of grains [lo, hi) one pass reads and writes.
pub struct ChunkColumns<'a> {
    /// Total force of the step, N.
    pub force: &'a [Vec3],
    /// Total torque of the step, N·m.
    pub torque: &'a [Vec3],
    pub inv_mass: &'a [Real],
    pub inv_inertia: &'a [Real],
    pub velocity: &'a mut [Vec3],
    pub position: &'a mut [Vec3],
    pub angular_velocity: &'a mut [Vec3],
    /// Written when the pass starts a step: v(t + dt) predicted.
    pub velocity_pred: &'a mut [Vec3],
    pub angular_velocity_pred: &'a mut [Vec3],
    /// Positions at the last neighbour build (`None` when none is tracked yet).
    pub reference: Option<&'a [Vec3]>,
}

/// What one pass does.
#[derive(Clone, Copy)]
pub struct PassKind {
    /// Time step, s.
    pub dt: Real,
    /// Finish a step: the second half kick.
    pub finish: bool,
    /// Start a step: half kick, drift, predict.
    pub start: bool,
    pub rotation: bool,
}

/// The outcome of a pass over one chunk.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChunkVerdict {
    /// All speeds finite and below [`BLOWUP_SPEED`].
    pub sane: bool,
    /// The two largest squared drifts since the last neighbour build, largest first, m².
    pub drift2: [Real; 2],
}

impl ChunkVerdict {
    /// The verdict on no grains at all.
    pub const CLEAN: Self = Self {
        sane: true,
        drift2: [0.0; 2],
    };

    /// The verdict on two sets of grains together.
    pub fn and(self, other: Self) -> Self {
        let mut v = Self {
            sane: self.sane && other.sane,
            ..self
        };
        for d2 in other.drift2 {
            v.saw_drift2(d2);
        }
        v
    }

    /// Take one grain's squared drift into the two largest.
    #[inline(always)]
    fn saw_drift2(&mut self, d2: Real) {
        // (Rarely true once the pass has met a few grains: a well predicted branch.)
        if d2 > self.drift2[1] {
            if d2 > self.drift2[0] {
                self.drift2 = [d2, self.drift2[0]];
            } else {
                self.drift2[1] = d2;
            }
        }
    }

    /// Whether the neighbour list with Verlet skin `skin` may have missed a pair: two
    /// grains close by at most the sum of their drifts, so none can have crossed the skin
    /// while the two largest drifts add up to at most the skin. (The usual test, a rebuild
    /// once any grain drifted half the skin, rebuilds when a single fast grain does; here
    /// that grain may go on until the second fastest and it together cover the skin. The
    /// wall lists and the outlet's list are taken one full skin out, so they hold too.)
    pub fn moved_far(&self, skin: Real) -> bool {
        self.drift2[0].sqrt() + self.drift2[1].sqrt() > skin
    }
}

/// One pass of the integrator over a chunk.
pub fn integrate_chunk(cols: ChunkColumns<'_>, kind: PassKind) -> ChunkVerdict {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2 (checked just above).
        return unsafe { integrate_chunk_avx2(cols, kind) };
    }
    integrate_chunk_body(cols, kind)
}

/// [`integrate_chunk_body`] compiled for AVX2 (no FMA: the same roundings as the baseline).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn integrate_chunk_avx2(cols: ChunkColumns<'_>, kind: PassKind) -> ChunkVerdict {
    integrate_chunk_body(cols, kind)
}

#[inline(always)]
fn integrate_chunk_body(cols: ChunkColumns<'_>, kind: PassKind) -> ChunkVerdict {
    let ChunkColumns {
        force,
        torque,
        inv_mass,
        inv_inertia,
        velocity,
        position,
        angular_velocity,
        velocity_pred,
        angular_velocity_pred,
        reference,
    } = cols;
    let n = velocity.len();
    let mut verdict = ChunkVerdict::CLEAN;
    let linear = Kicked {
        rate: &force[..n],
        inv_inertia: &inv_mass[..n],
        value: velocity,
        predicted: &mut velocity_pred[..n],
        // NaN compares false, so the check also catches NaN and infinity.
        sane_below2: BLOWUP_SPEED * BLOWUP_SPEED,
    };
    let drift = Drift {
        position: &mut position[..n],
        reference: reference.map(|r| &r[..n]),
    };
    kick_pass(linear, Some(drift), kind, &mut verdict);
    if kind.rotation {
        let angular = Kicked {
            rate: &torque[..n],
            inv_inertia: &inv_inertia[..n],
            value: &mut angular_velocity[..n],
            predicted: &mut angular_velocity_pred[..n],
            // Angular velocities need only be finite.
            sane_below2: Real::INFINITY,
        };
        kick_pass(angular, None, kind, &mut verdict);
    }
    verdict
}

/// A velocity-like column and what kicks it: v += rate · inv_inertia · dt/2.
struct Kicked<'a> {
    rate: &'a [Vec3],
    /// 1/mass or 1/moment of inertia.
    inv_inertia: &'a [Real],
    value: &'a mut [Vec3],
    predicted: &'a mut [Vec3],
    /// A kicked value is sane while its squared norm is below this.
    sane_below2: Real,
}

/// The positions the velocities drift, and where they were at the last neighbour build.
struct Drift<'a> {
    position: &'a mut [Vec3],
    reference: Option<&'a [Vec3]>,
}

/// Grains handled together: 4 grains are 12 components, three 4-wide registers, so the
/// kicks and the drift run as plain vector operations on the flattened arrays.
const BLOCK: usize = 4;
/// Components of a block.
const SPAN: usize = 3 * BLOCK;

/// One column's kicks (and for velocities, the drift and skin check) over the chunk.
#[inline(always)]
fn kick_pass(
    mut cols: Kicked<'_>,
    mut drift: Option<Drift<'_>>,
    kind: PassKind,
    verdict: &mut ChunkVerdict,
) {
    let n = cols.value.len();
    let full = n / BLOCK * BLOCK;
    for b in (0..full).step_by(BLOCK) {
        kick_block::<BLOCK>(&mut cols, &mut drift, b, kind, verdict);
    }
    // The last grains as blocks of one: the same operations in the same order.
    for b in full..n {
        kick_block::<1>(&mut cols, &mut drift, b, kind, verdict);
    }
}

/// Grains b..b+G of one column (G ≤ [`BLOCK`]; the arrays hold a whole block, of which the
/// first 3G components are used).
#[inline(always)]
fn kick_block<const G: usize>(
    cols: &mut Kicked<'_>,
    drift: &mut Option<Drift<'_>>,
    b: usize,
    kind: PassKind,
    verdict: &mut ChunkVerdict,
) {
    let PassKind {
        dt, finish, start, ..
    } = kind;
    let h = 0.5 * dt;
    let c = 3 * G;
    let at = 3 * b;
    let load = |all: &[Real]| -> [Real; SPAN] {
        let mut out = [0.0; SPAN];
        out[..c].copy_from_slice(&all[at..at + c]);
        out
    };
    let a: [Real; SPAN] = std::array::from_fn(|m| cols.inv_inertia[b + (m / 3).min(G - 1)] * h);
    let f = load(cols.rate.as_flattened());
    let mut v = load(cols.value.as_flattened());
    if finish {
        v = std::array::from_fn(|m| v[m] + f[m] * a[m]);
        for g in 0..G {
            verdict.sane &= norm2(part(&v, g)) < cols.sane_below2;
        }
    }
    if start {
        v = std::array::from_fn(|m| v[m] + f[m] * a[m]);
        let p: [Real; SPAN] = std::array::from_fn(|m| v[m] + f[m] * a[m]);
        cols.predicted.as_flattened_mut()[at..at + c].copy_from_slice(&p[..c]);
        if let Some(Drift {
            position,
            reference,
        }) = drift.as_mut()
        {
            let mut x = load(position.as_flattened());
            x = std::array::from_fn(|m| x[m] + v[m] * dt);
            position.as_flattened_mut()[at..at + c].copy_from_slice(&x[..c]);
            if let Some(reference) = reference {
                let r = load(reference.as_flattened());
                let d: [Real; SPAN] = std::array::from_fn(|m| x[m] - r[m]);
                for g in 0..G {
                    verdict.saw_drift2(norm2(part(&d, g)));
                }
            }
        }
    }
    cols.value.as_flattened_mut()[at..at + c].copy_from_slice(&v[..c]);
}

/// Grain g's three components of a block.
#[inline(always)]
fn part(block: &[Real; SPAN], g: usize) -> Vec3 {
    [block[3 * g], block[3 * g + 1], block[3 * g + 2]]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// The textbook kick of one grain: v + f · a.
    fn kick(v: Vec3, f: Vec3, a: Real) -> Vec3 {
        [v[0] + f[0] * a, v[1] + f[1] * a, v[2] + f[2] * a]
    }

    /// Grains in blocks and in the ragged tail must get exactly what the textbook update
    /// gives one grain at a time, and both flags must see a grain wherever it sits.
    #[test]
    fn blocks_and_tail_give_the_one_grain_update_bit_for_bit() {
        // The dispatched build (AVX2 where the CPU has it) and the baseline build.
        let bodies: [fn(ChunkColumns<'_>, PassKind) -> ChunkVerdict; 2] =
            [integrate_chunk, |c, k| integrate_chunk_body(c, k)];
        for body in bodies {
            check_body(body);
        }
    }

    fn check_body(body: fn(ChunkColumns<'_>, PassKind) -> ChunkVerdict) {
        let n = 7; // one block of 4, a tail of 3
        let mut rng = Rng::new(3);
        let mut col = |s: Real| -> Vec<Vec3> {
            (0..n)
                .map(|_| std::array::from_fn(|_| s * (rng.uniform() - 0.5)))
                .collect()
        };
        let (force, torque, v0, w0) = (col(1e-3), col(1e-7), col(0.5), col(100.0));
        let (x0, drift) = (col(0.01), col(1e-4));
        let x_ref: Vec<Vec3> = (0..n)
            .map(|k| std::array::from_fn(|c| x0[k][c] - drift[k][c]))
            .collect();
        let inv_mass: Vec<Real> = (0..n).map(|k| 1e5 * (1.0 + k as Real)).collect();
        let inv_inertia: Vec<Real> = (0..n).map(|k| 1e10 * (1.0 + k as Real)).collect();
        let kind = PassKind {
            dt: 5e-6,
            finish: true,
            start: true,
            rotation: true,
        };
        let run =
            |v: &mut Vec<Vec3>, x: &mut Vec<Vec3>, w: &mut Vec<Vec3>, x_ref: &[Vec3], kind| {
                let (mut vp, mut wp) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
                let verdict = body(
                    ChunkColumns {
                        force: &force,
                        torque: &torque,
                        inv_mass: &inv_mass,
                        inv_inertia: &inv_inertia,
                        velocity: v,
                        position: x,
                        angular_velocity: w,
                        velocity_pred: &mut vp,
                        angular_velocity_pred: &mut wp,
                        reference: Some(x_ref),
                    },
                    kind,
                );
                (verdict, vp, wp)
            };
        let (mut v, mut x, mut w) = (v0.clone(), x0.clone(), w0.clone());
        let (verdict, vp, wp) = run(&mut v, &mut x, &mut w, &x_ref, kind);
        assert!(verdict.sane && !verdict.moved_far(1e-3));
        let h = 0.5 * kind.dt;
        for k in 0..n {
            let (a, b) = (inv_mass[k] * h, inv_inertia[k] * h);
            let v_half = kick(kick(v0[k], force[k], a), force[k], a);
            let x_new: Vec3 = std::array::from_fn(|c| x0[k][c] + v_half[c] * kind.dt);
            let w_half = kick(kick(w0[k], torque[k], b), torque[k], b);
            assert_eq!(v[k], v_half, "velocity of grain {k}");
            assert_eq!(x[k], x_new, "position of grain {k}");
            assert_eq!(vp[k], kick(v_half, force[k], a), "predicted velocity {k}");
            assert_eq!(w[k], w_half, "angular velocity of grain {k}");
            assert_eq!(wp[k], kick(w_half, torque[k], b), "predicted spin {k}");
        }
        // A grain that drifted the skin (1 mm here; the drifts above are below 0.1 mm),
        // or blew up, is seen in a block and in the tail.
        let skin = 1e-3;
        for k in [1, 5] {
            // The verdict after `edit` changes the velocities or spins of the fresh state.
            let verdict = |edit: &dyn Fn(&mut [Vec3], &mut [Vec3]), x_ref: &[Vec3], kind| {
                let (mut v, mut x, mut w) = (v0.clone(), x0.clone(), w0.clone());
                edit(&mut v, &mut w);
                run(&mut v, &mut x, &mut w, x_ref, kind).0
            };
            let untouched = |_: &mut [Vec3], _: &mut [Vec3]| {};
            assert!(!verdict(&untouched, &x_ref, kind).moved_far(skin));
            let mut moved = x_ref.clone();
            moved[k][1] -= 2e-3;
            assert!(
                verdict(&untouched, &moved, kind).moved_far(skin),
                "grain {k} far"
            );
            // Two grains that each drifted 0.6 of the skin may have closed on each other
            // past it; one alone (the others below 0.1 of it) may not.
            let mut one = x_ref.clone();
            one[k][1] -= 0.6e-3;
            assert!(
                !verdict(&untouched, &one, kind).moved_far(skin),
                "grain {k} alone"
            );
            one[(k + 3) % n][0] += 0.6e-3;
            assert!(
                verdict(&untouched, &one, kind).moved_far(skin),
                "grain {k} and another"
            );
            let nan = |v: &mut [Vec3], _: &mut [Vec3]| v[k][2] = Real::NAN;
            assert!(!verdict(&nan, &x_ref, kind).sane, "NaN in grain {k}");
            let fast = |v: &mut [Vec3], _: &mut [Vec3]| v[k][0] = 2.0 * BLOWUP_SPEED;
            assert!(!verdict(&fast, &x_ref, kind).sane, "speed of grain {k}");
            let spin = |_: &mut [Vec3], w: &mut [Vec3]| w[k][0] = Real::INFINITY;
            assert!(!verdict(&spin, &x_ref, kind).sane, "spin of grain {k}");
        }
    }
}
