//! The conveyor inlet (`inlet.mode = "conveyor"`): a column of grains packed at the inlet's
//! porosity is pushed into the tube at the feed velocity, and every grain of it is held to
//! that motion until its centre leaves the inlet slab. The mass flow is then what the scene
//! asks for whatever the bed above presses with, as in the seeds' simulations (seed 000 §4:
//! "particles are injected from the bottom at a constant mass flow rate", at porosity 0.51
//! and 0.04 m/s, Fig. 10–11), which the slab inlet (random placement where there is room)
//! cannot do: random sequential placement saturates near 38 % solids, and a bed resting on
//! the slab blocks it.
//!
//! The column is made below the tube in blocks of [`BLOCK_DIAMETERS`] grain diameters, each
//! packed without overlap against the block above it by pushing overlapping pairs apart
//! (the grains start at random; a loose random packing results, not a lattice). Its grains
//! enter the tube when their centre is one radius past the inlet end. This module holds the
//! column's bookkeeping, engine-independent; the engine holds the grains in the slab to the
//! feed motion and releases them.

use super::config::{DemConfig, InletConfig, TubeGeometry};
use super::inlet::draw_radius;
use super::placement::perpendicular_basis;
use super::vec3::{add, dot, norm2, scale, sub};
use crate::rng::Rng;
use crate::{Real, Vec3};

/// Length of one packed block of the column, in largest grain diameters.
pub const BLOCK_DIAMETERS: Real = 4.0;

/// Largest overlap left between two column grains, in smallest grain diameters: 1e-4 d is
/// 0.14 µm for the seeds' 1.4 mm beads, a tenth of the overlap a resting grain carries
/// under its own weight at the scene's contact stiffness.
pub const PACK_TOLERANCE: Real = 1e-4;

/// Push-apart sweeps before the grains of a block that still overlap are left out.
const MAX_SWEEPS: usize = 20_000;

/// Blocks made before the run, deep enough to show a porosity the tube cannot hold.
const PRIME_BLOCKS: Real = 6.0;

/// One column grain not yet in the tube: axial coordinate in the column's frame `a` (it is
/// at s = travelled + a along the axis), cross-section coordinates `u`, `v` along the
/// tube's perpendicular basis, radius `r`; m.
type ColumnGrain = [Real; 4];

/// The column's state: carried in checkpoints, so that a resumed run feeds the same grains.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Conveyor {
    /// Distance the column has moved into the tube, m.
    travelled: Real,
    /// Grains made but not yet in the tube.
    pending: Vec<ColumnGrain>,
    /// Lowest centre coordinate the column has been made down to (column frame), m.
    bottom: Real,
    /// Fraction of a grain the blocks made so far owe (grains per block are rate × length /
    /// velocity, rounded with the remainder carried, so the mean is exact).
    owed: Real,
    /// Radii of grains a block could not pack (still overlapping after [`MAX_SWEEPS`]):
    /// the next block packs them first, so the column keeps its count per length and a
    /// jam costs a grain's position, not the grain.
    carried: Vec<Real>,
    /// Blocks that could not pack all their grains.
    jammed_blocks: usize,
    /// Grains of the column that could not be packed or that met a grain already in the
    /// tube where they were to enter: never fed (the summary's inlet backlog).
    pub unplaced: u64,
    /// The engine has taken the grains in the slab into the column (at the first feed).
    pub started: bool,
    /// Ids of the grains in the tube the engine holds to the feed motion, ascending.
    held: Vec<u64>,
}

/// What one feed of the conveyor asks of the engine (see [`Conveyor::feed`]).
#[derive(Debug, Default)]
pub struct ConveyorFeed {
    /// Indices of grains to hold to the feed motion (zero spin, the feed velocity, deaf to
    /// forces) from now.
    pub hold: Vec<usize>,
    /// Indices of held grains to let go (they answer forces again from the feed velocity).
    pub release: Vec<usize>,
    /// New grains (centre, radius), to be added held at the feed velocity.
    pub enter: Vec<(Vec3, Real)>,
}

/// A block of the column packed at its porosity.
struct Block {
    grains: Vec<ColumnGrain>,
    /// Radii of the grains that still overlapped after [`MAX_SWEEPS`] (left out, carried
    /// to the next block).
    dropped: Vec<Real>,
}

/// Most grains the column may carry from block to block before the excess is given up as
/// unplaced: a block's worth. A column that carries more than this keeps failing to pack
/// at its porosity; [`Conveyor::primed`] refuses such a scene before the run.
fn carry_limit(cfg: &DemConfig, inlet: &InletConfig) -> usize {
    (inlet.rate * block_length(cfg) / inlet.velocity).ceil() as usize
}

impl Conveyor {
    /// A column ready to feed: the blocks down to one block below the inlet end are made.
    /// Fails (with the reason) when the first block cannot be packed at the inlet's
    /// porosity in this tube.
    pub fn primed(cfg: &DemConfig, rng: &mut Rng) -> Result<Self, String> {
        let mut c = Conveyor::default();
        let (Some(inlet), Some(tube)) = (cfg.inlet, cfg.tube) else {
            return Ok(c);
        };
        // Make the column a few blocks deep: a porosity the tube cannot hold shows as
        // grains pushed out below the stretch their count was made for.
        let length = block_length(cfg);
        let mut blocks = 0;
        while c.bottom > -PRIME_BLOCKS * length {
            let block = c.make_block(cfg, &inlet, &tube, rng);
            c.push_block(block, cfg);
            blocks += 1;
        }
        // A jam now and then is carried to the next block; a column that still carries
        // grains after every block (or spreads below its stretch) is denser than the tube
        // packs.
        let carried = c.carried.len();
        let lowest = c
            .pending
            .iter()
            .map(|g| g[0])
            .fold(Real::INFINITY, Real::min);
        let spill = c.bottom - lowest;
        if c.jammed_blocks == blocks || carried > carry_limit(cfg, &inlet) / 4 || spill > length {
            return Err(format!(
                "a column at porosity {:.3} cannot be packed in this tube: {} of {blocks} \
                 blocks of {length:.3e} m jammed ({carried} grains still overlapped after \
                 {MAX_SWEEPS} push-apart sweeps at the end) and the grains spread {spill:.3e} \
                 m below their stretch (push-apart packings of spheres in a tube {:.1} grain \
                 diameters wide jam near porosity 0.5); lower `inlet.mass_flow` or raise \
                 `inlet.velocity`",
                inlet.porosity,
                c.jammed_blocks,
                tube.radius / cfg.radius_max,
            ));
        }
        c.extend(cfg, rng);
        Ok(c)
    }

    /// Move the column `distance` m further in and make blocks as needed.
    pub fn advance(&mut self, cfg: &DemConfig, distance: Real, rng: &mut Rng) {
        self.travelled += distance;
        self.extend(cfg, rng);
    }

    /// The grains whose centre is now at least one radius inside the tube, as (centre,
    /// radius), removed from the column. A grain that would overlap one of `near_inlet`
    /// (grains already in the tube near its inlet end: centre, radius) by more than the
    /// packing's tolerance is left out and counted in [`Conveyor::unplaced`].
    pub fn enter(&mut self, cfg: &DemConfig, near_inlet: &[(Vec3, Real)]) -> Vec<(Vec3, Real)> {
        let Some(tube) = cfg.tube else {
            return Vec::new();
        };
        let (e1, e2) = perpendicular_basis(tube.axis);
        let slack = 2.0 * PACK_TOLERANCE * 2.0 * cfg.radius_min;
        let travelled = self.travelled;
        let mut entered: Vec<(Vec3, Real)> = Vec::new();
        let mut unplaced = 0;
        self.pending.retain(|&[a, u, v, r]| {
            if travelled + a < r {
                return true;
            }
            let x = add(
                add(
                    add(tube.origin, scale(tube.axis, travelled + a)),
                    scale(e1, u),
                ),
                scale(e2, v),
            );
            let blocked = near_inlet.iter().any(|&(y, ry)| {
                let reach = r + ry - slack;
                norm2(sub(x, y)) < reach * reach
            });
            if blocked {
                unplaced += 1;
            } else {
                entered.push((x, r));
            }
            false
        });
        self.unplaced += unplaced;
        entered
    }

    /// Make blocks until the column reaches one block below the inlet end.
    fn extend(&mut self, cfg: &DemConfig, rng: &mut Rng) {
        let (Some(inlet), Some(tube)) = (cfg.inlet, cfg.tube) else {
            return;
        };
        while self.travelled + self.bottom > -block_length(cfg) {
            let block = self.make_block(cfg, &inlet, &tube, rng);
            self.push_block(block, cfg);
            let limit = carry_limit(cfg, &inlet);
            if self.carried.len() > limit {
                self.unplaced += (self.carried.len() - limit) as u64;
                self.carried.truncate(limit);
            }
        }
    }

    fn push_block(&mut self, block: Block, cfg: &DemConfig) {
        self.pending.extend(block.grains);
        if !block.dropped.is_empty() {
            self.jammed_blocks += 1;
        }
        self.carried = block.dropped;
        self.bottom -= block_length(cfg);
    }

    /// The next block: centres in [bottom − L, bottom], packed against the column's
    /// grains within reach above it.
    fn make_block(
        &mut self,
        cfg: &DemConfig,
        inlet: &InletConfig,
        tube: &TubeGeometry,
        rng: &mut Rng,
    ) -> Block {
        let length = block_length(cfg);
        self.owed += inlet.rate * length / inlet.velocity;
        let count = self.owed.floor();
        self.owed -= count;
        let mut radii = std::mem::take(&mut self.carried);
        radii.extend((0..count as usize).map(|_| draw_radius(cfg, rng)));
        let (hi, lo) = (self.bottom, self.bottom - length);
        let reach = hi + 2.0 * cfg.radius_max;
        let above: Vec<ColumnGrain> = self
            .pending
            .iter()
            .copied()
            .filter(|g| g[0] - g[3] < reach)
            .collect();
        let shape = Section {
            radius: tube.radius,
            slab_half: tube.slab_half,
        };
        let tolerance = PACK_TOLERANCE * 2.0 * cfg.radius_min;
        let (grains, overlapping) = pack(
            &radii,
            lo,
            hi,
            &shape,
            &above,
            tolerance,
            CANDIDATE_SKIN,
            rng,
        );
        let (kept, dropped): (Vec<_>, Vec<_>) =
            grains.into_iter().zip(overlapping).partition(|(_, o)| !o);
        Block {
            grains: kept.into_iter().map(|(g, _)| g).collect(),
            dropped: dropped.into_iter().map(|(g, _)| g[3]).collect(),
        }
    }

    /// One feed, `elapsed` s after the last, at `time` s, for any engine: which grains to
    /// hold to the feed motion from now, which to release, and the column's grains that came
    /// one radius into the tube (centre, radius; the engine adds them held and reports
    /// their ids with [`Conveyor::hold`]). `ids`, `positions`, `radii`: every grain the
    /// engine has; `movable(i)`: grain i answers forces (frozen grains are never taken).
    ///
    /// At the first feed the grains already in the slab (a tube filled by another run) join
    /// the column; a held grain whose centre passed the slab is released; when the feed stops
    /// (`inlet.until`) every held grain is. The column moves by the distance its grains did.
    #[allow(clippy::too_many_arguments)]
    pub fn feed(
        &mut self,
        cfg: &DemConfig,
        time: Real,
        elapsed: Real,
        ids: &[u64],
        positions: &[Vec3],
        radii: &[Real],
        movable: impl Fn(usize) -> bool,
        rng: &mut Rng,
    ) -> ConveyorFeed {
        let mut out = ConveyorFeed::default();
        let (Some(inlet), Some(tube)) = (cfg.inlet, cfg.tube) else {
            return out;
        };
        let slab = inlet.slab_length;
        if !self.started {
            for (i, &x) in positions.iter().enumerate() {
                if movable(i) && axial(&tube, x) < slab {
                    out.hold.push(i);
                    self.hold(ids[i]);
                }
            }
            self.started = true;
        }
        let stopped = inlet.until.is_some_and(|u| time > u);
        // One pass over the grains (every FEED_STRIDE steps, all of them): the held ones
        // past the slab, and those near the inlet end the entering grains must not overlap.
        let reach = 4.0 * cfg.radius_max;
        let mut near: Vec<(Vec3, Real)> = Vec::new();
        for (i, &x) in positions.iter().enumerate() {
            let a = axial(&tube, x);
            if (stopped || a > slab) && self.release(ids[i]) {
                out.release.push(i);
            }
            if !stopped && a < reach {
                near.push((x, radii[i]));
            }
        }
        if !stopped {
            self.advance(cfg, inlet.velocity * elapsed, rng);
            out.enter = self.enter(cfg, &near);
        }
        out
    }

    /// Note that the engine holds grain `id` to the feed motion.
    pub fn hold(&mut self, id: u64) {
        if let Err(k) = self.held.binary_search(&id) {
            self.held.insert(k, id);
        }
    }

    /// Whether grain `id` was held; it is not any more.
    pub fn release(&mut self, id: u64) -> bool {
        // Every feed asks this of every grain past the slab: most are older than any held
        // grain, and the range test answers them without the search.
        match (self.held.first(), self.held.last()) {
            (Some(&lo), Some(&hi)) if (lo..=hi).contains(&id) => {}
            _ => return false,
        }
        match self.held.binary_search(&id) {
            Ok(k) => {
                self.held.remove(k);
                true
            }
            Err(_) => false,
        }
    }

    /// Ids of the grains held to the feed motion, ascending.
    pub fn held(&self) -> &[u64] {
        &self.held
    }

    /// Whether grain `id` is held to the feed motion.
    pub fn holds(&self, id: u64) -> bool {
        self.held.binary_search(&id).is_ok()
    }

    /// Grains made and not yet in the tube (carried ones included).
    pub fn pending(&self) -> usize {
        self.pending.len() + self.carried.len()
    }
}

/// Length of one block of the column, m.
fn block_length(cfg: &DemConfig) -> Real {
    BLOCK_DIAMETERS * 2.0 * cfg.radius_max
}

/// The tube's open cross-section.
struct Section {
    radius: Real,
    slab_half: Option<Real>,
}

impl Section {
    /// Put a centre (u, v) of a grain of radius r back inside.
    fn project(&self, r: Real, u: &mut Real, v: &mut Real) {
        let room = self.radius - r;
        let d2 = *u * *u + *v * *v;
        if d2 > room * room {
            let f = room / d2.sqrt();
            *u *= f;
            *v *= f;
        }
        if let Some(h) = self.slab_half {
            *u = u.clamp(-(h - r), h - r);
        }
    }

    /// A uniformly random centre of a grain of radius r.
    fn sample(&self, r: Real, rng: &mut Rng) -> (Real, Real) {
        let room = self.radius - r;
        let half_u = self.slab_half.map_or(room, |h| (h - r).min(room));
        loop {
            let u = rng.range(-half_u, half_u);
            let v = rng.range(-room, room);
            if u * u + v * v <= room * room {
                return (u, v);
            }
        }
    }
}

/// Grains of `radii` started at random with centres in a ∈ [lo, hi] inside `section`,
/// pushed apart pair by pair (each by half the overlap, against a `fixed` grain above by
/// all of it) and back inside until no overlap exceeds `tolerance` or [`MAX_SWEEPS`] pass:
/// the grains and, per grain, whether it still overlaps. Only a ≤ hi holds them along the
/// axis: a grain pushed below lo stays there (the next block packs against it), so no
/// layer of centres gathers on a plane at each block's end and the column's density is
/// its count per length. Each sweep tests the [`Candidates`] within `candidate_skin`
/// smallest diameters ([`CANDIDATE_SKIN`]; infinite: every pair).
#[allow(clippy::too_many_arguments)]
fn pack(
    radii: &[Real],
    lo: Real,
    hi: Real,
    section: &Section,
    fixed: &[ColumnGrain],
    tolerance: Real,
    candidate_skin: Real,
    rng: &mut Rng,
) -> (Vec<ColumnGrain>, Vec<bool>) {
    let mut g: Vec<ColumnGrain> = radii
        .iter()
        .map(|&r| {
            let (u, v) = section.sample(r, rng);
            [rng.range(lo, hi), u, v, r]
        })
        .collect();
    let n = g.len();
    // Pushing a little past contact settles a packing in fewer sweeps.
    let over = 1.0 + 1e-3;
    let separate = |p: &ColumnGrain, q: &ColumnGrain| -> Option<(Vec3, Real)> {
        let d = [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
        let reach = p[3] + q[3];
        let dist2 = norm2(d);
        if dist2 >= (reach - tolerance).powi(2) {
            return None;
        }
        let dist = dist2.sqrt();
        let normal = if dist > 0.0 {
            scale(d, 1.0 / dist)
        } else {
            [1.0, 0.0, 0.0]
        };
        Some((normal, reach - dist))
    };
    let confine = |p: &mut ColumnGrain| {
        p[0] = p[0].min(hi);
        let (mut u, mut v) = (p[1], p[2]);
        section.project(p[3], &mut u, &mut v);
        p[1] = u;
        p[2] = v;
    };
    // Jacobi sweeps (every push of a sweep from the positions at its start, then all at
    // once): pushing pair by pair in place cycles where grains crowd against the wall.
    // Each sweep tests only the listed candidates, in the order a sweep over all pairs
    // takes them, so its sums (and the packing) are the same bit for bit.
    let skin = candidate_skin * 2.0 * radii.iter().copied().fold(Real::INFINITY, Real::min);
    let mut near = Candidates::default();
    let mut shift = vec![[0.0; 3]; n];
    for _ in 0..MAX_SWEEPS {
        if near.stale(&g, skin) {
            near.build(&g, fixed, skin);
        }
        let mut clean = true;
        shift.iter_mut().for_each(|d| *d = [0.0; 3]);
        for i in 0..n {
            for &f in near.fixed_of(i) {
                if let Some((normal, depth)) = separate(&g[i], &fixed[f as usize]) {
                    clean = false;
                    shift[i] = add(shift[i], scale(normal, depth * over));
                }
            }
            for &j in near.partners_of(i) {
                let j = j as usize;
                if let Some((normal, depth)) = separate(&g[i], &g[j]) {
                    clean = false;
                    let half = scale(normal, 0.5 * depth * over);
                    shift[i] = add(shift[i], half);
                    shift[j] = sub(shift[j], half);
                }
            }
        }
        if clean {
            return (g, vec![false; n]);
        }
        for (p, d) in g.iter_mut().zip(&shift) {
            *p = [p[0] + d[0], p[1] + d[1], p[2] + d[2], p[3]];
            confine(p);
        }
    }
    // Flag grains greedily until the rest are clear of each other and the fixed ones.
    let mut out = vec![false; n];
    for i in 0..n {
        let hits = fixed.iter().any(|f| separate(&g[i], f).is_some())
            || (0..i).any(|j| !out[j] && separate(&g[i], &g[j]).is_some());
        out[i] = hits;
    }
    (g, out)
}

/// Candidates' skin, in smallest grain diameters: wide enough that a block settling by
/// small pushes keeps its list for many sweeps, narrow enough that the list holds a
/// grain's touching neighbours and few more (~10 per grain at the column's porosity).
const CANDIDATE_SKIN: Real = 0.2;

/// The pairs a push-apart sweep must test: every pair of block grains, and every block
/// grain with a fixed grain, closer than their radii plus a skin at the positions of the
/// last build, by ascending index (the order of a sweep over all pairs). Rebuilt when
/// the two largest moves since add up to the skin: a pair not listed was a skin apart
/// then and cannot overlap yet. A jammed block sweeps 20 000 times; a sweep over the
/// list tests ~10 pairs per grain instead of every pair (~100 per grain).
#[derive(Default)]
struct Candidates {
    /// Per block grain i, its fixed candidates are `fixed[fixed_start[i]..fixed_start[i + 1]]`.
    fixed_start: Vec<u32>,
    fixed: Vec<u32>,
    /// Per block grain i, its partners j > i are `partner[start[i]..start[i + 1]]`.
    start: Vec<u32>,
    partner: Vec<u32>,
    /// Block grains' centres at the last build.
    at_build: Vec<Vec3>,
}

impl Candidates {
    /// Whether a grain may have come into reach of one not listed with it.
    fn stale(&self, g: &[ColumnGrain], skin: Real) -> bool {
        if self.at_build.len() != g.len() {
            return true;
        }
        let (mut first, mut second) = (0.0, 0.0);
        for (p, q) in g.iter().zip(&self.at_build) {
            let moved = norm2([p[0] - q[0], p[1] - q[1], p[2] - q[2]]).sqrt();
            if moved > first {
                second = first;
                first = moved;
            } else if moved > second {
                second = moved;
            }
        }
        first + second >= skin
    }

    fn build(&mut self, g: &[ColumnGrain], fixed: &[ColumnGrain], skin: Real) {
        let within = |p: &ColumnGrain, q: &ColumnGrain| {
            let reach = p[3] + q[3] + skin;
            norm2([p[0] - q[0], p[1] - q[1], p[2] - q[2]]) < reach * reach
        };
        let n = g.len();
        self.fixed_start.clear();
        self.fixed.clear();
        self.start.clear();
        self.partner.clear();
        self.fixed_start.push(0);
        self.start.push(0);
        for i in 0..n {
            self.fixed.extend(
                (0..fixed.len())
                    .filter(|&f| within(&g[i], &fixed[f]))
                    .map(|f| f as u32),
            );
            self.fixed_start.push(self.fixed.len() as u32);
            self.partner.extend(
                (i + 1..n)
                    .filter(|&j| within(&g[i], &g[j]))
                    .map(|j| j as u32),
            );
            self.start.push(self.partner.len() as u32);
        }
        self.at_build.clear();
        self.at_build.extend(g.iter().map(|p| [p[0], p[1], p[2]]));
    }

    fn fixed_of(&self, i: usize) -> &[u32] {
        &self.fixed[self.fixed_start[i] as usize..self.fixed_start[i + 1] as usize]
    }

    fn partners_of(&self, i: usize) -> &[u32] {
        &self.partner[self.start[i] as usize..self.start[i + 1] as usize]
    }
}

/// The axial position of `x` along the tube, m.
pub fn axial(tube: &TubeGeometry, x: Vec3) -> Real {
    dot(sub(x, tube.origin), tube.axis)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;

    fn vertical(set: &[&str]) -> DemConfig {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let mut set: Vec<String> = set.iter().map(|s| s.to_string()).collect();
        set.push("inlet.mode=\"conveyor\"".into());
        let scene = Scene::load(&root.join("cases/vertical_plug.toml"), &set).unwrap();
        crate::dem_config::dem_config(&scene).unwrap()
    }

    /// The column carries exactly the scene's grains per second (the remainder of each
    /// block carried to the next), at the porosity asked for, without overlaps.
    #[test]
    fn the_column_feeds_the_rate_at_its_porosity_without_overlap() {
        let cfg = vertical(&[]);
        let inlet = cfg.inlet.unwrap();
        let tube = cfg.tube.unwrap();
        let mut rng = Rng::new(3);
        let mut c = Conveyor::primed(&cfg, &mut rng).unwrap();
        let mut all: Vec<(Vec3, Real)> = Vec::new();
        let seconds = 2.0;
        let steps = 2000;
        for _ in 0..steps {
            c.advance(&cfg, inlet.velocity * seconds / steps as Real, &mut rng);
            // Grains entered earlier moved with the column.
            let entered = c.enter(&cfg, &[]);
            for g in &mut all {
                g.0 = add(
                    g.0,
                    scale(tube.axis, inlet.velocity * seconds / steps as Real),
                );
            }
            all.extend(entered);
        }
        assert_eq!(c.unplaced, 0);
        // Every grain made is either in the tube or still below it, and the blocks made
        // carry rate / velocity grains per metre to within the one grain of the carried
        // remainder.
        let made = (all.len() + c.pending()) as Real;
        let per_metre = inlet.rate / inlet.velocity;
        assert!(
            (made - per_metre * -c.bottom).abs() < 1.0,
            "{made} grains made for {} m of column at {per_metre} per m",
            -c.bottom
        );
        // Those in the tube: the column's centres down to one radius in, i.e. the
        // travelled length less one radius, to within the Poisson scatter of the block
        // the entry line crosses (3σ of its ~{per_metre × block} grains).
        let expected = per_metre * (c.travelled - cfg.radius_max);
        let block = per_metre * block_length(&cfg);
        assert!(
            (all.len() as Real - expected).abs() < 3.0 * block.sqrt(),
            "{} grains entered after {} m, expected {expected}",
            all.len(),
            c.travelled
        );
        // Porosity over the stretch filled everywhere (away from the column's top and
        // the inlet end): within 0.01 of the scene's (grains cut by the stretch's ends
        // counted by their centres: ±1 grain in ~260 per 2 cm).
        let (from, to) = (0.01, 0.07);
        let inside = all
            .iter()
            .filter(|(x, _)| (from..to).contains(&axial(&tube, *x)))
            .map(|(_, r)| 4.0 / 3.0 * std::f64::consts::PI * r.powi(3))
            .sum::<Real>();
        let volume =
            super::super::config::open_cross_section(tube.radius, tube.slab_half) * (to - from);
        let porosity = 1.0 - inside / volume;
        assert!(
            (porosity - inlet.porosity).abs() < 0.01,
            "porosity {porosity}, asked {}",
            inlet.porosity
        );
        // No overlap beyond the tolerance, and every grain inside the tube's wall.
        let tol = 2.0 * PACK_TOLERANCE * 2.0 * cfg.radius_min;
        for (i, (x, r)) in all.iter().enumerate() {
            let rel = sub(*x, tube.origin);
            let radial = norm2(sub(rel, scale(tube.axis, dot(rel, tube.axis)))).sqrt();
            assert!(radial <= tube.radius - r + 1e-12);
            for (y, q) in &all[..i] {
                assert!(norm2(sub(*x, *y)).sqrt() > r + q - tol);
            }
        }
    }

    /// A porosity no random packing reaches in the tube is refused before the run.
    #[test]
    fn a_column_denser_than_a_tube_packs_is_refused() {
        let cfg = vertical(&["inlet.mass_flow=\"3.3 kg/h\"", "inlet.porosity=0.36"]);
        let err = Conveyor::primed(&cfg, &mut Rng::new(1)).unwrap_err();
        assert!(err.contains("cannot be packed"), "{err}");
    }

    /// In the engine, with no gas to carry them, the grains fed pile up on the inlet: the
    /// conveyor still feeds the scene's rate (the grains it holds push the pile up), every
    /// grain held moves at the feed velocity with no spin and is in the slab, and the pile
    /// above it is free.
    #[test]
    fn the_engine_feeds_the_rate_under_a_pile_and_releases_grains_past_the_slab() {
        use plugflow_coupling::DemBackend;
        let mut cfg = vertical(&[]);
        cfg.threads = 1;
        let inlet = cfg.inlet.unwrap();
        let tube = cfg.tube.unwrap();
        let mut dem = super::super::NativeDem::new(cfg.clone()).unwrap();
        let seconds = 0.6;
        let steps = (seconds / cfg.dt).round() as u64;
        dem.advance(steps).unwrap();
        let fed = dem.flow.fed_count as Real;
        // Grains entered = grains per metre × (distance moved − one radius), to within 3σ
        // of the Poisson count of the block the entry line crosses (as above).
        let per_metre = inlet.rate / inlet.velocity;
        let expected = per_metre * (inlet.velocity * seconds - cfg.radius_max);
        let block = per_metre * block_length(&cfg);
        assert!(
            (fed - expected).abs() < 3.0 * block.sqrt(),
            "{fed} grains fed in {seconds} s, expected {expected}"
        );
        let column = dem.conveyor.as_ref().unwrap();
        assert_eq!(column.unplaced, 0);
        let s = &dem.state;
        let v = super::super::inlet::Feeder::velocity(&cfg);
        let (mut held, mut above) = (0, 0);
        for i in 0..s.len() {
            let a = axial(&tube, s.position[i]);
            if column.holds(s.id[i]) {
                held += 1;
                // Released at the first feed after its centre passed the slab.
                let stride = super::super::FEED_STRIDE as Real * cfg.dt;
                assert!(a <= inlet.slab_length + inlet.velocity * stride, "{a}");
                assert_eq!(s.velocity[i], v);
                assert_eq!(s.angular_velocity[i], [0.0; 3]);
                assert_eq!(s.inv_mass[i], 0.0);
            } else {
                assert!(s.inv_mass[i] > 0.0);
                if a > inlet.slab_length {
                    above += 1;
                }
            }
        }
        // The pile: what the slab cannot hold rests above it (with no gas it falls back
        // onto the held grains; they still move in at the feed velocity).
        assert!(held > 0 && above > 0, "{held} held, {above} above");
    }
    /// The sweeps over the candidate list pack a block bit for bit as sweeps over every
    /// pair (an infinite skin lists every pair and never goes stale: the sweeps as they
    /// were before the list): blocks that pack and blocks that jam (20 000 sweeps), with
    /// the column's fixed grains above.
    #[test]
    fn candidate_sweeps_pack_as_all_pairs_do() {
        let cfg = vertical(&[]);
        let inlet = cfg.inlet.unwrap();
        let tube = cfg.tube.unwrap();
        let shape = Section {
            radius: tube.radius,
            slab_half: tube.slab_half,
        };
        let tolerance = PACK_TOLERANCE * 2.0 * cfg.radius_min;
        let length = block_length(&cfg);
        let per_block = (inlet.rate * length / inlet.velocity).round() as usize;
        let mut rng = Rng::new(7);
        let mut column = Conveyor::default();
        let mut jammed = 0;
        for block in 0..6 {
            let radii: Vec<Real> = (0..per_block)
                .map(|_| draw_radius(&cfg, &mut rng))
                .collect();
            let (hi, lo) = (column.bottom, column.bottom - length);
            let above: Vec<ColumnGrain> = column
                .pending
                .iter()
                .copied()
                .filter(|g| g[0] - g[3] < hi + 2.0 * cfg.radius_max)
                .collect();
            let seed = 100 + block;
            let pack_with = |skin: Real| {
                let rng = &mut Rng::new(seed);
                pack(&radii, lo, hi, &shape, &above, tolerance, skin, rng)
            };
            let (listed, all) = (pack_with(CANDIDATE_SKIN), pack_with(Real::INFINITY));
            assert_eq!(listed, all, "block {block}");
            jammed += listed.1.iter().any(|&o| o) as usize;
            column.pending.extend(listed.0);
            column.bottom = lo;
        }
        // Both paths of the sweeps ran: blocks that packed and blocks that jammed.
        assert!(jammed > 0 && jammed < 6, "{jammed} of 6 blocks jammed");
    }
}
