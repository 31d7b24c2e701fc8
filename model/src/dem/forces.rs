//! The force loop: grain–grain pairs from the half neighbour list, grain–wall contacts,
//! gravity and the fluid-force slot. Generic over the contact laws so they inline; the laws
//! run on four contacts at once ([`Lanes`]), which is where the built-in engine's speed over
//! LIGGGHTS comes from (`cargo bench --bench dem_bench`).
//!
//! Threads split the grains into contiguous index ranges; a thread owns the force entries of
//! its range, and a pair whose partner j lies in another range sends j's share to a spill list.
//! The integration pass that follows adds the spills, each chunk those of its own grains, in
//! chunk order and list order, so a run is bitwise reproducible for a given thread count.

use super::contact::{NormalLaw, RollingLaw, RollingPair, TangentialLaw};
use super::lanes::{Lanes, Num, LANES};
use super::vec3::{add, add_assign, cross, dot, norm2, scale, sub, sub_assign};
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
    /// Radius of every grain, m.
    pub radius: Real,
}

/// Radii and masses of the grains a contact group joins: constants when all grains are
/// alike ([`UniformPair`]), else read per grain ([`EachOwn`]). A type, not a run-time
/// branch, so the alike case compiles to splatted constants and loads no radius or mass.
trait Sizes: Copy {
    /// Radius of grain i, m.
    fn radius(self, g: &GrainsIn<'_>, i: usize) -> Real;
    /// (r_i, r_j, sqrt(m*), r*) of grain pairs (i, j).
    fn pair(
        self,
        g: &GrainsIn<'_>,
        i: &[usize; LANES],
        j: &[usize; LANES],
    ) -> (Lanes, Lanes, Lanes, Lanes);
    /// (r_i, sqrt(m_i)) of grains i against a wall.
    fn wall(self, g: &GrainsIn<'_>, i: &[usize; LANES]) -> (Lanes, Lanes);
}

impl Sizes for UniformPair {
    #[inline(always)]
    fn radius(self, _: &GrainsIn<'_>, _: usize) -> Real {
        self.radius
    }
    #[inline(always)]
    fn pair(
        self,
        _: &GrainsIn<'_>,
        _: &[usize; LANES],
        _: &[usize; LANES],
    ) -> (Lanes, Lanes, Lanes, Lanes) {
        let r = Lanes::splat(self.radius);
        (
            r,
            r,
            Lanes::splat(self.sqrt_m_eff),
            Lanes::splat(self.r_eff),
        )
    }
    #[inline(always)]
    fn wall(self, _: &GrainsIn<'_>, _: &[usize; LANES]) -> (Lanes, Lanes) {
        (Lanes::splat(self.radius), Lanes::splat(self.sqrt_m))
    }
}

/// Grains of several sizes or densities: each pair's constants from its grains.
#[derive(Clone, Copy)]
struct EachOwn;

impl Sizes for EachOwn {
    #[inline(always)]
    fn radius(self, g: &GrainsIn<'_>, i: usize) -> Real {
        g.radius[i]
    }
    #[inline(always)]
    fn pair(
        self,
        g: &GrainsIn<'_>,
        i: &[usize; LANES],
        j: &[usize; LANES],
    ) -> (Lanes, Lanes, Lanes, Lanes) {
        let (ri, rj) = (Lanes(i.map(|i| g.radius[i])), Lanes(j.map(|j| g.radius[j])));
        let (mi, mj) = (Lanes(i.map(|i| g.mass[i])), Lanes(j.map(|j| g.mass[j])));
        (ri, rj, (mi * mj / (mi + mj)).sqrt(), ri * rj / (ri + rj))
    }
    #[inline(always)]
    fn wall(self, g: &GrainsIn<'_>, i: &[usize; LANES]) -> (Lanes, Lanes) {
        (
            Lanes(i.map(|i| g.radius[i])),
            Lanes(i.map(|i| g.mass[i])).sqrt(),
        )
    }
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

/// Per-chunk scratch of the force phase: the contacts found this step (grain–grain, then
/// each wall's in turn). Kept between steps so the force loop allocates nothing.
#[derive(Debug, Clone, Default)]
pub struct ContactScratch {
    /// Grain–grain: the contact's pair index in the neighbour list (its history slot).
    pair: Vec<u32>,
    /// Grain–grain: the partner j.
    partner: Vec<u32>,
    /// Grain–grain: the contact's grain i (its row).
    grain: Vec<u32>,
    /// Grain–grain, laws with a history only: the listed pairs found apart this step, whose
    /// histories are cleared after detection.
    apart: Vec<u32>,
    /// Grain–grain: x_j − x_i by component, m, as the detection found it (so the laws load
    /// four contacts' separations at once instead of gathering eight positions).
    gap: [Vec<Real>; 3],
    /// Grain–wall: the grain.
    wall_grain: Vec<u32>,
    /// Grain–wall: overlap, m.
    wall_overlap: Vec<Real>,
    /// Grain–wall: unit normal from the grain towards the wall, by component.
    wall_normal: [Vec<Real>; 3],
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
    /// This chunk's contact lists.
    pub scratch: &'a mut ContactScratch,
}

impl ChunkOut<'_> {
    /// The same outputs borrowed for a shorter time, by value: a stage takes its outputs as
    /// plain slices (held in registers), not through a reference to this struct.
    #[inline(always)]
    fn reborrow(&mut self) -> ChunkOut<'_> {
        ChunkOut {
            lo: self.lo,
            force: &mut *self.force,
            torque: &mut *self.torque,
            history: &mut *self.history,
            wall_history: &mut *self.wall_history,
            spill: &mut *self.spill,
            wall_force: &mut *self.wall_force,
            scratch: &mut *self.scratch,
        }
    }
}

/// What every chunk's force loop reads: the laws, the step's settings, the grains and the
/// neighbour list. One bundle, so the dispatch hops (sizes → CPU → body) pass one value.
pub struct ForceInputs<'a, N, T, R> {
    pub laws: &'a Laws<N, T>,
    /// The rolling law ([`NoRolling`](super::contact::NoRolling) when the scene has none).
    pub rolling: &'a RollingPair<R>,
    pub set: &'a StepSettings<'a>,
    pub grains: GrainsIn<'a>,
    /// Row starts of the half neighbour list: grain i's pairs are `start[i]..start[i + 1]`.
    pub start: &'a [u32],
    /// Partner j of each pair.
    pub partner: &'a [u32],
    /// Periodic boxes: the image shift of each pair's partner, m; empty otherwise.
    pub offset: &'a [Vec3],
    /// Per wall, the grains that may touch it.
    pub near_wall: &'a [Vec<u32>],
}

// By hand: `derive` would ask the laws themselves to be `Copy`.
impl<N, T, R> Clone for ForceInputs<'_, N, T, R> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<N, T, R> Copy for ForceInputs<'_, N, T, R> {}

/// Compute all forces on grains of the chunk (and partner shares). `near_wall`: per wall,
/// the grains that may touch it (see [`NeighborList`](super::neighbor::NeighborList)).
///
/// Contacts are found first (histories of pairs not touching are cleared) and listed by
/// component (separation, wall normal), padded to whole groups, so the laws read four
/// contacts with one load per list; the laws run over them [`LANES`] at a time
/// ([`Lanes`]: no branches, so the lanes share vector
/// registers and independent contacts overlap instead of queueing on one chain of sqrt and
/// division latencies), then each contact's force and torque go to its grains in list
/// order. Grain–grain pairs first, then each wall, then gravity and the fluid force. The
/// order is fixed, so a run is bitwise reproducible for a given thread count. On x86-64
/// CPUs with AVX2 the same code is compiled for 4-wide registers and chosen at run time; it
/// computes the same IEEE operations, so results do not depend on the CPU. Grains all
/// alike take a build of their own (`Sizes`) whose pair constants are compiled in.
pub fn chunk_forces<N: NormalLaw, T: TangentialLaw, R: RollingLaw>(
    inputs: ForceInputs<'_, N, T, R>,
    out: ChunkOut<'_>,
) {
    match inputs.set.uniform {
        Some(u) => chunk_forces_sized(inputs, out, u),
        None => chunk_forces_sized(inputs, out, EachOwn),
    }
}

/// [`chunk_forces`] for one kind of [`Sizes`]: the AVX2 build when the CPU has it.
#[inline(always)]
fn chunk_forces_sized<N: NormalLaw, T: TangentialLaw, R: RollingLaw, S: Sizes>(
    inputs: ForceInputs<'_, N, T, R>,
    out: ChunkOut<'_>,
    sizes: S,
) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2 (checked just above).
        unsafe { chunk_forces_avx2(inputs, out, sizes) };
        return;
    }
    chunk_forces_body(inputs, out, sizes);
}

/// [`chunk_forces_body`] compiled for AVX2 (no FMA: the same roundings as the baseline).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn chunk_forces_avx2<N: NormalLaw, T: TangentialLaw, R: RollingLaw, S: Sizes>(
    inputs: ForceInputs<'_, N, T, R>,
    out: ChunkOut<'_>,
    sizes: S,
) {
    chunk_forces_body(inputs, out, sizes);
}

#[inline(always)]
fn chunk_forces_body<N: NormalLaw, T: TangentialLaw, R: RollingLaw, S: Sizes>(
    inputs: ForceInputs<'_, N, T, R>,
    out: ChunkOut<'_>,
    sizes: S,
) {
    let ForceInputs {
        set,
        grains: g,
        start,
        ..
    } = inputs;
    let lo = out.lo;
    let hi = lo + out.force.len();
    // Every column cut to one length: a lane's index is then checked once, not per column.
    let n = g.position.len();
    let g = GrainsIn {
        position: &g.position[..n],
        velocity: &g.velocity[..n],
        angular_velocity: &g.angular_velocity[..n],
        radius: &g.radius[..n],
        mass: &g.mass[..n],
        external_force: &g.external_force[..n],
    };
    let inputs = ForceInputs {
        grains: g,
        ..inputs
    };
    let hist_off = start[lo] as usize;
    for f in out.force.iter_mut() {
        *f = [0.0; 3];
    }
    if set.rotation {
        for t in out.torque.iter_mut() {
            *t = [0.0; 3];
        }
    }

    let mut out = out;
    pair_contacts(inputs, out.reborrow(), sizes, hist_off);
    wall_contacts(inputs, out.reborrow(), sizes);
    for i in lo..hi {
        let fi = add(scale(set.gravity, g.mass[i]), g.external_force[i]);
        add_assign(&mut out.force[i - lo], fi);
    }
}

/// Grain–grain contacts of the chunk's rows: detection into the contact lists, then the laws
/// four contacts at a time, each force and torque to its two grains (or a spill), in list
/// order. (Inlined into the force loop: one function for reading, one body for the compiler.)
#[inline(always)]
fn pair_contacts<N: NormalLaw, T: TangentialLaw, R: RollingLaw, S: Sizes>(
    inputs: ForceInputs<'_, N, T, R>,
    out: ChunkOut<'_>,
    sizes: S,
    hist_off: usize,
) {
    let ForceInputs {
        set,
        grains: g,
        start,
        partner,
        offset,
        ..
    } = inputs;
    let periodic = !offset.is_empty();
    let lo = out.lo;
    let hi = lo + out.force.len();
    let sc = out.scratch;
    // The lists sized for every pair of the rows to touch and a last group's padding:
    // filled by index, no push.
    let room = start[hi] as usize - hist_off + LANES;
    for list in [&mut sc.pair, &mut sc.partner, &mut sc.grain] {
        if list.len() < room {
            list.resize(room, 0);
        }
    }
    if T::USES_HISTORY && sc.apart.len() < room {
        sc.apart.resize(room, 0);
    }
    for list in &mut sc.gap {
        if list.len() < room {
            list.resize(room, 0.0);
        }
    }
    // Without branches: every listed pair is written at the next free slot, which only a
    // touching pair claims (about half the listed pairs touch in a dense plug, so a branch
    // on it was mispredicted at every other pair: this loop took a third of the force pass).
    // With a history law, a pair that does not touch claims the next slot of a second list,
    // whose histories are cleared (+0.0) after the loop. (Masking each history in place
    // read and wrote every listed pair's history, and compiled to a branch on `touch`,
    // mispredicted at every other pair of a flowing bed: on LAMMPS's chute, half the listed
    // pairs apart, the second list makes the step about a quarter faster. Laws without a
    // history write no second list: their loop is unchanged.)
    let (mut nc, mut na) = (0, 0);
    let (pair, partner_of, grain) = (
        &mut sc.pair[..room],
        &mut sc.partner[..room],
        &mut sc.grain[..room],
    );
    let [gx, gy, gz] = &mut sc.gap;
    let (gx, gy, gz) = (&mut gx[..room], &mut gy[..room], &mut gz[..room]);
    let apart = &mut sc.apart[..if T::USES_HISTORY { room } else { 0 }];
    for i in lo..hi {
        let (xi, ri) = (g.position[i], sizes.radius(&g, i));
        let (k0, k1) = (start[i] as usize, start[i + 1] as usize);
        for (k, &j) in (k0..k1).zip(&partner[k0..k1]) {
            let j = j as usize;
            let rs = ri + sizes.radius(&g, j);
            let mut d = sub(g.position[j], xi);
            if periodic {
                // Across a periodic seam: the partner's image (a shift fixed at the build).
                let o = offset[k];
                d = [d[0] + o[0], d[1] + o[1], d[2] + o[2]];
            }
            let touch = norm2(d) < rs * rs;
            // (nc, na ≤ k − hist_off < room − LANES: every slot written lies in the lists.)
            pair[nc] = k as u32;
            partner_of[nc] = j as u32;
            grain[nc] = i as u32;
            gx[nc] = d[0];
            gy[nc] = d[1];
            gz[nc] = d[2];
            nc += touch as usize;
            if T::USES_HISTORY {
                apart[na] = k as u32;
                na += !touch as usize;
            }
        }
    }
    if T::USES_HISTORY {
        for &k in &apart[..na] {
            out.history[k as usize - hist_off] = [0.0; 3];
        }
    }
    // The last group's lanes past the end repeat the last contact (computed, then dropped),
    // so every group reads four consecutive entries.
    if nc > 0 {
        for p in nc..nc.next_multiple_of(LANES) {
            sc.pair[p] = sc.pair[nc - 1];
            sc.partner[p] = sc.partner[nc - 1];
            sc.grain[p] = sc.grain[nc - 1];
            for list in &mut sc.gap {
                list[p] = list[nc - 1];
            }
        }
    }
    for base in (0..nc).step_by(LANES) {
        let index = |list: &[u32]| four(list, base).map(|v| v as usize);
        let (k, i, j) = (index(&sc.pair), index(&sc.grain), index(&sc.partner));
        let gap = std::array::from_fn(|c| Lanes(four(&sc.gap[c], base)));
        let slot = k.map(|k| k - hist_off);
        let mut shear = if T::USES_HISTORY {
            gather3(out.history, &slot)
        } else {
            [Lanes::splat(0.0); 3]
        };
        let (f, arm, roll) = pair_lanes(&inputs, sizes, i, j, gap, &mut shear);
        // Each contact's force and torque to its two grains, in list order.
        for l in 0..LANES.min(nc - base) {
            if T::USES_HISTORY {
                out.history[slot[l]] = lane(shear, l);
            }
            let (i, j, f) = (i[l], j[l], lane(f, l));
            add_assign(&mut out.force[i - lo], f);
            let tj = if set.rotation {
                let arm = lane(arm, l);
                let mut ti = scale(arm, sizes.radius(&g, i));
                let mut tj = scale(arm, sizes.radius(&g, j));
                if R::ACTIVE {
                    let m = lane(roll, l);
                    add_assign(&mut ti, m);
                    sub_assign(&mut tj, m);
                }
                add_assign(&mut out.torque[i - lo], ti);
                tj
            } else {
                [0.0; 3]
            };
            if (lo..hi).contains(&j) {
                sub_assign(&mut out.force[j - lo], f);
                if set.rotation {
                    add_assign(&mut out.torque[j - lo], tj);
                }
            } else {
                out.spill.push(Spill {
                    j: j as u32,
                    force: scale(f, -1.0),
                    torque: tj,
                });
            }
        }
    }
}

/// Grain–wall contacts, one wall at a time (a partner of infinite mass and radius, at rest):
/// the wall's near list, the laws four contacts at a time, the force on the wall.
#[inline(always)]
fn wall_contacts<N: NormalLaw, T: TangentialLaw, R: RollingLaw, S: Sizes>(
    inputs: ForceInputs<'_, N, T, R>,
    out: ChunkOut<'_>,
    sizes: S,
) {
    let ForceInputs {
        set,
        grains: g,
        near_wall,
        ..
    } = inputs;
    let lo = out.lo;
    let hi = lo + out.force.len();
    let sc = out.scratch;
    let nw = set.walls.len();
    for (w, wall) in set.walls.iter().enumerate() {
        // Grains [lo, hi) of the wall's near list; all others were a skin or more away at
        // the build, have drifted less since, and their histories with it are already zero.
        let near = &near_wall[w];
        let (a, b) = (
            near.partition_point(|&i| (i as usize) < lo),
            near.partition_point(|&i| (i as usize) < hi),
        );
        let room = b - a + LANES;
        if sc.wall_grain.len() < room {
            sc.wall_grain.resize(room, 0);
            sc.wall_overlap.resize(room, 0.0);
            for list in &mut sc.wall_normal {
                list.resize(room, 0.0);
            }
        }
        let mut nc = 0;
        for &i in &near[a..b] {
            let i = i as usize;
            match wall.contact(g.position[i], sizes.radius(&g, i)) {
                Some((overlap, n)) => {
                    sc.wall_grain[nc] = i as u32;
                    sc.wall_overlap[nc] = overlap;
                    for (c, list) in sc.wall_normal.iter_mut().enumerate() {
                        list[nc] = n[c];
                    }
                    nc += 1;
                }
                None => {
                    if T::USES_HISTORY {
                        out.wall_history[(i - lo) * nw + w] = [0.0; 3];
                    }
                }
            }
        }
        if nc > 0 {
            for p in nc..nc.next_multiple_of(LANES) {
                sc.wall_grain[p] = sc.wall_grain[nc - 1];
                sc.wall_overlap[p] = sc.wall_overlap[nc - 1];
                for list in &mut sc.wall_normal {
                    list[p] = list[nc - 1];
                }
            }
        }
        let mut on_wall = [0.0; 3];
        for base in (0..nc).step_by(LANES) {
            let i = four(&sc.wall_grain, base).map(|v| v as usize);
            let slot = i.map(|i| (i - lo) * nw + w);
            let mut shear = if T::USES_HISTORY {
                gather3(out.wall_history, &slot)
            } else {
                [Lanes::splat(0.0); 3]
            };
            let overlap = Lanes(four(&sc.wall_overlap, base));
            let n = std::array::from_fn(|c| Lanes(four(&sc.wall_normal[c], base)));
            let (f, arm, roll) = wall_lanes(&inputs, w, sizes, i, overlap, n, &mut shear);
            for l in 0..LANES.min(nc - base) {
                if T::USES_HISTORY {
                    out.wall_history[slot[l]] = lane(shear, l);
                }
                let (i, f) = (i[l], lane(f, l));
                add_assign(&mut out.force[i - lo], f);
                sub_assign(&mut on_wall, f);
                if set.rotation {
                    let mut ti = scale(lane(arm, l), sizes.radius(&g, i));
                    if R::ACTIVE {
                        add_assign(&mut ti, lane(roll, l));
                    }
                    add_assign(&mut out.torque[i - lo], ti);
                }
            }
        }
        out.wall_force[w] = on_wall;
    }
}

/// Entries base..base + [`LANES`] of a contact list (one load when the compiler can).
#[inline(always)]
fn four<V: Copy>(list: &[V], base: usize) -> [V; LANES] {
    let group: &[V; LANES] = list[base..base + LANES]
        .try_into()
        .expect("a slice of LANES entries");
    *group
}

/// Component c of `v[idx[l]]` in lane l.
#[inline(always)]
fn gather3(v: &[Vec3], idx: &[usize; LANES]) -> [Lanes; 3] {
    std::array::from_fn(|c| Lanes(idx.map(|k| v[k][c])))
}

/// The vector in lane l.
#[inline(always)]
fn lane(v: [Lanes; 3], l: usize) -> Vec3 {
    [v[0].0[l], v[1].0[l], v[2].0[l]]
}

/// The grain–grain laws on `LANES` contacts (i[l], j[l]) in contact; returns the force on
/// each i, n × F_t and the rolling torque on i, and updates the contacts' `shear` histories.
#[inline(always)]
fn pair_lanes<N: NormalLaw, T: TangentialLaw, R: RollingLaw, S: Sizes>(
    inputs: &ForceInputs<'_, N, T, R>,
    sizes: S,
    i: [usize; LANES],
    j: [usize; LANES],
    d: [Lanes; 3],
    shear: &mut [Lanes; 3],
) -> ([Lanes; 3], [Lanes; 3], [Lanes; 3]) {
    let (laws, set, g) = (inputs.laws, inputs.set, &inputs.grains);
    let (ri, rj, sqrt_m_eff, r_eff) = sizes.pair(g, &i, &j);
    let rs = ri + rj;
    let dist = norm2(d).sqrt();
    let n = scale(d, Lanes::splat(1.0) / dist);
    let mut vrel = sub(gather3(g.velocity, &i), gather3(g.velocity, &j));
    let mut w_rel = [Lanes::splat(0.0); 3];
    if set.rotation {
        let (wi, wj) = (
            gather3(g.angular_velocity, &i),
            gather3(g.angular_velocity, &j),
        );
        let spin = std::array::from_fn(|c| ri * wi[c] + rj * wj[c]);
        add_assign(&mut vrel, cross(spin, n));
        if R::ACTIVE {
            w_rel = sub(wi, wj);
        }
    }
    let (f, arm, (elastic, normal)) = respond(
        &laws.pp_normal,
        &laws.pp_tangential,
        set.dt,
        (sqrt_m_eff, r_eff),
        rs - dist,
        n,
        vrel,
        shear,
    );
    let roll = if R::ACTIVE {
        inputs.rolling.pp.torque(elastic, normal, r_eff, w_rel, n)
    } else {
        [Lanes::splat(0.0); 3]
    };
    (f, arm, roll)
}

/// The grain–wall laws of wall `w` on `LANES` grains `i` touching it with `overlap` along
/// `n`; returns the force on each grain, n × F_t and the rolling torque, and updates their
/// `shear` histories.
#[inline(always)]
fn wall_lanes<N: NormalLaw, T: TangentialLaw, R: RollingLaw, S: Sizes>(
    inputs: &ForceInputs<'_, N, T, R>,
    w: usize,
    sizes: S,
    i: [usize; LANES],
    overlap: Lanes,
    n: [Lanes; 3],
    shear: &mut [Lanes; 3],
) -> ([Lanes; 3], [Lanes; 3], [Lanes; 3]) {
    let (laws, set, g) = (inputs.laws, inputs.set, &inputs.grains);
    let (ri, sqrt_m) = sizes.wall(g, &i);
    let mut vrel = gather3(g.velocity, &i);
    let mut w_rel = [Lanes::splat(0.0); 3];
    if set.rotation {
        let wi = gather3(g.angular_velocity, &i);
        let spin = std::array::from_fn(|c| ri * wi[c]);
        add_assign(&mut vrel, cross(spin, n));
        if R::ACTIVE {
            w_rel = wi;
        }
    }
    let (f, arm, (elastic, normal)) = respond(
        &laws.pw_normal,
        &laws.wall_tangential[w],
        set.dt,
        (sqrt_m, ri),
        overlap,
        n,
        vrel,
        shear,
    );
    let roll = if R::ACTIVE {
        inputs.rolling.pw.torque(elastic, normal, ri, w_rel, n)
    } else {
        [Lanes::splat(0.0); 3]
    };
    (f, arm, roll)
}

/// Normal and tangential law of one contact group: `vrel` the contact point's velocity of
/// grain i relative to its partner, `n` from i to the partner; returns (force on i, n × F_t,
/// the normal force's elastic part and whole, N).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn respond<N: NormalLaw, T: TangentialLaw>(
    normal_law: &N,
    tangential_law: &T,
    dt: Real,
    (sqrt_m_eff, r_eff): (Lanes, Lanes),
    overlap: Lanes,
    n: [Lanes; 3],
    vrel: [Lanes; 3],
    shear: &mut [Lanes; 3],
) -> ([Lanes; 3], [Lanes; 3], (Lanes, Lanes)) {
    let vn = dot(vrel, n);
    let vt = sub(vrel, scale(n, vn));
    let normal = normal_law.evaluate(sqrt_m_eff, r_eff, overlap, vn);
    let ft = tangential_law.force(&normal, vt, n, shear, Lanes::splat(dt));
    (
        sub(ft, scale(n, normal.force)),
        cross(n, ft),
        (normal.elastic, normal.force),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dem::contact::{ConstantTorque, Hertz, History, NoRolling, TorqueReading};
    use crate::dem::walls::WallShape;
    use crate::rng::Rng;

    /// 40 grains of two sizes jostled in a tube against a floor, moving and spinning, with
    /// shear histories: many grain–grain and grain–wall contacts, some sliding.
    struct Scene {
        x: Vec<Vec3>,
        v: Vec<Vec3>,
        w: Vec<Vec3>,
        r: Vec<Real>,
        m: Vec<Real>,
        fext: Vec<Vec3>,
        start: Vec<u32>,
        partner: Vec<u32>,
        history: Vec<Vec3>,
        wall_history: Vec<Vec3>,
        walls: Vec<Wall>,
        laws: Laws<Hertz, History>,
    }

    fn scene(two_sizes: bool) -> Scene {
        let mut rng = Rng::new(7);
        let mut u = |a: Real| a * (2.0 * rng.uniform() - 1.0);
        let n = 40;
        let (mut x, mut v, mut w, mut r, mut m) = (vec![], vec![], vec![], vec![], vec![]);
        for k in 0..n {
            let rad = if two_sizes && k % 3 == 0 {
                0.6e-3
            } else {
                0.5e-3
            };
            // A column of layers 0.95 mm apart, 4 grains per layer 0.95 mm apart: overlaps.
            let (layer, slot) = ((k / 4) as Real, k % 4);
            let (cx, cy) = [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)][slot];
            x.push([
                0.475e-3 * cx + u(5e-5),
                0.475e-3 * cy + u(5e-5),
                0.5e-3 + 0.95e-3 * layer + u(5e-5),
            ]);
            v.push([u(0.2), u(0.2), u(0.2)]);
            w.push([u(300.0), u(300.0), u(300.0)]);
            r.push(rad);
            m.push(1000.0 * 4.0 / 3.0 * std::f64::consts::PI * rad * rad * rad);
        }
        let (mut start, mut partner) = (vec![0u32], vec![]);
        for i in 0..n {
            for j in i + 1..n {
                if norm2(sub(x[j], x[i])) < (r[i] + r[j] + 2e-4).powi(2) {
                    partner.push(j as u32);
                }
            }
            start.push(partner.len() as u32);
        }
        let history = (0..partner.len())
            .map(|_| [u(2e-6), u(2e-6), u(2e-6)])
            .collect();
        let walls = vec![
            Wall {
                name: "tube".into(),
                shape: WallShape::Cylinder {
                    point: [0.0; 3],
                    axis: [0.0, 0.0, 1.0],
                    radius: 1.15e-3,
                },
                friction: None,
            },
            Wall {
                name: "floor".into(),
                shape: WallShape::Plane {
                    point: [0.0, 0.0, 0.1e-3],
                    normal: [0.0, 0.0, 1.0],
                },
                friction: Some(0.1),
            },
        ];
        let wall_history = (0..n * walls.len())
            .map(|_| [u(2e-6), u(2e-6), u(2e-6)])
            .collect();
        let fext = (0..n).map(|_| [u(1e-4), u(1e-4), u(1e-4)]).collect();
        let hertz = Hertz::new(5e6, 0.45, 0.5);
        let mut laws = Laws {
            pp_normal: hertz.clone(),
            pp_tangential: History {
                mu: 0.5,
                gamma_t: None,
            },
            pw_normal: hertz,
            pw_tangential: History {
                mu: 0.3,
                gamma_t: None,
            },
            wall_tangential: vec![],
        };
        laws.attach_walls(&walls);
        Scene {
            x,
            v,
            w,
            r,
            m,
            fext,
            start,
            partner,
            history,
            wall_history,
            walls,
            laws,
        }
    }

    /// Forces, torques, histories and wall forces of one chunk over all grains, through
    /// `body` (the run-time dispatch, or one compiled variant).
    type Outcome = (Vec<Vec3>, Vec<Vec3>, Vec<Vec3>, Vec<Vec3>, Vec<Vec3>);
    type ForceBody<R> = fn(ForceInputs<'_, Hertz, History, R>, ChunkOut<'_>);
    fn run<R: RollingLaw>(
        s: &Scene,
        rolling: &RollingPair<R>,
        body: ForceBody<R>,
        uniform: Option<UniformPair>,
    ) -> Outcome {
        let n = s.x.len();
        let (mut force, mut torque) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
        let (mut history, mut wall_history) = (s.history.clone(), s.wall_history.clone());
        let mut wall_force = vec![[0.0; 3]; s.walls.len()];
        let (mut spill, mut scratch) = (vec![], ContactScratch::default());
        let set = StepSettings {
            uniform,
            walls: &s.walls,
            gravity: [0.0, 0.0, -9.81],
            dt: 1e-6,
            rotation: true,
        };
        let g = GrainsIn {
            position: &s.x,
            velocity: &s.v,
            angular_velocity: &s.w,
            radius: &s.r,
            mass: &s.m,
            external_force: &s.fext,
        };
        let out = ChunkOut {
            lo: 0,
            force: &mut force,
            torque: &mut torque,
            history: &mut history,
            wall_history: &mut wall_history,
            spill: &mut spill,
            wall_force: &mut wall_force,
            scratch: &mut scratch,
        };
        // Every grain is near every wall: the near lists only skip grains that cannot touch.
        let near = vec![(0..n as u32).collect::<Vec<_>>(); s.walls.len()];
        let inputs = ForceInputs {
            laws: &s.laws,
            rolling,
            set: &set,
            grains: g,
            start: &s.start,
            partner: &s.partner,
            offset: &[],
            near_wall: &near,
        };
        body(inputs, out);
        assert!(spill.is_empty(), "one chunk holds every partner");
        (force, torque, history, wall_history, wall_force)
    }

    /// The same laws one contact at a time (`Num` = `Real`), summed in the same order, with
    /// the constant-torque rolling law when `rolling` is given.
    fn one_contact_at_a_time(s: &Scene, rolling: Option<&RollingPair<ConstantTorque>>) -> Outcome {
        let n = s.x.len();
        let (mut force, mut torque) = (vec![[0.0; 3]; n], vec![[0.0; 3]; n]);
        let (mut history, mut wall_history) = (s.history.clone(), s.wall_history.clone());
        let mut wall_force = vec![[0.0; 3]; s.walls.len()];
        let dt = 1e-6;
        let respond1 = |normal_law: &Hertz,
                        tangential: &History,
                        sqrt_m: Real,
                        r_eff: Real,
                        overlap: Real,
                        n: Vec3,
                        vrel: Vec3,
                        h: &mut Vec3| {
            let vn = dot(vrel, n);
            let vt = sub(vrel, scale(n, vn));
            let normal = normal_law.evaluate(sqrt_m, r_eff, overlap, vn);
            let ft = tangential.force(&normal, vt, n, h, dt);
            (
                sub(ft, scale(n, normal.force)),
                cross(n, ft),
                (normal.elastic, normal.force),
            )
        };
        for i in 0..n {
            for k in s.start[i] as usize..s.start[i + 1] as usize {
                let j = s.partner[k] as usize;
                let d = sub(s.x[j], s.x[i]);
                let rs = s.r[i] + s.r[j];
                if norm2(d) >= rs * rs {
                    history[k] = [0.0; 3];
                    continue;
                }
                let dist = norm2(d).sqrt();
                let nrm = scale(d, 1.0 / dist);
                let (mi, mj) = (s.m[i], s.m[j]);
                let spin: Vec3 = std::array::from_fn(|c| s.r[i] * s.w[i][c] + s.r[j] * s.w[j][c]);
                let vrel = add(sub(s.v[i], s.v[j]), cross(spin, nrm));
                let r_eff = s.r[i] * s.r[j] / rs;
                let (f, arm, (elastic, normal)) = respond1(
                    &s.laws.pp_normal,
                    &s.laws.pp_tangential,
                    (mi * mj / (mi + mj)).sqrt(),
                    r_eff,
                    rs - dist,
                    nrm,
                    vrel,
                    &mut history[k],
                );
                let (mut ti, mut tj) = (scale(arm, s.r[i]), scale(arm, s.r[j]));
                if let Some(roll) = rolling {
                    let m = roll
                        .pp
                        .torque(elastic, normal, r_eff, sub(s.w[i], s.w[j]), nrm);
                    add_assign(&mut ti, m);
                    sub_assign(&mut tj, m);
                }
                add_assign(&mut force[i], f);
                add_assign(&mut torque[i], ti);
                sub_assign(&mut force[j], f);
                add_assign(&mut torque[j], tj);
            }
        }
        let nw = s.walls.len();
        for (wi, wall) in s.walls.iter().enumerate() {
            let mut on_wall = [0.0; 3];
            for i in 0..n {
                let Some((overlap, nrm)) = wall.contact(s.x[i], s.r[i]) else {
                    wall_history[i * nw + wi] = [0.0; 3];
                    continue;
                };
                let spin = scale(s.w[i], s.r[i]);
                let vrel = add(s.v[i], cross(spin, nrm));
                let (f, arm, (elastic, normal)) = respond1(
                    &s.laws.pw_normal,
                    &s.laws.wall_tangential[wi],
                    s.m[i].sqrt(),
                    s.r[i],
                    overlap,
                    nrm,
                    vrel,
                    &mut wall_history[i * nw + wi],
                );
                let mut ti = scale(arm, s.r[i]);
                if let Some(roll) = rolling {
                    add_assign(
                        &mut ti,
                        roll.pw.torque(elastic, normal, s.r[i], s.w[i], nrm),
                    );
                }
                add_assign(&mut force[i], f);
                sub_assign(&mut on_wall, f);
                add_assign(&mut torque[i], ti);
            }
            wall_force[wi] = on_wall;
        }
        for i in 0..n {
            add_assign(
                &mut force[i],
                add(scale([0.0, 0.0, -9.81], s.m[i]), s.fext[i]),
            );
        }
        (force, torque, history, wall_history, wall_force)
    }

    #[test]
    fn lanes_give_bitwise_what_one_contact_at_a_time_gives() {
        let s = scene(true);
        let expected = one_contact_at_a_time(&s, None);
        let contacts = expected.2.iter().filter(|h| **h != [0.0; 3]).count();
        let on_walls = expected.3.iter().filter(|h| **h != [0.0; 3]).count();
        // Enough contacts for full groups and a ragged last one, on both kinds.
        assert!(
            contacts > 2 * LANES && contacts % LANES != 0,
            "{contacts} contacts"
        );
        assert!(on_walls > LANES, "{on_walls} wall contacts");
        let bits = |o: &Outcome| -> Vec<u64> {
            [&o.0, &o.1, &o.2, &o.3, &o.4]
                .iter()
                .flat_map(|v| v.iter().flatten().map(|x| x.to_bits()))
                .collect()
        };
        let free = RollingPair {
            pp: NoRolling,
            pw: NoRolling,
        };
        let baseline = run(
            &s,
            &free,
            |inputs, out| chunk_forces_body(inputs, out, EachOwn),
            None,
        );
        assert_eq!(bits(&baseline), bits(&expected), "baseline lanes");
        let dispatched = run(&s, &free, chunk_forces, None);
        assert_eq!(bits(&dispatched), bits(&expected), "run-time dispatch");

        // The constant-torque rolling law: the same in lanes as one contact at a time, and
        // it changes only torques (the laws' forces do not read it).
        // Both readings (LIGGGHTS's and Lethe's).
        let mut torques = Vec::new();
        for reading in [
            TorqueReading::ElasticNoTwist,
            TorqueReading::WholeForceAndRotation,
        ] {
            let rolling = RollingPair {
                pp: ConstantTorque { mu_r: 0.1, reading },
                pw: ConstantTorque { mu_r: 0.2, reading },
            };
            let expected_rolling = one_contact_at_a_time(&s, Some(&rolling));
            let got = run(&s, &rolling, chunk_forces, None);
            assert_eq!(bits(&got), bits(&expected_rolling), "{reading:?}, in lanes");
            assert_eq!(got.0, expected.0, "forces do not depend on the rolling law");
            assert_ne!(got.1, expected.1, "the rolling law adds torques");
            torques.push(got.1);
        }
        assert_ne!(torques[0], torques[1], "the readings differ on this scene");
    }

    /// The constant-torque law on one contact against its formula. LIGGGHTS's reading:
    /// μ_r R* F_el against the relative rotation, less its part along n; none for pure
    /// twisting or no rotation, none for a negative elastic force. Lethe's: μ_r R* |F_n|
    /// against the whole relative rotation (twist too), F_n the whole normal force.
    #[test]
    fn constant_torque_opposes_relative_rolling() {
        let law = ConstantTorque {
            mu_r: 0.3,
            reading: TorqueReading::ElasticNoTwist,
        };
        let n = [0.0, 0.0, 1.0];
        let close = |m: Vec3, e: Vec3| (0..3).all(|c| (m[c] - e[c]).abs() < 1e-18);
        // Pure rolling: μ_r R* F_el against ω (the whole force 2.5 N not read).
        let m = law.torque(2.0, 2.5, 0.5e-3, [3.0, 4.0, 0.0], n);
        assert!(close(m, [-0.3e-3 * 0.6, -0.3e-3 * 0.8, 0.0]), "{m:?}");
        // Rolling and twisting: normalised by |ω|, the twist's part removed (LIGGGHTS).
        let m = law.torque(2.0, 2.5, 0.5e-3, [3.0, 0.0, 4.0], n);
        assert!(close(m, [-0.3e-3 * 0.6, 0.0, 0.0]), "{m:?}");
        assert_eq!(law.torque(2.0, 2.5, 0.5e-3, [0.0, 0.0, 9.0], n), [0.0; 3]);
        assert_eq!(law.torque(2.0, 2.5, 0.5e-3, [0.0; 3], n), [0.0; 3]);
        assert_eq!(
            law.torque(-1.0, 2.5, 0.5e-3, [1.0, 0.0, 0.0], n),
            [-0.0, 0.0, 0.0]
        );

        let lethe = ConstantTorque {
            mu_r: 0.3,
            reading: TorqueReading::WholeForceAndRotation,
        };
        // Pure rolling: μ_r R* |F_n| = 0.3 × 0.5e-3 × 2.5 against ω.
        let m = lethe.torque(2.0, 2.5, 0.5e-3, [3.0, 4.0, 0.0], n);
        assert!(close(m, [-0.375e-3 * 0.6, -0.375e-3 * 0.8, 0.0]), "{m:?}");
        // Rolling and twisting: the whole rotation resisted, twist included.
        let m = lethe.torque(2.0, 2.5, 0.5e-3, [3.0, 0.0, 4.0], n);
        assert!(close(m, [-0.375e-3 * 0.6, 0.0, -0.375e-3 * 0.8]), "{m:?}");
        // A damped contact pulling at its end (F_n = −1 N): |F_n| still resists.
        let m = lethe.torque(0.5, -1.0, 0.5e-3, [0.0, 2.0, 0.0], n);
        assert!(close(m, [0.0, -0.15e-3, 0.0]), "{m:?}");
        assert_eq!(lethe.torque(2.0, 2.5, 0.5e-3, [0.0; 3], n), [0.0; 3]);
    }

    /// Grains all alike take the constant path ([`UniformPair`]): the same forces as each
    /// pair's own constants, to round-off. Tolerance: only m* and r* are formed otherwise
    /// (sqrt(m/2) for sqrt(m·m/(m+m)), r/2 for r·r/(r+r)), a few ulps that carry into
    /// each force once; 1e-12 of the largest entry of each column is a thousand times that.
    #[test]
    fn alike_grains_take_the_constant_path_to_round_off() {
        let s = scene(false);
        let (r, m) = (s.r[0], s.m[0]);
        assert!(s.r.iter().all(|&x| x == r) && s.m.iter().all(|&x| x == m));
        let uniform = UniformPair {
            sqrt_m_eff: (0.5 * m).sqrt(),
            r_eff: 0.5 * r,
            sqrt_m: m.sqrt(),
            radius: r,
        };
        let expected = one_contact_at_a_time(&s, None);
        let contacts = expected.2.iter().filter(|h| **h != [0.0; 3]).count();
        assert!(contacts > 2 * LANES, "{contacts} contacts");
        let free = RollingPair {
            pp: NoRolling,
            pw: NoRolling,
        };
        let got = run(&s, &free, chunk_forces, Some(uniform));
        let columns = |o: &Outcome| {
            [
                o.0.clone(),
                o.1.clone(),
                o.2.clone(),
                o.3.clone(),
                o.4.clone(),
            ]
        };
        for (k, (a, b)) in columns(&got).iter().zip(columns(&expected)).enumerate() {
            let largest = b.iter().flatten().fold(0.0, |m: Real, x| m.max(x.abs()));
            for (x, y) in a.iter().flatten().zip(b.iter().flatten()) {
                assert!(
                    (x - y).abs() <= 1e-12 * largest,
                    "column {k}: {x} vs {y} (largest {largest})"
                );
            }
        }
    }
}
