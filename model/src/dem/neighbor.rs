//! Cell-list neighbour search with a Verlet skin.
//!
//! The half list holds every pair (i, j > i) closer than r_i + r_j + skin; it is rebuilt only
//! when the two largest drifts since the last build add up to more than the skin (until then
//! no pair can have come into contact unseen: a pair closes by at most its two drifts). At
//! each build the grains are re-sorted by cell so that neighbours sit close in memory, and
//! the tangential history of every live contact is carried over by the grains' stable ids.
//! Between builds, fed grains get rows of their own ([`NeighborList::append`]), and in place
//! of a build the far-drifted few can be listed again ([`NeighborList::refresh_movers`]);
//! their rows list each pair once, in either orientation.
//!
//! Periodic directions (a periodic pipe section, a chute): the cells wrap around, and a pair
//! found across the seam keeps the image shift of its partner (`offset`, m) until the next
//! build, as LAMMPS's neighbour lists do: positions are wrapped back into the box at each
//! build only, so between builds x_j + offset − x_i is the pair's separation. A pair is
//! listed once (j > i, from the one image within reach: a periodic direction holds at
//! least three cells).

use super::state::{ParticleState, ReorderScratch};
use super::team::{share, Shared, Team};
use super::vec3::{add, norm2, sub};
use super::walls::Wall;
use crate::{Real, Vec3};

/// Fewest rows per member worth sharing a build (below, the sync costs more than it saves).
pub const MIN_ROWS_PER_MEMBER: usize = 256;

/// Weights of a grain's work per step in units of one pair test (see [`RowScratch::build`]).
const PAIR: u64 = 1;
const CONTACT: u64 = 7;
const WALL_CONTACT: u64 = 6;
const GRAIN: u64 = 2;

/// One member's part of a build: the rows [lo, hi) of the list.
#[derive(Debug, Clone, Default)]
struct RowScratch {
    /// Partners of the rows, row after row.
    partner: Vec<u32>,
    /// Partners per row.
    count: Vec<u32>,
    /// Work per row (see [`RowScratch::build`]).
    cost: Vec<u64>,
    /// Per wall: the rows' grains near it, ascending.
    near: Vec<Vec<u32>>,
    /// Periodic boxes: the image shift of each partner, row after row, m.
    offset: Vec<Vec3>,
}

impl RowScratch {
    /// List grains `js` (all after i) within r_i + r_j + `skin` of grain i as its partners,
    /// their images at `shift` (a periodic box's: recorded per pair; without periodic
    /// directions nothing is added or recorded, the loop compiled without it). Returns how
    /// many of them touch i.
    #[inline(always)]
    fn scan<const PERIODIC: bool>(
        &mut self,
        x: &[Vec3],
        r: &[Real],
        i: usize,
        js: std::ops::Range<usize>,
        skin: Real,
        shift: Vec3,
    ) -> u64 {
        let (xi, ri) = (x[i], r[i]);
        let mut contacts = 0;
        for j in js {
            let touch = ri + r[j];
            let reach = touch + skin;
            let mut d = sub(x[j], xi);
            if PERIODIC {
                d = add(d, shift);
            }
            let d2 = norm2(d);
            if d2 < reach * reach {
                self.partner.push(j as u32);
                if PERIODIC {
                    self.offset.push(shift);
                }
                contacts += u64::from(d2 < touch * touch);
            }
        }
        contacts
    }

    /// Pairs of rows [lo, hi), their work, and the rows' grains near each wall.
    ///
    /// The work of a grain's share of a step, in units of one pair test: its pair tests, its
    /// contacts (the laws: ~7 pair tests each), its wall contacts (~6) and its own
    /// integration (~2); the weights are the bench's stage times (`cargo bench --bench
    /// dem_bench`) over its counts. Contacts at the build stand for the contacts until the
    /// next, as grains drift less than the skin in between. Weighing pairs alone left
    /// the dense bottom of a bed 12 % more work than the top.
    #[allow(clippy::too_many_arguments)]
    fn build(
        &mut self,
        s: &ParticleState,
        grid: &CellGrid,
        cell_start: &[u32],
        skin: Real,
        walls: &[Wall],
        lo: usize,
        hi: usize,
    ) {
        self.partner.clear();
        self.count.clear();
        self.cost.clear();
        self.offset.clear();
        let dims = grid.dims;
        let periodic = grid.is_periodic();
        let (x, r) = (&s.position[..], &s.radius[..]);
        for i in lo..hi {
            let xi = x[i];
            let c = grid.coord(xi);
            let before = self.partner.len();
            let mut contacts = 0u64;
            for dz in -1i64..=1 {
                let Some((z, shift_z)) = grid.neighbour(2, c[2], dz) else {
                    continue;
                };
                for dy in -1i64..=1 {
                    let Some((y, shift_y)) = grid.neighbour(1, c[1], dy) else {
                        continue;
                    };
                    let row = grid.index([0, y, z]);
                    // The fastest direction as runs of cells: one run without wrapping, each
                    // cell on its own when the direction is periodic.
                    let mut runs = [(0usize, 0usize, [0.0; 3]); 3];
                    let nruns = if grid.wrap[0].is_some() {
                        for (k, dx) in (-1i64..=1).enumerate() {
                            let (cx, sx) = grid.neighbour(0, c[0], dx).expect("periodic");
                            runs[k] = (cx, cx, sx);
                        }
                        3
                    } else {
                        let x0 = (c[0] as i64 - 1).max(0) as usize;
                        let x1 = (c[0] + 1).min(dims[0] - 1);
                        runs[0] = (x0, x1, [0.0; 3]);
                        1
                    };
                    for &(x0, x1, shift_x) in &runs[..nruns] {
                        let (a, b) = (
                            cell_start[row + x0] as usize,
                            cell_start[row + x1 + 1] as usize,
                        );
                        let js = a.max(i + 1)..b;
                        contacts += if periodic {
                            let shift =
                                std::array::from_fn(|k| shift_x[k] + shift_y[k] + shift_z[k]);
                            self.scan::<true>(x, r, i, js, skin, shift)
                        } else {
                            self.scan::<false>(x, r, i, js, skin, [0.0; 3])
                        };
                    }
                }
            }
            let pairs = (self.partner.len() - before) as u64;
            self.count.push(pairs as u32);
            self.cost.push(PAIR * pairs + CONTACT * contacts + GRAIN);
        }
        self.near.resize(walls.len(), Vec::new());
        for (near, wall) in self.near.iter_mut().zip(walls) {
            near.clear();
            for i in lo..hi {
                if let Some((overlap, _)) = wall.contact(x[i], r[i] + skin) {
                    near.push(i as u32);
                    if overlap > skin {
                        self.cost[i - lo] += WALL_CONTACT;
                    }
                }
            }
        }
    }
}

/// Uniform grid of cells over the simulation box. Cells are numbered with the box's
/// longest direction slowest (`axes`): grains sorted by cell then lie in slices across
/// it, so the threads' contiguous ranges of grains are slices of a tube along its axis
/// and few pairs cross from one to the next. (Numbered x fastest, a horizontal pipe along
/// x was cut into a lower and an upper layer: most pairs of the resting layer crossed, and
/// two threads ran its slug slower than one.)
#[derive(Debug, Clone)]
pub struct CellGrid {
    lo: Vec3,
    inv_cell: Real,
    /// Cells along `axes[0]` (fastest), `axes[1]`, `axes[2]` (slowest).
    dims: [usize; 3],
    /// The lab direction (0 = x, 1 = y, 2 = z) of each cell coordinate, fastest first.
    axes: [usize; 3],
    /// Per cell coordinate (fastest first): the box's length when the direction is
    /// periodic, m.
    wrap: [Option<Real>; 3],
}

impl CellGrid {
    /// Grid over the box [lo, hi] with cells at least `cell` wide.
    pub fn new(lo: Vec3, hi: Vec3, cell: Real) -> Self {
        match Self::periodic(lo, hi, cell, [false; 3]) {
            Ok(grid) => grid,
            Err(_) => unreachable!("only a periodic direction can be refused"),
        }
    }

    /// Grid over the box [lo, hi] with cells at least `cell` wide, wrapping around along
    /// the lab directions marked `periodic` (each must hold at least three cells, so that
    /// a grain's neighbour cells are distinct and a pair is found through one image only;
    /// refused otherwise, naming the direction).
    pub fn periodic(lo: Vec3, hi: Vec3, cell: Real, periodic: [bool; 3]) -> Result<Self, String> {
        let mut dims = [1usize; 3];
        let mut size = cell;
        for k in 0..3 {
            dims[k] = (((hi[k] - lo[k]) / cell).floor() as usize).max(1);
        }
        // Cap the cell count for huge, sparse boxes; cells then grow (never shrink).
        while dims.iter().product::<usize>() > 4_000_000 {
            size *= 1.26;
            for k in 0..3 {
                dims[k] = (((hi[k] - lo[k]) / size).floor() as usize).max(1);
            }
        }
        let width = (0..3)
            .map(|k| (hi[k] - lo[k]) / dims[k] as Real)
            .fold(Real::INFINITY, Real::min);
        // The direction with the most cells slowest (z on a tie), the others in order.
        let slowest = (0..3).max_by_key(|&k| dims[k]).expect("three axes");
        let mut axes = [0usize; 3];
        let mut rest = (0..3).filter(|&k| k != slowest);
        axes[0] = rest.next().expect("two others");
        axes[1] = rest.next().expect("two others");
        axes[2] = slowest;
        // (The scene check asks for three cells of the finest grid; a huge box whose cells
        // had to grow past the cap can still fall short.)
        if let Some(k) = (0..3).find(|&k| periodic[k] && dims[k] < 3) {
            return Err(format!(
                "the periodic direction {} holds {} neighbour cells of {:.4e} m (a box this \
                 large takes cells over the least size); three are needed",
                ["x", "y", "z"][k],
                dims[k],
                (hi[k] - lo[k]) / dims[k] as Real
            ));
        }
        Ok(Self {
            lo,
            inv_cell: 1.0 / width.max(cell),
            dims: axes.map(|k| dims[k]),
            axes,
            wrap: axes.map(|k| periodic[k].then(|| hi[k] - lo[k])),
        })
    }

    /// True when some direction wraps around.
    pub fn is_periodic(&self) -> bool {
        self.wrap.iter().any(Option::is_some)
    }

    /// The cell `step` (−1, 0, 1) from coordinate `c` along cell direction `k`, and the
    /// image shift of the grains found there (m, lab frame); None past a box end that does
    /// not wrap.
    #[inline]
    fn neighbour(&self, k: usize, c: usize, step: i64) -> Option<(usize, Vec3)> {
        let n = self.dims[k] as i64;
        let to = c as i64 + step;
        let mut shift = [0.0; 3];
        if (0..n).contains(&to) {
            return Some((to as usize, shift));
        }
        let length = self.wrap[k]?;
        // Past the upper end the partner's image lies one length up, past the lower end
        // one length down.
        shift[self.axes[k]] = if to < 0 { -length } else { length };
        Some((to.rem_euclid(n) as usize, shift))
    }

    /// Bring positions back into the box along its periodic directions (between builds
    /// grains may stray past a periodic end by less than the skin).
    pub fn wrap_positions(&self, x: &mut [Vec3]) {
        for (k, &a) in self.axes.iter().enumerate() {
            if let Some(length) = self.wrap[k] {
                let lo = self.lo[a];
                for p in x.iter_mut() {
                    let u = p[a] - lo;
                    if !(0.0..length).contains(&u) {
                        p[a] = lo + u.rem_euclid(length);
                    }
                }
            }
        }
    }

    /// Cell coordinates of a point, fastest first (see `axes`).
    #[inline]
    fn coord(&self, x: Vec3) -> [usize; 3] {
        std::array::from_fn(|k| self.coord_along(k, x[self.axes[k]]))
    }

    /// Cell coordinate along cell direction `k` of a point whose lab coordinate along that
    /// direction is `v`. Points outside the box are clamped into the edge cells (monotone,
    /// so close grains stay in the same or adjacent cells).
    #[inline(always)]
    fn coord_along(&self, k: usize, v: Real) -> usize {
        let a = self.axes[k];
        // The cast truncates, which is the floor for the non-negative, and saturates: a
        // negative or NaN coordinate gives 0 (without a call to libm's floor: a build asks
        // this for every grain).
        (((v - self.lo[a]) * self.inv_cell) as usize).min(self.dims[k] - 1)
    }

    /// The grains of a list sorted by cell index whose cells lie within `reach` (m) of `x`
    /// along every direction, as index ranges in ascending order, one per row of the box
    /// of cells (the fastest direction's cells of a row are consecutive indices).
    /// `first_at(c)`: the first entry whose cell is not below cell c (see
    /// [`first_at_by_bisection`] when no table of cell starts is at hand). Without
    /// periodic directions.
    fn sorted_ranges_near(
        &self,
        x: Vec3,
        reach: Real,
        first_at: impl Fn(usize) -> usize,
        mut visit: impl FnMut(std::ops::Range<usize>),
    ) {
        let lo: [usize; 3] = std::array::from_fn(|k| self.coord_along(k, x[self.axes[k]] - reach));
        let hi: [usize; 3] = std::array::from_fn(|k| self.coord_along(k, x[self.axes[k]] + reach));
        for c2 in lo[2]..=hi[2] {
            for c1 in lo[1]..=hi[1] {
                let from = first_at(self.index([lo[0], c1, c2]));
                let to = first_at(self.index([hi[0], c1, c2]) + 1);
                if from < to {
                    visit(from..to);
                }
            }
        }
    }

    #[inline]
    fn index(&self, c: [usize; 3]) -> usize {
        (c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]
    }

    fn count(&self) -> usize {
        self.dims.iter().product()
    }

    /// The cells [from, to) whose starts a build reads (as `cell_start[from..=to]`) for
    /// grains in `cells`: every cell of the slices (fixed slowest coordinate) that hold a
    /// grain and of the slice on each side, the neighbours' reach. A box wrapping along
    /// its slowest direction reads across the seam: all cells.
    fn cells_read(&self, cells: &[u32]) -> (usize, usize) {
        let all = self.count();
        if self.wrap[2].is_some() {
            return (0, all);
        }
        let plane = self.dims[0] * self.dims[1];
        let Some(lowest) = cells.iter().min() else {
            return (0, 0);
        };
        let highest = cells.iter().max().expect("not empty");
        let first_slice = (*lowest as usize / plane).saturating_sub(1);
        let last_slice = *highest as usize / plane + 1;
        (first_slice * plane, ((last_slice + 1) * plane).min(all))
    }
}

/// Half neighbour list in compressed rows, with one shear history per pair.
#[derive(Debug, Clone, Default)]
pub struct NeighborList {
    /// Row offsets: partners of grain i are `partner[start[i]..start[i+1]]`.
    pub start: Vec<u32>,
    /// Partner indices j > i.
    pub partner: Vec<u32>,
    /// Periodic boxes: the image shift of each pair's partner, m (x_j + offset − x_i is the
    /// pair's separation); empty without periodic directions.
    pub offset: Vec<Vec3>,
    /// Tangential shear displacement of each pair as seen from i, m.
    pub history: Vec<Vec3>,
    /// Per wall, ascending: the grains within one skin of it at the build. No other grain
    /// can reach the wall before the next build (that comes once a grain has moved half the
    /// skin), so the force loop asks only these about that wall.
    pub near_wall: Vec<Vec<u32>>,
    /// The work of each grain's share of a step at the build, in units of one pair test
    /// (see [`RowScratch::build`]): what the threads' chunks are cut by.
    pub cost: Vec<u64>,
    /// Positions at the last build, m.
    x_at_build: Vec<Vec3>,
    /// Scratch: per-cell start offsets.
    cell_start: Vec<u32>,
    /// Scratch of the sort: each grain's cell, the next free slot per cell, the new order.
    cell: Vec<u32>,
    fill: Vec<u32>,
    order: Vec<usize>,
    /// Scratch: one spare column per element type, for reordering the grains in place.
    spare: ReorderScratch,
    /// Scratch: each member's rows.
    rows: Vec<RowScratch>,
    /// Scratch of [`NeighborList::refresh_movers`] (a refresh every few steps allocates
    /// nothing once these have grown).
    refresh: RefreshScratch,
    /// Live histories keyed by (smaller id, larger id), as seen from the smaller id; filled
    /// by [`NeighborList::stash_history`] before grain indices change.
    saved: Vec<((u64, u64), Vec3)>,
    /// Scratch for [`NeighborList::restore_history`]: new index of each id (offset by the
    /// smallest), saved contacts by row, and their row offsets.
    index_of_id: Vec<u32>,
    contacts: Vec<(u32, u32, Vec3)>,
    contact_start: Vec<u32>,
    /// The list matches the current grain order.
    valid: bool,
    /// Grains [0, appended_from) lie sorted by cell of their reference positions, as a
    /// build leaves them; later ones were appended since ([`NeighborList::append`]). Only a search aid: what `append` lists does not
    /// depend on it. `usize::MAX`: not known yet (a list from a checkpoint).
    appended_from: usize,
    /// Builds so far.
    pub builds: u64,
    /// How the list was kept between builds (the summary reports them).
    pub upkeep: ListUpkeep,
}

/// The first entry k of [0, `len`) whose cell (`cell_of(k)`, ascending in k) is not below
/// `cell`, by bisection: [`CellGrid::sorted_ranges_near`]'s lookup over a sorted prefix
/// without a table of cell starts.
fn first_at_by_bisection(len: usize, cell_of: impl Fn(usize) -> usize, cell: usize) -> usize {
    let (mut a, mut b) = (0, len);
    while a < b {
        let m = (a + b) / 2;
        if cell_of(m) < cell {
            a = m + 1;
        } else {
            b = m;
        }
    }
    a
}

/// The pair test of a row listed between builds ([`NeighborList::append`],
/// [`NeighborList::refresh_movers`]): grains a and j are listed when closer than
/// r_a + r_j + `margin` (the skin plus the others' largest drift D); Some(touching) then.
fn appended_pair(xa: Vec3, ra: Real, xj: Vec3, rj: Real, margin: Real) -> Option<bool> {
    let touch = ra + rj;
    let reach = touch + margin;
    let d2 = norm2(sub(xj, xa));
    (d2 < reach * reach).then_some(d2 < touch * touch)
}

/// Scratch of [`NeighborList::refresh_movers`]: per grain whether it moved far, its new
/// reference and its new index; the movers' saved histories and a row being searched; the
/// wall flags; and the new list's columns, swapped with the list's own (so each refresh
/// reuses the previous list's memory).
#[derive(Debug, Clone, Default)]
struct RefreshScratch {
    is_mover: Vec<bool>,
    reference: Vec<Vec3>,
    new_index: Vec<u32>,
    saved: Vec<((u64, u64), Vec3)>,
    row: Vec<(u32, Vec3)>,
    listed: Vec<bool>,
    start: Vec<u32>,
    partner: Vec<u32>,
    history: Vec<Vec3>,
    cost: Vec<u64>,
}

/// What [`NeighborList::refresh_movers`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Refreshed {
    /// Grains listed again from where they are (their drift is now zero).
    pub movers: usize,
    /// The largest drift of any grain from its reference afterwards (m): the others'.
    pub largest_drift: Real,
}

/// How often a [`NeighborList`] was kept without a whole build, since the run began.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct ListUpkeep {
    /// Feeds whose grains joined the list without a build ([`NeighborList::append`]).
    pub appends: u64,
    /// Builds replaced by listing the far-drifted grains again
    /// ([`NeighborList::refresh_movers`]).
    pub refreshes: u64,
}

/// What of a [`NeighborList`] a checkpoint keeps: the list, its histories and its
/// reference positions (the rest is scratch that the next build fills).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct NeighborKeep {
    start: Vec<u32>,
    partner: Vec<u32>,
    #[serde(default)]
    offset: Vec<Vec3>,
    history: Vec<Vec3>,
    near_wall: Vec<Vec<u32>>,
    cost: Vec<u64>,
    x_at_build: Vec<Vec3>,
    saved: Vec<((u64, u64), Vec3)>,
    valid: bool,
    builds: u64,
}

impl NeighborList {
    /// Keep only the grains `keep` lists, in its order (grains leaving between builds),
    /// through this list's spare columns: no allocation, as a build's reorder.
    pub fn reorder_grains(
        &mut self,
        state: &mut ParticleState,
        keep: &[usize],
        walls: usize,
        team: &Team,
    ) {
        state.reorder(keep, walls, &mut self.spare, team);
    }

    /// The part a checkpoint keeps.
    pub fn keep(&self) -> NeighborKeep {
        NeighborKeep {
            start: self.start.clone(),
            partner: self.partner.clone(),
            offset: self.offset.clone(),
            history: self.history.clone(),
            near_wall: self.near_wall.clone(),
            cost: self.cost.clone(),
            x_at_build: self.x_at_build.clone(),
            saved: self.saved.clone(),
            valid: self.valid,
            builds: self.builds,
        }
    }

    /// Go on from a checkpoint's list, for `grains` grains; refused when it does not fit.
    pub fn restore(&mut self, k: NeighborKeep, grains: usize) -> Result<(), String> {
        let rows_fit = k.start.is_empty() || k.start.len() == grains + 1;
        let pairs = k.start.last().map_or(0, |&e| e as usize);
        if !rows_fit || k.partner.len() != pairs || k.history.len() != pairs {
            return Err(format!(
                "the neighbour list ({} rows, {} pairs, {} histories) does not fit {grains} grains",
                k.start.len().saturating_sub(1),
                k.partner.len(),
                k.history.len()
            ));
        }
        if !k.offset.is_empty() && k.offset.len() != pairs {
            return Err("the neighbour list's image shifts do not fit its pairs".to_string());
        }
        if k.partner.iter().any(|&j| j as usize >= grains) {
            return Err("a neighbour index lies past the last grain".to_string());
        }
        self.start = k.start;
        self.partner = k.partner;
        self.offset = k.offset;
        self.history = k.history;
        self.near_wall = k.near_wall;
        self.cost = k.cost;
        self.x_at_build = k.x_at_build;
        self.saved = k.saved;
        self.valid = k.valid;
        // (Found again at the next append: only a search aid, see `append`.)
        self.appended_from = usize::MAX;
        self.builds = k.builds;
        Ok(())
    }

    /// Positions at the last build (empty before the first): the drifts that call for a
    /// rebuild are measured from here.
    pub fn reference_positions(&self) -> &[Vec3] {
        &self.x_at_build
    }

    /// Sort grains by cell, rebuild the list, and carry the shear history over. The team's
    /// members share the work (cells, the reordering by column, pairs and wall lists by
    /// contiguous rows); the list does not depend on how many took part.
    pub fn rebuild(
        &mut self,
        state: &mut ParticleState,
        grid: &CellGrid,
        skin: Real,
        walls: &[Wall],
        keep_history: bool,
        team: &Team,
    ) {
        let n = state.len();
        if keep_history {
            self.stash_history(state);
        }
        let members = team.members_for(n, MIN_ROWS_PER_MEMBER);
        // 0. Periodic directions: every grain back into the box.
        grid.wrap_positions(&mut state.position);
        // 1. Each grain's cell.
        self.cell.resize(n, 0);
        {
            let cell = Shared::new(&mut self.cell);
            let x = &state.position;
            team.run(members, &|m| {
                let (lo, hi) = share(n, members, m);
                // SAFETY: members write disjoint ranges.
                let out = unsafe { cell.range(lo, hi) };
                for (c, &x) in out.iter_mut().zip(&x[lo..hi]) {
                    *c = grid.index(grid.coord(x)) as u32;
                }
            });
        }
        // 2. Counting sort of the grains by cell (stable, hence deterministic), over the
        // cells the build reads only: those of the slices holding grains and one slice
        // each side (a long pipe filling from its inlet pays for its grains, not for a
        // million empty cells cleared and summed at every build). The rest of `cell_start`
        // is stale and never read.
        let (from, to) = grid.cells_read(&self.cell);
        if self.cell_start.len() < to + 1 {
            self.cell_start.resize(to + 1, 0);
        }
        let starts = &mut self.cell_start[from..=to];
        starts.fill(0);
        for &c in &self.cell {
            starts[c as usize + 1 - from] += 1;
        }
        for c in 0..to - from {
            starts[c + 1] += starts[c];
        }
        self.fill.clear();
        self.fill.extend_from_slice(&starts[..to - from]);
        self.order.resize(n, 0);
        for (i, &c) in self.cell.iter().enumerate() {
            let slot = &mut self.fill[c as usize - from];
            self.order[*slot as usize] = i;
            *slot += 1;
        }
        state.reorder(&self.order, walls.len(), &mut self.spare, team);
        // 3. Pairs within reach from the 27 surrounding cells, the contacts among them, and
        // the grains near each wall (closer than one skin: the wall's contact test with the
        // radius grown by the skin), each member over its own rows.
        self.rows.resize_with(team.members(), RowScratch::default);
        {
            let rows = Shared::new(&mut self.rows);
            let (s, cell_start) = (&*state, &self.cell_start[..]);
            team.run(members, &|m| {
                let (lo, hi) = share(n, members, m);
                // SAFETY: slot m is member m's alone.
                let out = unsafe { &mut rows.range(m, m + 1)[0] };
                out.build(s, grid, cell_start, skin, walls, lo, hi);
            });
        }
        // 4. The members' rows joined in order.
        self.start.clear();
        self.partner.clear();
        self.offset.clear();
        self.cost.clear();
        self.start.push(0);
        self.near_wall.resize(walls.len(), Vec::new());
        for near in &mut self.near_wall {
            near.clear();
        }
        for rows in &self.rows[..members] {
            for &count in &rows.count {
                let last = *self.start.last().expect("starts with 0");
                self.start.push(last + count);
            }
            self.partner.extend_from_slice(&rows.partner);
            self.offset.extend_from_slice(&rows.offset);
            self.cost.extend_from_slice(&rows.cost);
            for (near, mine) in self.near_wall.iter_mut().zip(&rows.near) {
                near.extend_from_slice(mine);
            }
        }
        // 5. Restore histories.
        self.history.clear();
        if keep_history {
            self.history.resize(self.partner.len(), [0.0; 3]);
            self.restore_history(state);
        }
        self.saved.clear();
        self.valid = true;
        self.x_at_build.clear();
        self.x_at_build.extend_from_slice(&state.position);
        self.appended_from = n;
        self.builds += 1;
    }

    /// Whether grains pushed after the first `grains` can join the list by
    /// [`NeighborList::append`] instead of a build: the list matches those grains and
    /// knows which of them are in build order, and no direction wraps (a pair across a
    /// seam needs its image shift, which only a build finds).
    pub fn can_append(&self, grains: usize, grid: &CellGrid) -> bool {
        self.valid
            && self.start.len() == grains + 1
            && self.x_at_build.len() == grains
            && (self.appended_from <= grains || self.appended_from == usize::MAX)
            && !grid.is_periodic()
    }

    /// Give grains [first, n) — just pushed, after a [`NeighborList::can_append`] of
    /// `first` — rows of their own without a build: a new grain a lists every earlier
    /// grain j closer than r_a + r_j + skin + D now, where D (m) is the largest drift of
    /// any grain since its reference position (the last build's, or where it was
    /// appended); its reference is where it is now.
    ///
    /// Why nothing is missed until the next build: a pair left out was at least
    /// r_a + r_j + skin + D apart when a was appended, so to touch it must close by more
    /// than skin + D. Grain a has moved its own drift since; grain j at most its drift now
    /// plus its drift then (≤ D). So the two drifts add up to more than the skin, which is
    /// the test that calls the next build
    /// ([`ChunkVerdict::moved_far`](super::integrate::ChunkVerdict::moved_far)). The same
    /// reasoning as a build's, with D added to the reach.
    ///
    /// The new rows list partners j < a (a build lists j > i), ascending; the force pass
    /// and its spills take either. Earlier grains are found through the build's order:
    /// sorted by slice along the box's longest direction at their build positions, so
    /// those within reach lie in one index range, found by bisection (a feed into an 8 m
    /// pipe of 600 000 grains tests a few thousand, where a build sorts them all); grains
    /// appended since are tested one by one. A row holds every earlier grain within
    /// reach in ascending order however they were found, so a run resumed from a
    /// checkpoint (which does not keep where the sorted grains end) lists the same.
    /// `r_max`: the largest grain radius (m). Returns how many pairs were added.
    #[allow(clippy::too_many_arguments)]
    pub fn append(
        &mut self,
        state: &ParticleState,
        first: usize,
        grid: &CellGrid,
        skin: Real,
        r_max: Real,
        walls: &[Wall],
        max_drift: Real,
    ) -> usize {
        let n = state.len();
        debug_assert!(self.can_append(first, grid) && first <= n);
        let (x, r) = (&state.position[..], &state.radius[..]);
        let with_history = self.history.len() == self.partner.len();
        let pairs_before = self.partner.len();
        let cell = |p: &Vec3| grid.index(grid.coord(*p));
        if self.appended_from == usize::MAX {
            let x0 = &self.x_at_build;
            self.appended_from = (1..x0.len())
                .find(|&i| cell(&x0[i]) < cell(&x0[i - 1]))
                .unwrap_or(x0.len());
        }
        let sorted = &self.x_at_build[..self.appended_from];
        for a in first..n {
            let (xa, ra) = (x[a], r[a]);
            let before = self.partner.len();
            let mut contacts = 0u64;
            let mut test = |j: usize, partner: &mut Vec<u32>| {
                if let Some(touching) = appended_pair(xa, ra, x[j], r[j], skin + max_drift) {
                    partner.push(j as u32);
                    contacts += u64::from(touching);
                }
            };
            // Earlier grains in build order whose reference lies within the widest reach
            // (their drift D counted twice: now and at their reference), by cell boxes;
            // those appended since, one by one.
            let widest = ra + r_max + skin + 2.0 * max_drift;
            grid.sorted_ranges_near(
                xa,
                widest,
                |c| first_at_by_bisection(sorted.len(), |k| cell(&sorted[k]), c),
                |range| range.for_each(|j| test(j, &mut self.partner)),
            );
            (self.appended_from..a).for_each(|j| test(j, &mut self.partner));
            self.partner[before..].sort_unstable();
            let pairs = (self.partner.len() - before) as u64;
            self.start.push(self.partner.len() as u32);
            let mut cost = PAIR * pairs + CONTACT * contacts + GRAIN;
            self.near_wall.resize(walls.len(), Vec::new());
            for (near, wall) in self.near_wall.iter_mut().zip(walls) {
                if let Some((overlap, _)) = wall.contact(xa, ra + skin) {
                    near.push(a as u32);
                    if overlap > skin {
                        cost += WALL_CONTACT;
                    }
                }
            }
            self.cost.push(cost);
        }
        // (Their reference positions: where they are now.)
        self.x_at_build.extend_from_slice(&x[first..n]);
        if with_history {
            self.history.resize(self.partner.len(), [0.0; 3]);
        }
        self.upkeep.appends += 1;
        self.partner.len() - pairs_before
    }

    /// Put the saved histories back on the new list's pairs: each saved contact goes to the
    /// row of its grain with the smaller new index (grains looked up by id in a dense table
    /// over the ids present), then each row's pairs look through that row's few contacts.
    /// Linear in pairs + contacts (a binary search per pair cost half of a rebuild).
    fn restore_history(&mut self, state: &ParticleState) {
        let n = state.len();
        if self.saved.is_empty() || n == 0 {
            return;
        }
        let lo = state.id.iter().copied().min().unwrap_or(0);
        let hi = state.id.iter().copied().max().unwrap_or(0);
        let slot = &mut self.index_of_id;
        slot.clear();
        slot.resize((hi - lo + 1) as usize, u32::MAX);
        for (i, &id) in state.id.iter().enumerate() {
            slot[(id - lo) as usize] = i as u32;
        }
        let find = |id: u64| -> Option<usize> {
            if id < lo || id > hi {
                return None;
            }
            let i = slot[(id - lo) as usize];
            (i != u32::MAX).then_some(i as usize)
        };
        // Contacts of both grains still present, as (row, partner, history seen from row).
        let contacts = &mut self.contacts;
        contacts.clear();
        for &((a, b), h) in &self.saved {
            let (Some(ia), Some(ib)) = (find(a), find(b)) else {
                continue;
            };
            let (i, j) = if ia < ib { (ia, ib) } else { (ib, ia) };
            // Saved as seen from the smaller id, a.
            let seen = if state.id[i] == a {
                h
            } else {
                [-h[0], -h[1], -h[2]]
            };
            contacts.push((i as u32, j as u32, seen));
        }
        // Bucket by row (counting sort).
        let row_start = &mut self.contact_start;
        row_start.clear();
        row_start.resize(n + 1, 0);
        for c in contacts.iter() {
            row_start[c.0 as usize + 1] += 1;
        }
        for i in 0..n {
            row_start[i + 1] += row_start[i];
        }
        let mut by_row = vec![(0u32, [0.0; 3]); contacts.len()];
        let mut fill = row_start.clone();
        for &(i, j, h) in contacts.iter() {
            by_row[fill[i as usize] as usize] = (j, h);
            fill[i as usize] += 1;
        }
        for i in 0..n {
            let mine = &by_row[row_start[i] as usize..row_start[i + 1] as usize];
            if mine.is_empty() {
                continue;
            }
            for k in self.start[i] as usize..self.start[i + 1] as usize {
                if let Some(&(_, h)) = mine.iter().find(|e| e.0 == self.partner[k]) {
                    self.history[k] = h;
                }
            }
        }
    }

    /// In place of a build, when few grains have drifted far: the grains that drifted
    /// more than `threshold` (m; "movers") are listed again from where they are now, as
    /// [`NeighborList::append`] lists fed grains (with D the largest drift of the others,
    /// ≤ `threshold`), and take that as their reference; the others keep their pairs among
    /// themselves, their shear histories and their references. The movers' histories carry
    /// over by id. The grains are then re-sorted (stably) by cell of their references, as a
    /// build sorts them, so the next search can bisect. A flow where a few grains fly
    /// fast over a slow bed (the gas stream over a resting layer) calls a build every few
    /// steps for all of them; this searches pairs for the few, and only passes over the rest.
    ///
    /// Nothing is missed: a pair of two others is a build's; a pair with a mover is an
    /// appended pair, and `append`'s reasoning holds for it. Afterwards no grain has
    /// drifted more than `threshold` from its reference, so with `threshold` ≤ skin/4 the
    /// next build or refresh is half a skin's drift away at least. A row lists its pairs
    /// in any orientation (a pair of two others stays in its grain's row however the two
    /// are re-sorted; a mover's row lists every other grain and the movers before it),
    /// ascending, so the list depends on the grains and their drifts only.
    ///
    /// Returns how many grains were listed again and the largest drift left, or None,
    /// changing nothing, when a build is needed instead: the list cannot take such rows ([`NeighborList::can_append`]), no
    /// grain drifted past `threshold`, or more than one grain in `max_share` did (movers'
    /// reach is wider by D and their rows out of cell order: a build then pays).
    #[allow(clippy::too_many_arguments)]
    pub fn refresh_movers(
        &mut self,
        state: &mut ParticleState,
        grid: &CellGrid,
        skin: Real,
        r_max: Real,
        walls: &[Wall],
        threshold: Real,
        max_share: usize,
        team: &Team,
    ) -> Option<Refreshed> {
        let n = state.len();
        if n == 0 || !self.can_append(n, grid) {
            return None;
        }
        let (x, r, id) = (&state.position[..], &state.radius[..], &state.id[..]);
        let sc = &mut self.refresh;
        // 1. The movers, and the others' largest drift.
        let limit2 = threshold * threshold;
        sc.is_mover.clear();
        let (mut movers, mut rest2): (usize, Real) = (0, 0.0);
        for i in 0..n {
            let d2 = norm2(sub(x[i], self.x_at_build[i]));
            let far = d2 > limit2;
            sc.is_mover.push(far);
            if far {
                movers += 1;
            } else {
                rest2 = rest2.max(d2);
            }
        }
        if movers == 0 || movers * max_share > n {
            return None;
        }
        let is_mover = &sc.is_mover[..];
        let rest_drift = rest2.sqrt();
        // 2. The new references, and the grains' new order: by cell of the reference, as a
        // build sorts, stably (a counting sort over the cells from the lowest to the
        // highest that holds a grain).
        sc.reference.clear();
        sc.reference.extend((0..n).map(|i| {
            if is_mover[i] {
                x[i]
            } else {
                self.x_at_build[i]
            }
        }));
        self.cell.clear();
        self.cell.extend(
            sc.reference
                .iter()
                .map(|p| grid.index(grid.coord(*p)) as u32),
        );
        let cell = &self.cell[..];
        let lowest = *cell.iter().min().expect("n > 0") as usize;
        let highest = *cell.iter().max().expect("n > 0") as usize;
        self.fill.clear();
        self.fill.resize(highest - lowest + 2, 0);
        for &c in cell {
            self.fill[c as usize - lowest + 1] += 1;
        }
        for c in 0..highest - lowest {
            self.fill[c + 1] += self.fill[c];
        }
        let order = &mut self.order;
        order.clear();
        order.resize(n, 0);
        for (i, &c) in cell.iter().enumerate() {
            let slot = &mut self.fill[c as usize - lowest];
            order[*slot as usize] = i;
            *slot += 1;
        }
        let order = &self.order[..];
        sc.new_index.clear();
        sc.new_index.resize(n, 0);
        for (k, &i) in order.iter().enumerate() {
            sc.new_index[i] = k as u32;
        }
        // 3. The movers' live histories by (smaller id, larger id), seen from the smaller.
        let with_history = self.history.len() == self.partner.len();
        sc.saved.clear();
        if with_history {
            for i in 0..n {
                for k in self.start[i] as usize..self.start[i + 1] as usize {
                    let j = self.partner[k] as usize;
                    let h = self.history[k];
                    if (is_mover[i] || is_mover[j]) && h != [0.0; 3] {
                        let (a, b) = (id[i], id[j]);
                        sc.saved.push(if a < b {
                            ((a, b), h)
                        } else {
                            ((b, a), [-h[0], -h[1], -h[2]])
                        });
                    }
                }
            }
            sc.saved.sort_unstable_by_key(|e| e.0);
        }
        // 4. The rows in the new order: an other's row less its pairs with movers; a
        // mover's row searched (every other grain, and the movers before it, within
        // r_a + r_j + skin + D now) in the cells its reach can hold.
        // (After the placement above, fill[c − lowest] is where cell c ends in the new
        // order, i.e. where cell c + 1 starts.)
        let cell_end = &self.fill[..];
        let first_in_new_order = |c: usize| {
            if c <= lowest {
                0
            } else if c > highest {
                n
            } else {
                cell_end[c - 1 - lowest] as usize
            }
        };
        let (start, partner) = (&mut sc.start, &mut sc.partner);
        let (history, cost) = (&mut sc.history, &mut sc.cost);
        start.clear();
        partner.clear();
        history.clear();
        cost.clear();
        start.push(0u32);
        for (k, &i) in order.iter().enumerate() {
            if !is_mover[i] {
                for p in self.start[i] as usize..self.start[i + 1] as usize {
                    let j = self.partner[p] as usize;
                    if !is_mover[j] {
                        partner.push(sc.new_index[j]);
                        if with_history {
                            history.push(self.history[p]);
                        }
                    }
                }
                cost.push(self.cost[i]);
            } else {
                let (xi, ri) = (x[i], r[i]);
                let widest = ri + r_max + skin + 2.0 * rest_drift;
                let row = &mut sc.row;
                row.clear();
                let mut contacts = 0u64;
                let saved = &sc.saved[..];
                grid.sorted_ranges_near(xi, widest, first_in_new_order, |range| {
                    for c in range {
                        let j = order[c];
                        if c == k || (is_mover[j] && c > k) {
                            continue;
                        }
                        let margin = skin + rest_drift;
                        if let Some(touching) = appended_pair(xi, ri, x[j], r[j], margin) {
                            contacts += u64::from(touching);
                            let mut h = [0.0; 3];
                            let key = (id[i].min(id[j]), id[i].max(id[j]));
                            if let Ok(e) = saved.binary_search_by_key(&key, |e| e.0) {
                                let s = saved[e].1;
                                h = if id[i] == key.0 {
                                    s
                                } else {
                                    [-s[0], -s[1], -s[2]]
                                };
                            }
                            row.push((c as u32, h));
                        }
                    }
                });
                row.sort_unstable_by_key(|e| e.0);
                partner.extend(row.iter().map(|e| e.0));
                if with_history {
                    history.extend(row.iter().map(|e| e.1));
                }
                let mut work = PAIR * row.len() as u64 + CONTACT * contacts + GRAIN;
                for wall in walls {
                    if let Some((overlap, _)) = wall.contact(xi, ri + skin) {
                        if overlap > skin {
                            work += WALL_CONTACT;
                        }
                    }
                }
                cost.push(work);
            }
            start.push(partner.len() as u32);
        }
        // 5. The wall lists: the others keep theirs, the movers are tested from here.
        for (near, wall) in self.near_wall.iter_mut().zip(walls) {
            sc.listed.clear();
            sc.listed.resize(n, false);
            for &i in near.iter() {
                sc.listed[i as usize] = true;
            }
            near.clear();
            near.extend((0..n).filter_map(|k| {
                let i = order[k];
                let keep = if is_mover[i] {
                    wall.contact(x[i], r[i] + skin).is_some()
                } else {
                    sc.listed[i]
                };
                keep.then_some(k as u32)
            }));
        }
        self.x_at_build.clear();
        self.x_at_build
            .extend(order.iter().map(|&i| sc.reference[i]));
        std::mem::swap(&mut self.start, &mut sc.start);
        std::mem::swap(&mut self.partner, &mut sc.partner);
        std::mem::swap(&mut self.history, &mut sc.history);
        std::mem::swap(&mut self.cost, &mut sc.cost);
        state.reorder(&self.order, walls.len(), &mut self.spare, team);
        self.appended_from = n;
        self.upkeep.refreshes += 1;
        Some(Refreshed {
            movers,
            largest_drift: rest_drift,
        })
    }

    /// Keep only the grains `keep` (ascending old indices; grain `keep[k]` becomes grain k)
    /// without a new build: the rows and partners of the kept grains renumbered, their
    /// histories, wall lists, costs and build positions with them. The order of the kept
    /// grains does not change, so every pair keeps j > i and the list stays what a build at
    /// the last build's positions would have listed for them. Returns false (nothing
    /// changed) when the list does not match the current grains; then rebuild instead.
    pub fn retain(&mut self, keep: &[usize], grains: usize) -> bool {
        if !self.valid || self.start.len() != grains + 1 || self.x_at_build.len() != grains {
            return false;
        }
        const GONE: u32 = u32::MAX;
        let new_index = &mut self.index_of_id;
        new_index.clear();
        new_index.resize(grains, GONE);
        for (k, &i) in keep.iter().enumerate() {
            new_index[i] = k as u32;
        }
        let with_history = self.history.len() == self.partner.len();
        let with_offset = !self.offset.is_empty();
        let mut out = 0usize;
        let mut new_start = Vec::with_capacity(keep.len() + 1);
        new_start.push(0u32);
        for &i in keep {
            for k in self.start[i] as usize..self.start[i + 1] as usize {
                let j = new_index[self.partner[k] as usize];
                if j != GONE {
                    // In place: `out` never passes `k`.
                    self.partner[out] = j;
                    if with_history {
                        self.history[out] = self.history[k];
                    }
                    if with_offset {
                        self.offset[out] = self.offset[k];
                    }
                    out += 1;
                }
            }
            new_start.push(out as u32);
        }
        self.partner.truncate(out);
        if with_offset {
            self.offset.truncate(out);
        }
        if with_history {
            self.history.truncate(out);
        }
        self.start = new_start;
        for near in &mut self.near_wall {
            near.retain_mut(|i| {
                *i = new_index[*i as usize];
                *i != GONE
            });
        }
        if self.appended_from != usize::MAX {
            self.appended_from = keep.partition_point(|&i| i < self.appended_from);
        }
        for (k, &i) in keep.iter().enumerate() {
            self.cost[k] = self.cost[i];
            self.x_at_build[k] = self.x_at_build[i];
        }
        self.cost.truncate(keep.len());
        self.x_at_build.truncate(keep.len());
        true
    }

    /// The new index of each old grain after the last [`NeighborList::retain`]
    /// (`u32::MAX`: removed).
    pub fn retained_index(&self) -> &[u32] {
        &self.index_of_id
    }

    /// Save the shear history of every live contact by grain ids. Call before grains are
    /// added, removed or reordered; the next [`NeighborList::rebuild`] restores it.
    pub fn stash_history(&mut self, state: &ParticleState) {
        if !self.valid || self.start.len() != state.len() + 1 || self.history.is_empty() {
            self.valid = false;
            return;
        }
        let n = state.len();
        for i in 0..n {
            for k in self.start[i] as usize..self.start[i + 1] as usize {
                let h = self.history[k];
                if h != [0.0; 3] {
                    let (a, b) = (state.id[i], state.id[self.partner[k] as usize]);
                    if a < b {
                        self.saved.push(((a, b), h));
                    } else {
                        self.saved.push(((b, a), [-h[0], -h[1], -h[2]]));
                    }
                }
            }
        }
        self.valid = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dem::walls::WallShape;
    use crate::rng::Rng;

    /// A plane at z = 0 facing up.
    fn floor() -> Wall {
        Wall {
            name: "floor".into(),
            shape: WallShape::Plane {
                point: [0.0, 0.0, 0.0],
                normal: [0.0, 0.0, 1.0],
            },
            friction: None,
        }
    }

    /// (id pairs, their histories) of a list, as sorted (smaller id, larger id) keys.
    fn pairs(l: &NeighborList, s: &ParticleState) -> Vec<((u64, u64), Vec3)> {
        let mut v = Vec::new();
        for i in 0..s.len() {
            for k in l.start[i] as usize..l.start[i + 1] as usize {
                let (a, b) = (s.id[i], s.id[l.partner[k] as usize]);
                let h = l.history.get(k).copied().unwrap_or([0.0; 3]);
                v.push(if a < b {
                    ((a, b), h)
                } else {
                    ((b, a), [-h[0], -h[1], -h[2]])
                });
            }
        }
        v.sort_by_key(|p| p.0);
        v
    }

    /// The box's longest direction is the slowest cell coordinate (the others keep their
    /// order), so cells, and the grains sorted by them, come in slices across a tube.
    #[test]
    fn a_periodic_direction_short_of_three_cells_is_refused() {
        // 5 cells along periodic z at the least size, but the box is so wide that the
        // cells grow past the cap and z keeps fewer than three: refused, naming z.
        let err = CellGrid::periodic([0.0; 3], [100.0, 100.0, 5e-3], 1e-3, [false, false, true])
            .expect_err("refused");
        assert!(err.contains("direction z"), "{err}");
        assert!(
            CellGrid::periodic([0.0; 3], [0.01, 0.01, 5e-3], 1e-3, [false, false, true]).is_ok()
        );
    }

    #[test]
    fn a_periodic_list_is_every_pair_within_reach_of_the_nearest_image() {
        // A box periodic along x (the fastest cell direction, cut cell by cell) and z (the
        // slowest), not y: the list is every pair closer than r_i + r_j + skin by the
        // nearest image, once, and each pair's shift is the one that image takes.
        let (l, skin) = ([0.012, 0.02, 0.009], 2e-4);
        let mut rng = Rng::new(5);
        let mut s = ParticleState::default();
        for id in 0..400u64 {
            let x = [
                l[0] * rng.uniform(),
                l[1] * rng.uniform(),
                l[2] * rng.uniform(),
            ];
            s.push(id, x, [0.0; 3], 1e-3, 1000.0, 0);
        }
        let grid = CellGrid::periodic([0.0; 3], l, 2e-3 + skin, [true, false, true]).expect("grid");
        assert!(
            grid.wrap[0].is_some(),
            "x fastest and periodic: {:?}",
            grid.axes
        );
        let mut list = NeighborList::default();
        list.rebuild(&mut s, &grid, skin, &[], false, &Team::new(1));
        let mut listed = Vec::new();
        for i in 0..s.len() {
            for k in list.start[i] as usize..list.start[i + 1] as usize {
                let j = list.partner[k] as usize;
                let d = sub(s.position[j], s.position[i]);
                let o = list.offset[k];
                let d2 = norm2([d[0] + o[0], d[1] + o[1], d[2] + o[2]]);
                assert!(
                    d2 < (2e-3 + skin) * (2e-3 + skin),
                    "pair {i}-{j} out of reach"
                );
                listed.push((s.id[i].min(s.id[j]), s.id[i].max(s.id[j])));
            }
        }
        listed.sort_unstable();
        let mut brute = Vec::new();
        for i in 0..s.len() {
            for j in i + 1..s.len() {
                let mut d = sub(s.position[j], s.position[i]);
                for c in [0, 2] {
                    d[c] -= l[c] * (d[c] / l[c]).round();
                }
                if norm2(d) < (2e-3 + skin) * (2e-3 + skin) {
                    brute.push((s.id[i].min(s.id[j]), s.id[i].max(s.id[j])));
                }
            }
        }
        brute.sort_unstable();
        assert!(brute.len() > 100, "{} pairs", brute.len());
        assert_eq!(listed, brute);
    }

    /// A long pipe holding grains in a few places reads (and sorts over) the cells around
    /// them only, and still lists every pair within reach, build after build, however the
    /// grains move between builds (the starts left from the previous build are stale there):
    /// against all pairs by brute force, with grains in the first and the last slice too.
    #[test]
    fn a_sparse_long_box_sorts_over_its_occupied_slices_and_misses_no_pair() {
        let (l, skin, d) = ([1.0, 0.01, 0.01], 2e-4, 2e-3);
        let grid = CellGrid::new([0.0; 3], l, d + skin);
        let mut rng = Rng::new(11);
        let mut list = NeighborList::default();
        // (The second build holds fewer grains, and its lowest cluster sits just above the
        // first one's middle cluster: a start left from the first build and read by mistake
        // would point past the grains.)
        let builds = [(600u64, [0.0, 0.31, 0.97]), (300, [0.33, 0.6, 0.998])];
        for (round, (grains, clusters)) in builds.iter().enumerate() {
            let mut s = ParticleState::default();
            for id in 0..*grains {
                let at = clusters[id as usize % 3];
                let x = [
                    (at + 0.02 * rng.uniform()).min(l[0]),
                    l[1] * rng.uniform(),
                    l[2] * rng.uniform(),
                ];
                s.push(id, x, [0.0; 3], 0.5 * d, 1000.0, 0);
            }
            list.rebuild(&mut s, &grid, skin, &[], false, &Team::new(1));
            let (from, to) = grid.cells_read(&list.cell);
            assert!(
                to - from < grid.count(),
                "round {round}: cells {from}..{to} of {}",
                grid.count()
            );
            let mut listed = Vec::new();
            for i in 0..s.len() {
                for k in list.start[i] as usize..list.start[i + 1] as usize {
                    let j = list.partner[k] as usize;
                    listed.push((s.id[i].min(s.id[j]), s.id[i].max(s.id[j])));
                }
            }
            listed.sort_unstable();
            let mut brute = Vec::new();
            for i in 0..s.len() {
                for j in i + 1..s.len() {
                    if norm2(sub(s.position[j], s.position[i])) < (d + skin) * (d + skin) {
                        brute.push((s.id[i].min(s.id[j]), s.id[i].max(s.id[j])));
                    }
                }
            }
            brute.sort_unstable();
            assert!(brute.len() > 100, "round {round}: {} pairs", brute.len());
            assert_eq!(listed, brute, "round {round}");
        }
    }

    #[test]
    fn cells_are_numbered_with_the_longest_direction_slowest() {
        let along_x = CellGrid::new([0.0; 3], [1.0, 0.01, 0.01], 2e-3);
        assert_eq!(along_x.axes, [1, 2, 0]);
        assert_eq!(along_x.dims, [5, 5, 500]);
        let along_z = CellGrid::new([0.0; 3], [0.01, 0.01, 1.0], 2e-3);
        assert_eq!(along_z.axes, [0, 1, 2]);
        let cube = CellGrid::new([0.0; 3], [0.01; 3], 2e-3);
        assert_eq!(cube.axes, [0, 1, 2], "a tie keeps z slowest");
        // The list of grains in a pipe along x is every pair within reach (brute force).
        let mut rng = Rng::new(11);
        let mut s = ParticleState::default();
        for id in 0..600u64 {
            let x = [rng.uniform(), 0.01 * rng.uniform(), 0.01 * rng.uniform()];
            s.push(id, x, [0.0; 3], 1e-3, 1000.0, 0);
        }
        let skin = 2e-4;
        let grid = CellGrid::new([0.0; 3], [1.0, 0.01, 0.01], 2e-3 + skin);
        let mut list = NeighborList::default();
        list.rebuild(&mut s, &grid, skin, &[], false, &Team::new(1));
        let listed: Vec<(u64, u64)> = pairs(&list, &s).into_iter().map(|p| p.0).collect();
        let mut brute = Vec::new();
        for i in 0..s.len() {
            for j in i + 1..s.len() {
                if norm2(sub(s.position[i], s.position[j])) < (2e-3 + skin) * (2e-3 + skin) {
                    let (a, b) = (s.id[i], s.id[j]);
                    brute.push((a.min(b), a.max(b)));
                }
            }
        }
        brute.sort_unstable();
        assert!(!brute.is_empty());
        assert_eq!(listed, brute);
        // Two points a cell apart along the pipe: their cells a whole slice (5 × 5) apart.
        let (a, b) = ([0.5, 0.005, 0.005], [0.5021, 0.005, 0.005]);
        let (ia, ib) = (
            along_x.index(along_x.coord(a)),
            along_x.index(along_x.coord(b)),
        );
        assert_eq!(ib - ia, 25);
    }

    /// Grains fed between builds join the list by `append`, and when the drifts call for a
    /// build the far-drifted few are listed again by `refresh_movers` (their histories
    /// kept by id), and no touching pair and no grain touching the wall goes unlisted
    /// until the two largest drifts add up to the skin: grains of a long box moving at
    /// velocities of their own that turn now and then (every 25th ten times faster, so the
    /// drift D of the reach matters), new grains pushed at random every third round (half
    /// of them within a grain of an old one), some grains leaving by `retain` between
    /// feeds, every round checked against all pairs by brute force, over several builds.
    #[test]
    fn appended_grains_miss_no_contact_until_a_build_is_due() {
        let mut rng = Rng::new(23);
        let walls = vec![floor()];
        let nw = walls.len();
        let (l, skin, r_max) = ([0.06, 0.01, 0.01], 3e-4, 1e-3);
        let grid = CellGrid::new([0.0; 3], l, 2.0 * r_max + skin);
        let team = Team::new(1);
        let mut s = ParticleState::default();
        let mut next_id = 0u64;
        let mut push_random = |s: &mut ParticleState, rng: &mut Rng, near: Option<Vec3>| {
            let x = match near {
                Some(c) => std::array::from_fn(|k| c[k] + 2.0 * r_max * (rng.uniform() - 0.5)),
                None => std::array::from_fn(|k| l[k] * rng.uniform()),
            };
            let r = r_max * (0.8 + 0.2 * rng.uniform());
            s.push(next_id, x, [0.0; 3], r, 1000.0, nw);
            next_id += 1;
        };
        for _ in 0..300 {
            push_random(&mut s, &mut rng, None);
        }
        let mut list = NeighborList::default();
        list.rebuild(&mut s, &grid, skin, &walls, true, &team);
        let (mut checked_contacts, mut appended_pairs, mut builds) = (0usize, 0usize, 1);
        let (mut refreshes, mut triggers) = (0, 0);
        for round in 0..240 {
            // Drifts since each grain's reference; a build when the two largest cover the skin.
            let reference = list.reference_positions();
            let mut drifts: Vec<Real> = (0..s.len())
                .map(|i| norm2(sub(s.position[i], reference[i])).sqrt())
                .collect();
            drifts.sort_by(|a, b| b.total_cmp(a));
            if drifts[0] + drifts[1] > skin {
                // The far-drifted few listed again if they are few (their histories by id
                // kept: every listed pair carries one made of its ids), a build otherwise.
                let mark = |list: &mut NeighborList, s: &ParticleState| {
                    for i in 0..s.len() {
                        for k in list.start[i] as usize..list.start[i + 1] as usize {
                            let (a, b) = (s.id[i], s.id[list.partner[k] as usize]);
                            let h = [a.min(b) as Real, a.max(b) as Real, 1.0];
                            list.history[k] = if a < b { h } else { h.map(|c| -c) };
                        }
                    }
                };
                mark(&mut list, &s);
                let before = pairs(&list, &s);
                // (Every third time a build anyway, so builds after appends are tried too.)
                triggers += 1;
                if triggers % 3 != 0
                    && list
                        .refresh_movers(&mut s, &grid, skin, r_max, &walls, skin / 4.0, 8, &team)
                        .is_some()
                {
                    refreshes += 1;
                    for ((a, b), h) in pairs(&list, &s) {
                        let was = before.binary_search_by_key(&(a, b), |e| e.0).is_ok();
                        let expected = if was {
                            [a as Real, b as Real, 1.0]
                        } else {
                            [0.0; 3]
                        };
                        assert_eq!(h, expected, "round {round}: history of ({a}, {b})");
                    }
                    let reference = list.reference_positions();
                    assert!((0..s.len())
                        .all(|i| norm2(sub(s.position[i], reference[i])).sqrt() <= skin / 4.0));
                } else {
                    list.rebuild(&mut s, &grid, skin, &walls, true, &team);
                    builds += 1;
                    continue;
                }
            }
            // Every touching pair listed (once), every grain touching the floor near it.
            let listed: Vec<(u64, u64)> = pairs(&list, &s).into_iter().map(|p| p.0).collect();
            assert!(
                listed.windows(2).all(|w| w[0] != w[1]),
                "round {round}: a pair twice"
            );
            for i in 0..s.len() {
                for j in i + 1..s.len() {
                    let touch = s.radius[i] + s.radius[j];
                    if norm2(sub(s.position[j], s.position[i])) < touch * touch {
                        let key = (s.id[i].min(s.id[j]), s.id[i].max(s.id[j]));
                        assert!(
                            listed.binary_search(&key).is_ok(),
                            "round {round}: contact {key:?} not listed"
                        );
                        checked_contacts += 1;
                    }
                }
                if walls[0].contact(s.position[i], s.radius[i]).is_some() {
                    assert!(
                        list.near_wall[0].contains(&(i as u32)),
                        "round {round}: grain {} on the floor not listed",
                        s.id[i]
                    );
                }
            }
            // Some grains leave (a third of the rounds), some are fed (another third).
            if round % 3 == 1 {
                let keep: Vec<usize> = (0..s.len()).filter(|_| rng.uniform() > 0.02).collect();
                assert!(list.retain(&keep, s.len()));
                s.permute(&keep, nw);
            } else if round % 3 == 2 {
                assert!(list.can_append(s.len(), &grid));
                let first = s.len();
                for k in 0..8 {
                    let near =
                        (k % 2 == 0).then(|| s.position[(rng.uniform() * first as Real) as usize]);
                    push_random(&mut s, &mut rng, near);
                }
                appended_pairs += list.append(&s, first, &grid, skin, r_max, &walls, drifts[0]);
            }
            // Everyone moves on at a velocity of its own (drawn from its id and the current
            // stretch of 7 rounds, so it turns now and then); every 25th grain ten times as
            // fast.
            for i in 0..s.len() {
                let fast = s.id[i] % 25 == 0;
                let step = if fast { 4e-5 } else { 4e-6 };
                let mut own = Rng::new(s.id[i] * 1000 + round / 7);
                for c in 0..3 {
                    s.position[i][c] += step * (2.0 * own.uniform() - 1.0);
                }
            }
        }
        assert!(builds >= 3, "{builds} builds");
        assert!(refreshes >= 10, "{refreshes} refreshes");
        assert!(list.upkeep.appends >= 40, "{} appends", list.upkeep.appends);
        assert!(appended_pairs > 500, "{appended_pairs} pairs appended");
        assert!(
            checked_contacts > 10_000,
            "{checked_contacts} contacts checked"
        );
    }

    /// The drift D in an appended grain's reach: an old grain drifted D away from a spot
    /// before a new grain is appended a skin and half a D from it (out of a build's reach,
    /// r_a + r_j + skin); the old one then moves 2 D back towards the new one, which moves
    /// 1.25 D towards it, and they touch, while their drifts (D and 1.25 D) add up to less
    /// than the skin: no build is due, so the pair must have been listed.
    #[test]
    fn an_appended_grain_lists_partners_within_the_drift_of_the_reach() {
        let (skin, r, drift) = (3e-4, 1e-3, 1.2e-4);
        let l = [0.02, 0.01, 0.01];
        let grid = CellGrid::new([0.0; 3], l, 2.0 * r + skin);
        let mut s = ParticleState::default();
        s.push(0, [0.0100, 0.005, 0.005], [0.0; 3], r, 1000.0, 0);
        let mut list = NeighborList::default();
        list.rebuild(&mut s, &grid, skin, &[], true, &Team::new(1));
        s.position[0][0] -= drift;
        let gap = skin + 0.5 * drift;
        s.push(
            1,
            [s.position[0][0] + 2.0 * r + gap, 0.005, 0.005],
            [0.0; 3],
            r,
            1000.0,
            0,
        );
        assert!(list.can_append(1, &grid));
        assert_eq!(list.append(&s, 1, &grid, skin, r, &[], drift), 1);
        s.position[0][0] += 2.0 * drift;
        s.position[1][0] -= 1.25 * drift;
        assert!(drift + 1.25 * drift < skin, "a build would be due");
        let d = s.position[1][0] - s.position[0][0];
        assert!(d < 2.0 * r, "not in contact: {d}");
        assert_eq!(
            list.partner[list.start[1] as usize..list.start[2] as usize],
            [0]
        );
    }

    /// The cells searched for a row listed between builds cover the whole reach: the
    /// partner's reference placed at every tenth of a cell in turn, so that some lie just
    /// across a cell face from a search box narrowed by the skin (which the cases above,
    /// with both grains inside one cell's span, would not notice), an appended grain and a
    /// refreshed mover each list a partner a skin and half a D away.
    #[test]
    fn rows_listed_between_builds_search_across_cell_faces() {
        let (skin, r, drift) = (3e-4, 1e-3, 4e-5);
        let cell = 2.0 * r + skin;
        let grid = CellGrid::new([0.0; 3], [0.03, 0.01, 0.01], cell);
        for tenth in 0..10 {
            let x0 = 0.0092 + 0.1 * tenth as Real * cell;
            // Appended.
            let mut s = ParticleState::default();
            s.push(0, [x0, 0.005, 0.005], [0.0; 3], r, 1000.0, 0);
            let mut list = NeighborList::default();
            list.rebuild(&mut s, &grid, skin, &[], true, &Team::new(1));
            s.position[0][0] -= drift;
            let x1 = s.position[0][0] + 2.0 * r + skin + 0.5 * drift;
            s.push(1, [x1, 0.005, 0.005], [0.0; 3], r, 1000.0, 0);
            assert_eq!(list.append(&s, 1, &grid, skin, r, &[], drift), 1, "x0 {x0}");
            // Refreshed: a far grain jumps to the same place.
            let mut s = ParticleState::default();
            s.push(0, [x0, 0.005, 0.005], [0.0; 3], r, 1000.0, 0);
            s.push(1, [0.025, 0.005, 0.005], [0.0; 3], r, 1000.0, 0);
            let mut list = NeighborList::default();
            list.rebuild(&mut s, &grid, skin, &[], true, &Team::new(1));
            let (slow, fast) = if s.id[0] == 0 { (0, 1) } else { (1, 0) };
            s.position[slow][0] -= drift;
            s.position[fast][0] = s.position[slow][0] + 2.0 * r + skin + 0.5 * drift;
            let refreshed =
                list.refresh_movers(&mut s, &grid, skin, r, &[], skin / 4.0, 1, &Team::new(1));
            assert_eq!(refreshed.map(|r| r.movers), Some(1), "x0 {x0}");
            assert_eq!(
                list.partner.len(),
                1,
                "x0 {x0}: the mover lists its partner"
            );
        }
    }

    /// The drift D of the others in a refreshed mover's reach: as for an appended grain
    /// (above), an old grain drifted D (under the mover threshold) away before a far-drifted
    /// grain is listed again a skin and half a D from it; they then close on each other and
    /// touch before their drifts add up to the skin.
    #[test]
    fn a_refreshed_mover_lists_partners_within_the_drift_of_the_others() {
        let (skin, r) = (3e-4, 1e-3);
        let (threshold, drift) = (skin / 4.0, 7e-5);
        let grid = CellGrid::new([0.0; 3], [0.03, 0.01, 0.01], 2.0 * r + skin);
        let mut s = ParticleState::default();
        s.push(0, [0.010, 0.005, 0.005], [0.0; 3], r, 1000.0, 0);
        s.push(1, [0.020, 0.005, 0.005], [0.0; 3], r, 1000.0, 0);
        let mut list = NeighborList::default();
        list.rebuild(&mut s, &grid, skin, &[], true, &Team::new(1));
        assert_eq!(list.partner.len(), 0);
        let (slow, fast) = if s.id[0] == 0 { (0, 1) } else { (1, 0) };
        s.position[slow][0] -= drift;
        s.position[fast][0] = s.position[slow][0] + 2.0 * r + skin + 0.5 * drift;
        let refreshed =
            list.refresh_movers(&mut s, &grid, skin, r, &[], threshold, 1, &Team::new(1));
        assert_eq!(refreshed.map(|r| r.movers), Some(1));
        // The mover last; the slow grain moves 2 D back, the mover skin − 1.2 D towards it.
        let (slow, fast) = (0, 1);
        assert_eq!(s.id[fast], 1);
        s.position[slow][0] += 2.0 * drift;
        let step = skin - 1.2 * drift;
        s.position[fast][0] -= step;
        assert!(drift + step < skin, "a build would be due");
        assert!(
            s.position[fast][0] - s.position[slow][0] < 2.0 * r,
            "not in contact"
        );
        assert_eq!(
            list.partner[list.start[1] as usize..list.start[2] as usize],
            [0]
        );
    }

    /// Grains leaving between builds: the list cut down by `retain` is the list a build at
    /// the last build's positions lists for the grains that stay (the same pairs, by id, with
    /// the same histories), and so are the wall lists and the build positions.
    #[test]
    fn retain_equals_a_build_of_the_grains_that_stay() {
        let mut rng = Rng::new(7);
        let walls = vec![floor()];
        let mut s = ParticleState::default();
        for id in 0..400u64 {
            let x = std::array::from_fn(|_| 0.02 * rng.uniform());
            s.push(id, x, [0.0; 3], 1e-3, 1000.0, walls.len());
        }
        let (skin, team) = (3e-4, Team::new(1));
        let grid = CellGrid::new([0.0; 3], [0.02; 3], 2e-3 + skin);
        let mut list = NeighborList::default();
        list.rebuild(&mut s, &grid, skin, &walls, true, &team);
        // Histories on every pair, distinct, so that a misplaced one shows.
        for (k, h) in list.history.iter_mut().enumerate() {
            *h = [k as Real, 1.0, -(k as Real)];
        }
        // (After the build the grains lie in cell order: pick them by id.)
        let keep: Vec<usize> = (0..s.len()).filter(|&i| s.id[i] % 3 != 1).collect();
        let mut kept = s.clone();
        kept.permute(&keep, walls.len());
        let expected: Vec<((u64, u64), Vec3)> = pairs(&list, &s)
            .into_iter()
            .filter(|((a, b), _)| a % 3 != 1 && b % 3 != 1)
            .collect();
        let ids_of = |l: &[u32], st: &ParticleState| {
            let mut v: Vec<u64> = l.iter().map(|&i| st.id[i as usize]).collect();
            v.sort_unstable();
            v
        };
        let near_expected: Vec<u64> = ids_of(&list.near_wall[0], &s)
            .into_iter()
            .filter(|id| id % 3 != 1)
            .collect();
        assert!(list.retain(&keep, s.len()));
        assert_eq!(list.start.len(), kept.len() + 1);
        assert_eq!(pairs(&list, &kept), expected);
        assert_eq!(ids_of(&list.near_wall[0], &kept), near_expected);
        assert_eq!(list.reference_positions(), &kept.position[..]);
        // A fresh build of the grains that stay, where they stood: the same pairs.
        let mut fresh = NeighborList::default();
        let mut again = kept.clone();
        fresh.rebuild(&mut again, &grid, skin, &walls, false, &team);
        let unkeyed = |v: Vec<((u64, u64), Vec3)>| v.into_iter().map(|p| p.0).collect::<Vec<_>>();
        assert_eq!(unkeyed(pairs(&fresh, &again)), unkeyed(expected));
        // A list that no longer matches the grains refuses (and changes nothing).
        assert!(!list.retain(&[0, 1], kept.len() + 5));
    }
}
