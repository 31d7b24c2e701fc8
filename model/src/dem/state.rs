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

    /// Reorder every array so that new index `k` holds old grain `order[k]`.
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

    /// Make this state `src` reordered so that index `k` holds `src`'s grain `order[k]`
    /// (every grain of `src` once), reusing this state's buffers. The team's members share
    /// the new indices in equal contiguous ranges (the ranges of the per-grain passes that
    /// follow, so each member's grains land in its own cache); a copy does not depend on
    /// who made it.
    pub fn gather(&mut self, src: &ParticleState, order: &[usize], walls: usize, team: &Team) {
        fn column<T: Copy + Default>(dst: &mut Vec<T>, len: usize) -> Shared<T> {
            dst.resize(len, T::default());
            Shared::new(dst)
        }
        fn copy<T: Copy>(dst: &Shared<T>, src: &[T], order: &[usize], lo: usize, hi: usize) {
            // SAFETY: members write disjoint ranges lo..hi, inside one `Team::run`.
            let dst = unsafe { dst.range(lo, hi) };
            for (d, &k) in dst.iter_mut().zip(&order[lo..hi]) {
                *d = src[k];
            }
        }
        let n = order.len();
        let id = column(&mut self.id, n);
        let position = column(&mut self.position, n);
        let velocity = column(&mut self.velocity, n);
        let angular_velocity = column(&mut self.angular_velocity, n);
        let force = column(&mut self.force, n);
        let torque = column(&mut self.torque, n);
        let external_force = column(&mut self.external_force, n);
        let radius = column(&mut self.radius, n);
        let mass = column(&mut self.mass, n);
        let inv_mass = column(&mut self.inv_mass, n);
        let inv_inertia = column(&mut self.inv_inertia, n);
        let wall_history = column(&mut self.wall_history, n * walls);
        let members = team.members_for(n, MIN_ROWS_PER_MEMBER);
        team.run(members, &|m| {
            let (lo, hi) = share(n, members, m);
            copy(&id, &src.id, order, lo, hi);
            copy(&position, &src.position, order, lo, hi);
            copy(&velocity, &src.velocity, order, lo, hi);
            copy(&angular_velocity, &src.angular_velocity, order, lo, hi);
            copy(&force, &src.force, order, lo, hi);
            copy(&torque, &src.torque, order, lo, hi);
            copy(&external_force, &src.external_force, order, lo, hi);
            copy(&radius, &src.radius, order, lo, hi);
            copy(&mass, &src.mass, order, lo, hi);
            copy(&inv_mass, &src.inv_mass, order, lo, hi);
            copy(&inv_inertia, &src.inv_inertia, order, lo, hi);
            if walls > 0 {
                // SAFETY: as in `copy`.
                let dst = unsafe { wall_history.range(lo * walls, hi * walls) };
                for (d, &k) in dst.chunks_exact_mut(walls).zip(&order[lo..hi]) {
                    d.copy_from_slice(&src.wall_history[k * walls..(k + 1) * walls]);
                }
            }
        });
    }
}
