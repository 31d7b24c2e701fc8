//! Grain state in plain structure-of-arrays containers. Steppers take it by `&mut`.

use super::neighbor::MIN_ROWS_PER_MEMBER;
use super::team::{share, Shared, Team};
use crate::{Real, Vec3};

/// How much heavier a frozen grain is made than its own mass (see
/// [`ParticleState::freeze_last`]).
pub const FROZEN_MASS_FACTOR: Real = 1e30;

/// All per-grain arrays; index `i` is the same grain in every array. The order changes when
/// the neighbour list re-sorts grains for locality; `id` is the stable name.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct ParticleState {
    /// Stable identifiers.
    pub id: Vec<u64>,
    /// Centre positions, m.
    pub position: Vec<Vec3>,
    /// Velocities, m/s.
    pub velocity: Vec<Vec3>,
    /// Angular velocities, rad/s (stay zero when rotation is off).
    pub angular_velocity: Vec<Vec3>,
    /// Total force of the current step, N.
    pub force: Vec<Vec3>,
    /// Total torque of the current step, N·m (unused when rotation is off).
    pub torque: Vec<Vec3>,
    /// Fluid force written by the coupling, held over a coupling interval, N.
    pub external_force: Vec<Vec3>,
    /// Radii, m.
    pub radius: Vec<Real>,
    /// Masses, kg.
    pub mass: Vec<Real>,
    /// 1 / mass, 1/kg.
    pub inv_mass: Vec<Real>,
    /// 1 / moment of inertia (solid sphere, 2/5 m r²), 1/(kg m²).
    pub inv_inertia: Vec<Real>,
    /// Tangential history against each wall: `walls` entries per grain, m.
    pub wall_history: Vec<Vec3>,
}

impl ParticleState {
    /// Number of grains.
    pub fn len(&self) -> usize {
        self.id.len()
    }

    /// True when there are no grains.
    pub fn is_empty(&self) -> bool {
        self.id.is_empty()
    }

    /// Append one grain at rest in rotation, with zeroed forces and wall history.
    pub fn push(&mut self, id: u64, x: Vec3, v: Vec3, radius: Real, density: Real, walls: usize) {
        let mass = density * 4.0 / 3.0 * std::f64::consts::PI * radius.powi(3);
        self.id.push(id);
        self.position.push(x);
        self.velocity.push(v);
        self.angular_velocity.push([0.0; 3]);
        self.force.push([0.0; 3]);
        self.torque.push([0.0; 3]);
        self.external_force.push([0.0; 3]);
        self.radius.push(radius);
        self.mass.push(mass);
        self.inv_mass.push(1.0 / mass);
        self.inv_inertia.push(1.0 / (0.4 * mass * radius * radius));
        self.wall_history
            .extend(std::iter::repeat_n([0.0; 3], walls));
    }

    /// Hold the last grain in place for good: no velocity, and no response to any force
    /// (1/m = 1/I = 0, so the integrator leaves it where it is without a test per grain). Its
    /// mass is made 1e30 times its own, so that a pair's m* = m_i m_j/(m_i + m_j) is the free
    /// grain's mass to 1e-30 (a partner of infinite mass, as LAMMPS's `fix freeze` makes
    /// its pair styles take it).
    pub fn freeze_last(&mut self) {
        let Some(k) = self.id.len().checked_sub(1) else {
            return;
        };
        self.velocity[k] = [0.0; 3];
        self.mass[k] *= FROZEN_MASS_FACTOR;
        self.inv_mass[k] = 0.0;
        self.inv_inertia[k] = 0.0;
    }

    /// Hold grain `k` to the velocity `v` (the conveyor inlet's column): 1/m = 1/I = 0, so
    /// the integrator moves it at `v` whatever acts on it. Its mass stays its own: the
    /// grains it pushes meet it with the pair constants of two grains (m* = m/2), as the
    /// grains of the seeds' injected column are grains.
    pub fn hold(&mut self, k: usize, v: Vec3) {
        self.velocity[k] = v;
        self.angular_velocity[k] = [0.0; 3];
        self.inv_mass[k] = 0.0;
        self.inv_inertia[k] = 0.0;
    }

    /// Let a held grain go: it answers forces again from its current velocity.
    pub fn release(&mut self, k: usize) {
        let (m, r) = (self.mass[k], self.radius[k]);
        self.inv_mass[k] = 1.0 / m;
        self.inv_inertia[k] = 1.0 / (0.4 * m * r * r);
    }

    /// Reorder every array so that new index `k` holds old grain `order[k]`: the plain
    /// allocating permutation, kept as the tests' reference for [`ParticleState::reorder`].
    #[cfg(test)]
    pub fn permute(&mut self, order: &[usize], walls: usize) {
        fn apply<T: Copy>(v: &mut Vec<T>, order: &[usize]) {
            let old = std::mem::take(v);
            v.extend(order.iter().map(|&k| old[k]));
        }
        apply(&mut self.id, order);
        apply(&mut self.position, order);
        apply(&mut self.velocity, order);
        apply(&mut self.angular_velocity, order);
        apply(&mut self.force, order);
        apply(&mut self.torque, order);
        apply(&mut self.external_force, order);
        apply(&mut self.radius, order);
        apply(&mut self.mass, order);
        apply(&mut self.inv_mass, order);
        apply(&mut self.inv_inertia, order);
        if walls > 0 {
            let old = std::mem::take(&mut self.wall_history);
            for &k in order {
                self.wall_history
                    .extend_from_slice(&old[k * walls..(k + 1) * walls]);
            }
        }
    }

    /// Reorder every array so that new index `k` holds old grain `order[k]` (each grain at
    /// most once: a shorter order drops the grains it leaves out), column by column through
    /// `scratch`: the extra memory is one column of each type (136 B per grain with four
    /// walls), not a second state (a copy of all twelve columns cost 280 B per grain of the
    /// ~1 kB a grain costs, issue 21 item 8).
    /// The team's members share the new indices in equal contiguous ranges (the ranges of
    /// the per-grain passes that follow, so each member's grains land in its own cache); a
    /// copy does not depend on who made it.
    pub fn reorder(
        &mut self,
        order: &[usize],
        walls: usize,
        scratch: &mut ReorderScratch,
        team: &Team,
    ) {
        let n = order.len();
        let members = team.members_for(n, MIN_ROWS_PER_MEMBER);
        reorder_column(&mut self.id, &mut scratch.id, order, 1, members, team);
        for column in [
            &mut self.position,
            &mut self.velocity,
            &mut self.angular_velocity,
            &mut self.force,
            &mut self.torque,
            &mut self.external_force,
        ] {
            reorder_column(column, &mut scratch.vector, order, 1, members, team);
        }
        for column in [
            &mut self.radius,
            &mut self.mass,
            &mut self.inv_mass,
            &mut self.inv_inertia,
        ] {
            reorder_column(column, &mut scratch.real, order, 1, members, team);
        }
        if walls > 0 {
            reorder_column(
                &mut self.wall_history,
                &mut scratch.wall_history,
                order,
                walls,
                members,
                team,
            );
        }
    }
}

/// One spare column of each element type and length, for [`ParticleState::reorder`]; kept
/// between reorders so that a rebuild allocates nothing. The wall histories (`walls`
/// vectors per grain) have their own: columns only swap buffers with columns of their own
/// length, so no buffer grown for the wall histories ends up under a one-vector column
/// (which would keep its larger capacity resident there).
#[derive(Debug, Clone, Default)]
pub struct ReorderScratch {
    id: Vec<u64>,
    vector: Vec<Vec3>,
    real: Vec<Real>,
    wall_history: Vec<Vec3>,
}

/// `column` (`per` entries per grain) reordered by `order` into `spare`, then the two
/// swapped: `spare` keeps the old buffer for the next column of its type.
fn reorder_column<T: Copy + Default + Send + Sync>(
    column: &mut Vec<T>,
    spare: &mut Vec<T>,
    order: &[usize],
    per: usize,
    members: usize,
    team: &Team,
) {
    let n = order.len();
    spare.resize(n * per, T::default());
    {
        let dst = Shared::new(spare);
        let src = &column[..];
        team.run(members, &|m| {
            let (lo, hi) = share(n, members, m);
            // SAFETY: members write disjoint ranges lo..hi, inside one `Team::run`.
            let dst = unsafe { dst.range(lo * per, hi * per) };
            if per == 1 {
                for (d, &k) in dst.iter_mut().zip(&order[lo..hi]) {
                    *d = src[k];
                }
            } else {
                for (d, &k) in dst.chunks_exact_mut(per).zip(&order[lo..hi]) {
                    d.copy_from_slice(&src[k * per..(k + 1) * per]);
                }
            }
        });
    }
    std::mem::swap(column, spare);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dem::team::TeamThreads;

    /// The column-by-column reorder gives what the plain permutation gives, for every
    /// column and the wall histories, on one member and on two (1000 grains: both members
    /// take part), twice in a row through the same scratch (the second reorder runs on
    /// buffers the first swapped in), and no column keeps a wall-history-sized buffer; then
    /// a shorter order keeps only the grains it lists.
    #[test]
    fn reorder_equals_the_permutation() {
        let walls = 3;
        let n = 1000;
        let mut state = ParticleState::default();
        for k in 0..n {
            let x = k as Real;
            state.push(
                k as u64 + 7,
                [x, -x, 0.5 * x],
                [1.0, x, 2.0],
                1e-3 + 1e-6 * x,
                900.0,
                walls,
            );
            state.angular_velocity[k] = [x, 3.0, -1.0];
            state.force[k] = [0.1 * x, 0.0, 1.0];
            state.torque[k] = [0.0, x, 0.0];
            state.external_force[k] = [x, x, -x];
            for w in 0..walls {
                state.wall_history[k * walls + w] = [x, w as Real, 1.0];
            }
        }
        // A permutation that moves every grain: a stride coprime with n; and a shorter
        // order that drops every third grain (the grains that leave between builds).
        let order: Vec<usize> = (0..n).map(|k| (k * 389 + 11) % n).collect();
        let keep: Vec<usize> = (0..n).filter(|k| k % 3 != 1).collect();
        for members in [1, 2] {
            let threads = TeamThreads::start(members);
            let team = threads.team();
            let mut expected = state.clone();
            let mut got = state.clone();
            let mut scratch = ReorderScratch::default();
            for _ in 0..2 {
                expected.permute(&order, walls);
                got.reorder(&order, walls, &mut scratch, &team);
            }
            assert_eq!(
                format!("{got:?}"),
                format!("{expected:?}"),
                "{members} members"
            );
            assert!(got.position.capacity() < n * walls);
            assert!(got.velocity.capacity() < n * walls);
            expected.permute(&keep, walls);
            got.reorder(&keep, walls, &mut scratch, &team);
            assert_eq!(got.len(), keep.len());
            assert_eq!(
                format!("{got:?}"),
                format!("{expected:?}"),
                "{members} members, shorter order"
            );
        }
    }
}
