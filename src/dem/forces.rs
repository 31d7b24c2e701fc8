//! The force loop: grain–grain pairs from the half neighbour list, grain–wall contacts,
//! gravity and the fluid-force slot. Generic over the contact laws so they inline.
//!
//! Threads split the grains into contiguous index ranges; a thread owns the force entries of
//! its range, and a pair whose partner j lies in a later range sends j's share to a spill list
//! applied after the join in a fixed order, so a run is bitwise reproducible for a given
//! thread count.

use super::contact::{NormalLaw, TangentialLaw};
use super::vec3::{add_assign, cross, dot, norm2, scale, sub, sub_assign};
use super::walls::Wall;
use crate::{Real, Vec3};

/// The contact laws of a scene: one instance for grain–grain and one for grain–wall pairs.
#[derive(Debug, Clone)]
pub struct Laws<N, T> {
    /// Grain–grain normal law.
    pub pp_normal: N,
    /// Grain–grain tangential law.
    pub pp_tangential: T,
    /// Grain–wall normal law.
    pub pw_normal: N,
    /// Grain–wall tangential law.
    pub pw_tangential: T,
    /// The grain–wall tangential law of each wall, in wall order: `pw_tangential`, or it with
    /// the wall's own friction ([`LawSet::attach_walls`](super::config::LawSet::attach_walls)).
    pub wall_tangential: Vec<T>,
}

impl<N, T: TangentialLaw> Laws<N, T> {
    /// Build `wall_tangential` for these walls (once, when the walls are known).
    pub fn attach_walls(&mut self, walls: &[Wall]) {
        self.wall_tangential = walls
            .iter()
            .map(|w| match w.friction {
                Some(mu) => self.pw_tangential.with_friction(mu),
                None => self.pw_tangential.clone(),
            })
            .collect();
    }
}

/// Read-only grain data the force loop needs.
#[derive(Clone, Copy)]
pub struct GrainsIn<'a> {
    pub position: &'a [Vec3],
    pub velocity: &'a [Vec3],
    pub angular_velocity: &'a [Vec3],
    pub radius: &'a [Real],
    pub mass: &'a [Real],
    pub external_force: &'a [Vec3],
}

/// Effective mass and radius of every grain pair when all grains are alike.
#[derive(Debug, Clone, Copy)]
pub struct UniformPair {
    /// sqrt(m*), kg^½.
    pub sqrt_m_eff: Real,
    /// r* = r/2, m.
    pub r_eff: Real,
    /// sqrt(m) of one grain (grain–wall pairs), kg^½.
    pub sqrt_m: Real,
}

/// Settings shared by all chunks of one step.
pub struct StepSettings<'a> {
    /// Set when all grains have one size and density: pair constants need no division.
    pub uniform: Option<UniformPair>,
    pub walls: &'a [Wall],
    pub gravity: Vec3,
    pub dt: Real,
    pub rotation: bool,
}

/// Force and torque a pair hands to a partner outside the computing thread's range.
#[derive(Debug, Clone, Copy)]
pub struct Spill {
    pub j: u32,
    pub force: Vec3,
    pub torque: Vec3,
}

/// The writable slices of one chunk [lo, hi).
pub struct ChunkOut<'a> {
    pub lo: usize,
    pub force: &'a mut [Vec3],
    pub torque: &'a mut [Vec3],
    /// Pair histories of rows lo..hi (offset `start[lo]`).
    pub history: &'a mut [Vec3],
    /// Wall histories of grains lo..hi (`walls.len()` per grain).
    pub wall_history: &'a mut [Vec3],
    pub spill: &'a mut Vec<Spill>,
    /// Force on each wall from this chunk, N.
    pub wall_force: &'a mut [Vec3],
}

/// Compute all forces on grains of the chunk (and partner shares).
#[inline(never)]
pub fn chunk_forces<N: NormalLaw, T: TangentialLaw>(
    laws: &Laws<N, T>,
    set: &StepSettings<'_>,
    g: GrainsIn<'_>,
    start: &[u32],
    partner: &[u32],
    out: ChunkOut<'_>,
) {
    let lo = out.lo;
    let hi = lo + out.force.len();
    let hist_off = start[lo] as usize;
    let nw = set.walls.len();
    for f in out.force.iter_mut() {
        *f = [0.0; 3];
    }
    if set.rotation {
        for t in out.torque.iter_mut() {
            *t = [0.0; 3];
        }
    }
    for w in out.wall_force.iter_mut() {
        *w = [0.0; 3];
    }
    for i in lo..hi {
        let xi = g.position[i];
        let vi = g.velocity[i];
        let ri = g.radius[i];
        let mi = g.mass[i];
        let wi = if set.rotation {
            scale(g.angular_velocity[i], ri)
        } else {
            [0.0; 3]
        };
        let mut fi = [0.0; 3];
        let mut ti = [0.0; 3];
        for k in start[i] as usize..start[i + 1] as usize {
            let j = partner[k] as usize;
            let d = sub(g.position[j], xi);
            let rj = g.radius[j];
            let rs = ri + rj;
            let dist2 = norm2(d);
            if dist2 >= rs * rs {
                if T::USES_HISTORY {
                    out.history[k - hist_off] = [0.0; 3];
                }
                continue;
            }
            let dist = dist2.sqrt();
            let n = scale(d, 1.0 / dist);
            let overlap = rs - dist;
            let (sqrt_m_eff, r_eff) = match set.uniform {
                Some(u) => (u.sqrt_m_eff, u.r_eff),
                None => {
                    let mj = g.mass[j];
                    ((mi * mj / (mi + mj)).sqrt(), ri * rj / rs)
                }
            };
            let mut vrel = sub(vi, g.velocity[j]);
            if set.rotation {
                let wsum = [
                    wi[0] + rj * g.angular_velocity[j][0],
                    wi[1] + rj * g.angular_velocity[j][1],
                    wi[2] + rj * g.angular_velocity[j][2],
                ];
                add_assign(&mut vrel, cross(wsum, n));
            }
            let vn = dot(vrel, n);
            let vt = sub(vrel, scale(n, vn));
            let normal = laws.pp_normal.evaluate(sqrt_m_eff, r_eff, overlap, vn);
            let ft =
                laws.pp_tangential
                    .force(&normal, vt, n, &mut out.history[k - hist_off], set.dt);
            let f = sub(ft, scale(n, normal.force));
            add_assign(&mut fi, f);
            let (ti_add, tj_add) = if set.rotation {
                let c = cross(n, ft);
                (scale(c, ri), scale(c, rj))
            } else {
                ([0.0; 3], [0.0; 3])
            };
            if set.rotation {
                add_assign(&mut ti, ti_add);
            }
            if j < hi {
                sub_assign(&mut out.force[j - lo], f);
                if set.rotation {
                    add_assign(&mut out.torque[j - lo], tj_add);
                }
            } else {
                out.spill.push(Spill {
                    j: j as u32,
                    force: scale(f, -1.0),
                    torque: tj_add,
                });
            }
        }
        // Walls: a partner of infinite mass and radius, at rest.
        for (w, wall) in set.walls.iter().enumerate() {
            let slot = (i - lo) * nw + w;
            match wall.contact(xi, ri) {
                Some((overlap, n)) => {
                    let mut vrel = vi;
                    if set.rotation {
                        add_assign(&mut vrel, cross(wi, n));
                    }
                    let vn = dot(vrel, n);
                    let vt = sub(vrel, scale(n, vn));
                    let sqrt_mi = match set.uniform {
                        Some(u) => u.sqrt_m,
                        None => mi.sqrt(),
                    };
                    let normal = laws.pw_normal.evaluate(sqrt_mi, ri, overlap, vn);
                    let ft = laws.wall_tangential[w].force(
                        &normal,
                        vt,
                        n,
                        &mut out.wall_history[slot],
                        set.dt,
                    );
                    let f = sub(ft, scale(n, normal.force));
                    add_assign(&mut fi, f);
                    sub_assign(&mut out.wall_force[w], f);
                    if set.rotation {
                        add_assign(&mut ti, scale(cross(n, ft), ri));
                    }
                }
                None => {
                    if T::USES_HISTORY {
                        out.wall_history[slot] = [0.0; 3];
                    }
                }
            }
        }
        add_assign(&mut fi, scale(set.gravity, mi));
        add_assign(&mut fi, g.external_force[i]);
        add_assign(&mut out.force[i - lo], fi);
        if set.rotation {
            add_assign(&mut out.torque[i - lo], ti);
        }
    }
}
