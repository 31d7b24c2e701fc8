//! The gas grid of a tube and the grain ↔ grid kernels of seed 000 eqs. 7–9.
//!
//! Nodes sit at cell centres: `nz` slices of length l_z along the axis, each cut into
//! `nx × ny` squares covering the tube's bounding square (the paper's 150 × 2 × 2 with
//! l = 3.5 mm for the 7 mm tube). The tube wall cuts the cells, so every node carries the
//! fluid-accessible volume of its cell: porosity is normalised by it (an empty tube reads
//! φ = 1, a packed one its true packing porosity).
//!
//! Deposit (eq. 8): 1 − φ_j = Σ_i V_i w_ij / V_j and u_j = Σ_i V_i w_ij v_i / Σ_i V_i w_ij,
//! with trilinear tent weights w_ij (eq. 7) that sum to one over the nodes for every grain
//! (coordinates outside the node hull are clamped onto it, so no grain volume is lost).
//! Interpolation (eq. 9) uses the same weights.

use crate::{Real, Vec3};

/// Two unit vectors perpendicular to `axis` and to each other (a right-handed frame).
pub fn perpendicular_basis(axis: Vec3) -> (Vec3, Vec3) {
    let helper = if axis[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let d = helper[0] * axis[0] + helper[1] * axis[1] + helper[2] * axis[2];
    let mut e1 = [
        helper[0] - d * axis[0],
        helper[1] - d * axis[1],
        helper[2] - d * axis[2],
    ];
    let n = (e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]).sqrt();
    e1 = [e1[0] / n, e1[1] / n, e1[2] / n];
    let e2 = [
        axis[1] * e1[2] - axis[2] * e1[1],
        axis[2] * e1[0] - axis[0] * e1[2],
        axis[0] * e1[1] - axis[1] * e1[0],
    ];
    (e1, e2)
}

/// The gas grid over a tube.
#[derive(Debug, Clone)]
pub struct TubeGrid {
    /// Centre of the inlet end, m.
    pub origin: Vec3,
    /// Unit axis, inlet → outlet.
    pub axis: Vec3,
    /// Cross-section frame.
    pub e1: Vec3,
    pub e2: Vec3,
    /// Inner radius, m.
    pub radius: Real,
    /// Length, m.
    pub length: Real,
    /// Node counts: along the axis, across (e1), across (e2).
    pub nz: usize,
    pub nx: usize,
    pub ny: usize,
    /// Cell sizes, m.
    pub dz: Real,
    pub dx: Real,
    pub dy: Real,
    /// Fluid-accessible volume of each node's cell, m³ (index `node(k, i, j)`).
    pub volume: Vec<Real>,
    /// Open area of the face between node (k,i,j) and (k,i+1,j), m² (per slice, i < nx−1).
    pub face_x: Vec<Real>,
    /// Open area of the face between node (k,i,j) and (k,i,j+1), m² (per slice).
    pub face_y: Vec<Real>,
    /// Open area of each node's cell across the axis, m² (per slice, index i + nx j).
    pub face_z: Vec<Real>,
    /// Columns (index i + nx j) that take part: open across at least
    /// [`OPEN_FRACTION`] of the largest column's area. A sliver the wall cuts off a corner
    /// cell would hold a porosity dominated by single grains (and a gas cell of no volume):
    /// grains weigh on the open nodes only.
    pub open: Vec<bool>,
    /// A periodic section: the last slice neighbours the first (the tent weights wrap
    /// around the seam; the gas solver joins the two).
    pub periodic: bool,
    /// Take each node's solid fraction over its whole grid cell dz·dx·dy instead of its
    /// open volume (`coupling.porosity_volume = "whole_cell"`: seed 000 eq. 8 read with
    /// the tent function normalised by the cubic grid's cell, a grid that ignores the wall).
    pub whole_cell_porosity: bool,
}

/// Least open cross-section of a column, as a share of the largest, for it to carry nodes.
pub const OPEN_FRACTION: Real = 0.1;

/// Tent weights of one grain: up to 8 (node, weight) pairs.
#[derive(Debug, Clone, Copy, Default)]
pub struct Stencil {
    pub node: [u32; 8],
    pub weight: [Real; 8],
    pub len: u8,
}

impl TubeGrid {
    /// Grid of `nz × nx × ny` nodes over a tube.
    pub fn new(
        origin: Vec3,
        axis: Vec3,
        radius: Real,
        length: Real,
        nz: usize,
        nx: usize,
        ny: usize,
    ) -> Self {
        Self::new_in_slab(origin, axis, radius, length, [nz, nx, ny], None)
    }

    /// Grid of `counts = [nz, nx, ny]` nodes over a tube, or over the slab |u| ≤ `slab_half`
    /// of it (u along e1): a quasi-2D tube, whose cells hold only the slab's volume.
    pub fn new_in_slab(
        origin: Vec3,
        axis: Vec3,
        radius: Real,
        length: Real,
        counts: [usize; 3],
        slab_half: Option<Real>,
    ) -> Self {
        let [nz, nx, ny] = counts;
        let h = slab_half.unwrap_or(Real::INFINITY);
        let (e1, e2) = perpendicular_basis(axis);
        let dz = length / nz as Real;
        let dx = 2.0 * radius / nx as Real;
        let dy = 2.0 * radius / ny as Real;
        // Open cross-section of each cell and of the faces between cells, by sampling.
        // (u sampled over the cell's part inside the slab, so a thin slab keeps 400 samples.)
        const S: usize = 400;
        let mut face_z = vec![0.0; nx * ny];
        for (i, j) in (0..ny).flat_map(|j| (0..nx).map(move |i| (i, j))) {
            let u_lo = (-radius + i as Real * dx).max(-h);
            let u_hi = (-radius + (i + 1) as Real * dx).min(h);
            if u_hi <= u_lo {
                continue;
            }
            let mut inside = 0usize;
            for a in 0..S {
                for b in 0..S {
                    let u = u_lo + (a as Real + 0.5) / S as Real * (u_hi - u_lo);
                    let w = -radius + (j as Real + (b as Real + 0.5) / S as Real) * dy;
                    if u * u + w * w <= radius * radius {
                        inside += 1;
                    }
                }
            }
            face_z[i + nx * j] = inside as Real / (S * S) as Real * (u_hi - u_lo) * dy;
        }
        let open_len = |fixed: Real, lo: Real, hi: Real| -> Real {
            // Length of the segment {fixed} × [lo, hi] inside the disc.
            let half = (radius * radius - fixed * fixed).max(0.0).sqrt();
            (hi.min(half) - lo.max(-half)).max(0.0)
        };
        let mut face_x = vec![0.0; nx.saturating_sub(1) * ny];
        for j in 0..ny {
            for i in 0..nx.saturating_sub(1) {
                let u = -radius + (i + 1) as Real * dx;
                let lo = -radius + j as Real * dy;
                let open = if u.abs() <= h {
                    open_len(u, lo, lo + dy)
                } else {
                    0.0
                };
                face_x[i + (nx - 1) * j] = open * dz;
            }
        }
        let mut face_y = vec![0.0; nx * ny.saturating_sub(1)];
        for j in 0..ny.saturating_sub(1) {
            for i in 0..nx {
                let w = -radius + (j + 1) as Real * dy;
                let lo = (-radius + i as Real * dx).max(-h);
                let hi = (-radius + (i + 1) as Real * dx).min(h);
                face_y[i + nx * j] = open_len(w, lo, hi.max(lo)) * dz;
            }
        }
        let largest = face_z.iter().copied().fold(0.0, Real::max);
        let open: Vec<bool> = face_z
            .iter()
            .map(|&a| a > 0.0 && a >= OPEN_FRACTION * largest)
            .collect();
        let volume = (0..nz)
            .flat_map(|_| face_z.iter().map(|a| a * dz))
            .collect();
        Self {
            origin,
            axis,
            e1,
            e2,
            radius,
            length,
            nz,
            nx,
            ny,
            dz,
            dx,
            dy,
            volume,
            face_x,
            face_y,
            face_z,
            open,
            periodic: false,
            whole_cell_porosity: false,
        }
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.nz * self.nx * self.ny
    }

    /// True for a grid without nodes (never built by [`TubeGrid::new`] with counts ≥ 1).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Index of node (slice k, column i, row j).
    #[inline]
    pub fn node(&self, k: usize, i: usize, j: usize) -> usize {
        (k * self.ny + j) * self.nx + i
    }

    /// True when node n's column takes part (see [`TubeGrid::open`]).
    #[inline]
    pub fn is_open(&self, n: usize) -> bool {
        self.open[n % (self.nx * self.ny)]
    }

    /// Smallest volume of an open node's cell, m³.
    pub fn smallest_open_volume(&self) -> Real {
        (0..self.len())
            .filter(|&n| self.is_open(n))
            .map(|n| self.volume[n])
            .fold(Real::INFINITY, Real::min)
    }

    /// Tube-frame coordinates (s along the axis, u, w across) of a point.
    #[inline(always)]
    pub fn local(&self, x: Vec3) -> (Real, Real, Real) {
        let r = [
            x[0] - self.origin[0],
            x[1] - self.origin[1],
            x[2] - self.origin[2],
        ];
        let d = |a: Vec3| r[0] * a[0] + r[1] * a[1] + r[2] * a[2];
        (d(self.axis), d(self.e1), d(self.e2))
    }

    /// Tent weights of a point (eq. 7), clamped onto the node hull so they sum to one; the
    /// weights of closed nodes (wall slivers, see [`TubeGrid::open`]) go to the open ones
    /// in proportion, so no grain volume is lost.
    pub fn stencil(&self, x: Vec3) -> Stencil {
        self.stencil_local(self.local(x))
    }

    /// [`TubeGrid::stencil`] of a point given in tube-frame coordinates (s, u, w).
    pub fn stencil_local(&self, local: (Real, Real, Real)) -> Stencil {
        let mut st = Stencil::default();
        self.write_stencil(local, &mut st);
        st
    }

    /// [`TubeGrid::stencil_local`] written in place, over whatever `st` held: the deposit
    /// writes each grain's stencil straight into its slot (a stencil built apart and copied
    /// in is read back in 16-byte pieces its 4- and 8-byte writes cannot forward, a stall
    /// per piece).
    #[inline(always)]
    fn write_stencil(&self, local: (Real, Real, Real), st: &mut Stencil) {
        self.write_stencil_at(self.tent_coordinates(local), st);
    }

    /// A point's coordinates in node units along each direction (s, u, w), less one half:
    /// the tent weights' argument, before clamping or wrapping (node k sits at k).
    #[inline(always)]
    fn tent_coordinates(&self, (s, u, w): (Real, Real, Real)) -> [Real; 3] {
        [
            s / self.dz - 0.5,
            (u + self.radius) / self.dx - 0.5,
            (w + self.radius) / self.dy - 0.5,
        ]
    }

    /// [`TubeGrid::write_stencil`] from the point's [`TubeGrid::tent_coordinates`] (the
    /// deposit takes those for a block of grains first: the divisions then overlap).
    ///
    /// Written for speed (it runs for every grain at every exchange): no libm call, no
    /// integer division, the 4 columns' open flags looked up once. The weights and their
    /// order are those of the plain triple loop over (slice, column, row).
    #[inline(always)]
    fn write_stencil_at(&self, [fz, fx, fy]: [Real; 3], st: &mut Stencil) {
        let (kz, wz) = axis_weights(fz, self.nz, self.periodic);
        let (kx, wx) = axis_weights(fx, self.nx, false);
        let (ky, wy) = axis_weights(fy, self.ny, false);
        let slice = self.nx * self.ny;
        let column = |b: usize, c: usize| kx[b] + self.nx * ky[c];
        let columns = [column(0, 0), column(0, 1), column(1, 0), column(1, 1)];
        let open = columns.map(|col| self.open[col]);
        st.len = 0;
        let mut dropped = false;
        for a in 0..2 {
            let base = kz[a] * slice;
            for bc in 0..4 {
                let weight = wz[a] * wx[bc >> 1] * wy[bc & 1];
                if weight <= 0.0 {
                    continue;
                }
                if !open[bc] {
                    dropped = true;
                    continue;
                }
                let n = st.len as usize;
                st.node[n] = (base + columns[bc]) as u32;
                st.weight[n] = weight;
                st.len += 1;
            }
        }
        if dropped {
            let kept: Real = st.weight[..st.len as usize].iter().sum();
            if kept > 0.0 {
                st.weight[..st.len as usize]
                    .iter_mut()
                    .for_each(|w| *w /= kept);
            }
        }
    }
}

/// The two nodes either side of a point along one direction of the grid and their tent
/// weights (eq. 7), from its tent coordinate `f` (see [`TubeGrid::tent_coordinates`]) and
/// the direction's node count `n`. A direction that wraps (a periodic section's axis) takes
/// the last node as the first's neighbour below; one that does not clamps onto its end
/// nodes.
#[inline(always)]
fn axis_weights(f: Real, n: usize, wraps: bool) -> ([usize; 2], [Real; 2]) {
    if n == 1 {
        return ([0, 0], [1.0, 0.0]);
    }
    let (f, top) = if wraps {
        // (f % n is f itself on [0, n): the remainder's libm call only outside it.)
        let inside = (0.0..(n as Real)).contains(&f);
        (if inside { f } else { f.rem_euclid(n as Real) }, n - 1)
    } else {
        (f.clamp(0.0, (n - 1) as Real), n - 2)
    };
    // f ≥ 0 here (or NaN, which casts to 0 as its floor does): truncation is the floor.
    // (Through i64: the conversions are single instructions, unsigned ones are not.)
    let k0 = ((f as i64) as usize).min(top);
    let t = f - k0 as i64 as Real;
    let k1 = if k0 + 1 == n { 0 } else { k0 + 1 };
    ([k0, k1], [1.0 - t, t])
}

/// Granular fields on the nodes (eq. 8), and the stencil of every grain that made them.
#[derive(Debug, Clone, Default)]
pub struct GranularFields {
    /// Porosity φ_j before clamping.
    pub porosity: Vec<Real>,
    /// Granular velocity u_j, m/s (zero where no grain contributes).
    pub velocity: Vec<Vec3>,
    /// Tent weights of grain i (in the order deposited; `None` outside the tube's length),
    /// kept so the interpolation back to the grains (eq. 9) does not compute them again.
    pub stencils: Vec<Option<Stencil>>,
    /// Solid fraction on the nodes of the grains fed since the last exchange (empty: none
    /// known). A gas whose continuity keeps ∂ε/∂t counts them as if they had been there
    /// already: fed grains enter with their gas, they do not push it out of the cell they
    /// appear in (a whole inlet batch appearing at once would otherwise blow a jet).
    pub fed_solid: Vec<Real>,
}

/// One range of grains' share of a deposit: their volume and momentum summed per node.
#[derive(Debug, Clone, Default)]
pub struct NodeSums {
    /// Per node: Σ w V (m³), then Σ w V v (m³·m/s, three components). One 32-byte entry
    /// per node: a grain's share goes on in one vector addition.
    pub node: Vec<[Real; 4]>,
}

/// Deposit grains (centres `x`, velocities `v`, radii `r`) onto the grid. Grains outside the
/// tube's length are left out (they have left or not yet entered).
pub fn deposit(grid: &TubeGrid, x: &[Vec3], v: &[Vec3], r: &[Real], out: &mut GranularFields) {
    let mut sums = NodeSums::default();
    out.stencils.clear();
    out.stencils.resize(x.len(), None);
    deposit_part(grid, x, v, r, &mut out.stencils, &mut sums);
    finish_deposit(grid, std::slice::from_ref(&sums), out);
}

/// The first half of [`deposit`] for one range of grains: each grain's stencil (`None`
/// outside the tube's length) and the range's sums on the nodes (`sums` is overwritten).
/// Ranges deposited apart and finished together give the same fields as one deposit up to
/// the order of the sums (the same order for a fixed split).
pub fn deposit_part(
    grid: &TubeGrid,
    x: &[Vec3],
    v: &[Vec3],
    r: &[Real],
    stencils: &mut [Option<Stencil>],
    sums: &mut NodeSums,
) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2 (checked just above).
        unsafe { deposit_part_avx2(grid, x, v, r, stencils, sums) };
        return;
    }
    deposit_part_body(grid, x, v, r, stencils, sums);
}

/// [`deposit_part_body`] compiled for AVX2 (no FMA: the same roundings as the baseline).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn deposit_part_avx2(
    grid: &TubeGrid,
    x: &[Vec3],
    v: &[Vec3],
    r: &[Real],
    stencils: &mut [Option<Stencil>],
    sums: &mut NodeSums,
) {
    deposit_part_body(grid, x, v, r, stencils, sums);
}

#[inline(always)]
fn deposit_part_body(
    grid: &TubeGrid,
    x: &[Vec3],
    v: &[Vec3],
    r: &[Real],
    stencils: &mut [Option<Stencil>],
    sums: &mut NodeSums,
) {
    let n = grid.len();
    let node_sums = &mut sums.node;
    node_sums.clear();
    node_sums.resize(n, [0.0; 4]);
    // Blocks of grains: first every grain's tent coordinates (three divisions each, which
    // overlap when nothing waits on them), then the stencils and the sums.
    const BLOCK: usize = 32;
    let mut axial = [0.0; BLOCK];
    let mut tent = [[0.0; 3]; BLOCK];
    for start in (0..x.len()).step_by(BLOCK) {
        let end = (start + BLOCK).min(x.len());
        for (k, p) in (start..end).enumerate() {
            let local = grid.local(x[p]);
            axial[k] = local.0;
            tent[k] = grid.tent_coordinates(local);
        }
        for (k, p) in (start..end).enumerate() {
            // (A periodic section holds every grain: between neighbour builds one may sit
            // past the seam, and its weights wrap around.)
            if !grid.periodic && !(0.0..=grid.length).contains(&axial[k]) {
                stencils[p] = None;
                continue;
            }
            let vol = 4.0 / 3.0 * std::f64::consts::PI * r[p] * r[p] * r[p];
            let st = stencils[p].get_or_insert_with(Stencil::default);
            grid.write_stencil_at(tent[k], st);
            scatter(st, vol, v[p], node_sums);
        }
    }
}

/// One grain's volume `vol` (m³) and momentum `vol · v` onto the nodes of its stencil.
#[inline(always)]
fn scatter(st: &Stencil, vol: Real, v: Vec3, node_sums: &mut [[Real; 4]]) {
    // (w V · 1 is w V exactly: the volume and the momentum in one product.)
    let per_weight = [1.0, v[0], v[1], v[2]];
    for q in 0..st.len as usize {
        let wv = st.weight[q] * vol;
        let sum = &mut node_sums[st.node[q] as usize];
        for c in 0..4 {
            sum[c] += wv * per_weight[c];
        }
    }
}

/// The second half of [`deposit`]: porosity and granular velocity from the ranges' sums,
/// added in range order.
pub fn finish_deposit(grid: &TubeGrid, parts: &[NodeSums], out: &mut GranularFields) {
    let n = grid.len();
    out.porosity.clear();
    out.velocity.clear();
    for j in 0..n {
        let mut sum = parts[0].node[j];
        for part in &parts[1..] {
            for (s, add) in sum.iter_mut().zip(part.node[j]) {
                *s += add;
            }
        }
        let (solid, momentum) = (sum[0], [sum[1], sum[2], sum[3]]);
        // (Closed nodes hold no grain and may have no volume: empty.)
        let volume = if grid.whole_cell_porosity {
            grid.dz * grid.dx * grid.dy
        } else {
            grid.volume[j]
        };
        out.porosity.push(if solid > 0.0 {
            1.0 - solid / volume
        } else {
            1.0
        });
        out.velocity.push(if solid > 0.0 {
            [
                momentum[0] / solid,
                momentum[1] / solid,
                momentum[2] / solid,
            ]
        } else {
            [0.0; 3]
        });
    }
}

/// Interpolate a scalar node field to a point with the tent weights (eq. 9).
#[inline]
pub fn interpolate_scalar(stencil: &Stencil, field: &[Real]) -> Real {
    (0..stencil.len as usize)
        .map(|q| field[stencil.node[q] as usize] * stencil.weight[q])
        .sum()
}

/// Interpolate a vector node field to a point with the tent weights (eq. 9).
#[inline]
pub fn interpolate_vec3(stencil: &Stencil, field: &[Vec3]) -> Vec3 {
    let mut acc = [0.0; 3];
    for q in 0..stencil.len as usize {
        let f = field[stencil.node[q] as usize];
        for c in 0..3 {
            acc[c] += f[c] * stencil.weight[q];
        }
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reproducible stream of uniform numbers in [0, 1) (a 64-bit LCG's top 53 bits), so
    /// the tests draw the same points on every machine without the model crate's Rng.
    fn uniform_stream(seed: u64) -> impl FnMut() -> Real {
        let mut state = seed;
        move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as Real / (1u64 << 53) as Real
        }
    }

    fn paper_grid() -> TubeGrid {
        TubeGrid::new([0.0; 3], [0.0, 0.0, 1.0], 3.5e-3, 0.525, 150, 2, 2)
    }

    #[test]
    fn periodic_weights_wrap_around_the_seam() {
        // A grain a fifth of a slice past the seam (s = L + 0.2 dz, as it may lie between
        // neighbour builds) weighs on the first slice (0.7) and the last (0.3): as a grain
        // at 0.2 dz, the same point of the circle. Weights sum to one either way.
        let mut g = TubeGrid::new([0.0; 3], [0.0, 0.0, 1.0], 3.5e-3, 0.1, 10, 1, 1);
        g.periodic = true;
        for s in [0.1 + 0.2 * g.dz, 0.2 * g.dz] {
            let st = g.stencil([0.0, 0.0, s]);
            let w = |k: usize| {
                (0..st.len as usize)
                    .filter(|&q| st.node[q] as usize == k)
                    .map(|q| st.weight[q])
                    .sum::<Real>()
            };
            assert!(
                (w(0) - 0.7).abs() < 1e-9 && (w(9) - 0.3).abs() < 1e-9,
                "s = {s}: {st:?}"
            );
        }
    }

    /// A deposit on a single slice of a Lethe-like pipe (8 × 8 across, its cut cells):
    /// smoothing over L keeps every grain's volume and momentum (conservative fluxes),
    /// keeps every node's solid fraction non-negative, and spreads the slice along the axis
    /// with variance L² exactly (each explicit pass adds 2κ, n passes 2κn = L²; the
    /// flow across the section leaves the axial spread alone, as every column diffuses
    /// alike along the axis).
    #[test]
    fn smoothing_conserves_the_deposit_and_spreads_it_over_its_length() {
        let g = TubeGrid::new([0.0; 3], [1.0, 0.0, 0.0], 0.042, 1.0, 90, 8, 8);
        let mut fields = GranularFields {
            porosity: vec![1.0; g.len()],
            velocity: vec![[0.0; 3]; g.len()],
            ..Default::default()
        };
        let k0 = 45;
        for j in 0..g.ny {
            for i in 0..g.nx {
                let n = g.node(k0, i, j);
                if g.is_open(n) {
                    // A dense, uneven slice: denser at the centre, moving along the axis.
                    fields.porosity[n] = 0.3 + 0.05 * (i as Real - 3.5).abs();
                    fields.velocity[n] = [1.0 + 0.1 * j as Real, 0.0, -0.2];
                }
            }
        }
        let totals = |f: &GranularFields| {
            let mut t = [0.0; 4];
            for n in 0..g.len() {
                let s = (1.0 - f.porosity[n]) * g.volume[n];
                t[0] += s;
                for q in 0..3 {
                    t[1 + q] += s * f.velocity[n][q];
                }
            }
            t
        };
        let before = totals(&fields);
        let length = 0.01; // 2 d of Lethe's 5 mm grains, ~1 cell
        let mut sm = Smoothing::new(&g, length);
        sm.apply(&g, &mut fields);
        let after = totals(&fields);
        for q in 0..4 {
            assert!(
                (after[q] - before[q]).abs() <= 1e-12 * before[q].abs().max(1e-12),
                "quantity {q}: {} before, {} after",
                before[q],
                after[q]
            );
        }
        assert!(
            fields.porosity.iter().all(|&p| p <= 1.0 + 1e-15),
            "negative solid"
        );
        // The axial spread of the solid volume (node positions k dz about slice k0).
        let (mut m0, mut m2) = (0.0, 0.0);
        for k in 0..g.nz {
            let z = (k as Real - k0 as Real) * g.dz;
            for j in 0..g.ny {
                for i in 0..g.nx {
                    let n = g.node(k, i, j);
                    let s = (1.0 - fields.porosity[n]) * g.volume[n];
                    m0 += s;
                    m2 += s * z * z;
                }
            }
        }
        let variance = m2 / m0;
        assert!(
            (variance - length * length).abs() <= 1e-9 * length * length,
            "axial variance {variance:e} m², L² = {:e} m² ({} passes)",
            length * length,
            sm.passes()
        );
    }

    #[test]
    fn accessible_volume_adds_up_to_the_tube() {
        let g = paper_grid();
        let total: Real = g.volume.iter().sum();
        let tube = std::f64::consts::PI * 3.5e-3f64.powi(2) * 0.525;
        // Sampling 400 × 400 points per cell: area error ~ perimeter × h ≈ 1e-3 relative.
        assert!((total / tube - 1.0).abs() < 2e-3, "{total} vs {tube}");
        // The 2 × 2 cells are quarter discs; the inner faces are fully open (length R).
        assert!((g.face_x[0] - 3.5e-3 * g.dz).abs() < 1e-12);
    }

    #[test]
    fn weights_sum_to_one_everywhere_in_the_tube() {
        let g = paper_grid();
        for &(x, y, z) in &[
            (0.0, 0.0, 0.1),
            (2.8e-3, 0.0, 0.001),
            (-2.0e-3, 1.9e-3, 0.5249),
        ] {
            let st = g.stencil([x, y, z]);
            let sum: Real = st.weight[..st.len as usize].iter().sum();
            assert!((sum - 1.0).abs() < 1e-14, "{sum}");
        }
    }

    /// On a fine cross-section (6 × 6 over the tube's square) the corner cells keep 2.9 % of
    /// a full cell's area: closed. A grain near such a corner weighs only on open nodes, its
    /// weights still summing to one; the inner columns stay open.
    #[test]
    fn closed_corner_cells_take_no_weight() {
        let g = TubeGrid::new([0.0; 3], [0.0, 0.0, 1.0], 3.5e-3, 0.1, 10, 6, 6);
        let closed: Vec<usize> = (0..36).filter(|&c| !g.open[c]).collect();
        assert_eq!(closed, vec![0, 5, 30, 35]);
        // Near the (−, −) corner, at 45°: the tent reaches the corner column's node.
        let r = 3.2e-3 / 2f64.sqrt();
        let st = g.stencil([-r, -r, 0.05]);
        let sum: Real = st.weight[..st.len as usize].iter().sum();
        assert!((sum - 1.0).abs() < 1e-14, "{sum}");
        assert!(st.node[..st.len as usize]
            .iter()
            .all(|&n| g.is_open(n as usize)));
        assert!(g.smallest_open_volume() > 0.5 * g.volume[g.node(0, 1, 0)]);
    }

    /// The deposit's fast stencils (`write_stencil_at` and the blocked, AVX2 deposit) are
    /// the plain tent weights of eq. 7 to the bit: against a reference written as the
    /// equation reads (floor, triple loop, closed nodes' weight shared out), for points
    /// all over and beyond four grids (the seeds' 2 × 2, one with closed corner columns, a
    /// periodic section, one with a single node across), and a whole deposit's sums
    /// against the reference stencils' sums in the same order.
    #[test]
    fn fast_stencils_are_the_plain_tent_weights_bit_for_bit() {
        fn reference(g: &TubeGrid, (s, u, w): (Real, Real, Real)) -> Stencil {
            let axis = |coord: Real, lo: Real, h: Real, n: usize, wraps: bool| {
                if n == 1 {
                    return ([0, 0], [1.0, 0.0]);
                }
                let f = (coord - lo) / h - 0.5;
                let (f, top) = if wraps {
                    (f.rem_euclid(n as Real), n - 1)
                } else {
                    (f.clamp(0.0, (n - 1) as Real), n - 2)
                };
                let k0 = (f.floor() as usize).min(top);
                let t = f - k0 as Real;
                ([k0, (k0 + 1) % n], [1.0 - t, t])
            };
            let (kz, wz) = axis(s, 0.0, g.dz, g.nz, g.periodic);
            let (kx, wx) = axis(u, -g.radius, g.dx, g.nx, false);
            let (ky, wy) = axis(w, -g.radius, g.dy, g.ny, false);
            let mut st = Stencil::default();
            let mut dropped = false;
            for a in 0..2 {
                for b in 0..2 {
                    for c in 0..2 {
                        let weight = wz[a] * wx[b] * wy[c];
                        if weight <= 0.0 {
                            continue;
                        }
                        if !g.open[kx[b] + g.nx * ky[c]] {
                            dropped = true;
                            continue;
                        }
                        st.node[st.len as usize] = g.node(kz[a], kx[b], ky[c]) as u32;
                        st.weight[st.len as usize] = weight;
                        st.len += 1;
                    }
                }
            }
            let kept: Real = st.weight[..st.len as usize].iter().sum();
            if dropped && kept > 0.0 {
                st.weight[..st.len as usize]
                    .iter_mut()
                    .for_each(|w| *w /= kept);
            }
            st
        }
        let mut periodic = TubeGrid::new([0.0; 3], [1.0, 0.0, 0.0], 0.042, 1.0, 90, 8, 8);
        periodic.periodic = true;
        let grids = [
            paper_grid(),
            TubeGrid::new([0.0; 3], [0.0, 0.0, 1.0], 3.5e-3, 0.1, 10, 6, 6),
            periodic,
            TubeGrid::new([1.0, 2.0, 3.0], [0.0, 1.0, 0.0], 2.0e-3, 0.2, 40, 1, 4),
        ];
        let mut next = uniform_stream(99);
        for (gi, g) in grids.iter().enumerate() {
            // Points over the tube's square and 10 % beyond each end (clamped or wrapped),
            // and the grid's node and cell-edge positions exactly.
            let mut points: Vec<(Real, Real, Real)> = (0..4000)
                .map(|_| {
                    (
                        (1.2 * next() - 0.1) * g.length,
                        (2.0 * next() - 1.0) * g.radius,
                        (2.0 * next() - 1.0) * g.radius,
                    )
                })
                .collect();
            for k in 0..=2 * g.nz {
                let s = 0.5 * k as Real * g.dz;
                points.push((s, -g.radius + 0.5 * g.dx, g.radius - 0.5 * g.dy));
                points.push((s, 0.0, 0.0));
            }
            for &p in &points {
                let (fast, plain) = (g.stencil_local(p), reference(g, p));
                let len = plain.len as usize;
                assert_eq!(fast.len, plain.len, "grid {gi}, point {p:?}");
                assert_eq!(fast.node[..len], plain.node[..len], "grid {gi}, {p:?}");
                let bits = |st: &Stencil| {
                    st.weight[..len]
                        .iter()
                        .map(|w| w.to_bits())
                        .collect::<Vec<_>>()
                };
                assert_eq!(bits(&fast), bits(&plain), "grid {gi}, point {p:?}");
            }
            // A whole deposit (blocked, AVX2 where the CPU has it) against the reference
            // stencils summed grain by grain in the same order.
            let inside: Vec<(Real, Real, Real)> = points
                .iter()
                .copied()
                .filter(|p| g.periodic || (0.0..=g.length).contains(&p.0))
                .filter(|p| p.1 * p.1 + p.2 * p.2 < g.radius * g.radius)
                .collect();
            let x: Vec<Vec3> = inside
                .iter()
                .map(|&(s, u, w)| {
                    std::array::from_fn(|c| g.origin[c] + s * g.axis[c] + u * g.e1[c] + w * g.e2[c])
                })
                .collect();
            let v: Vec<Vec3> = (0..x.len()).map(|_| [next(), next(), next()]).collect();
            let r: Vec<Real> = (0..x.len()).map(|_| 1e-4 * (1.0 + next())).collect();
            let mut fields = GranularFields::default();
            deposit(g, &x, &v, &r, &mut fields);
            let mut sums = vec![[0.0; 4]; g.len()];
            for p in 0..x.len() {
                // (The deposit's own test of the tube's length, on the point as it reads it.)
                let local = g.local(x[p]);
                if !g.periodic && !(0.0..=g.length).contains(&local.0) {
                    continue;
                }
                let st = reference(g, local);
                let vol = 4.0 / 3.0 * std::f64::consts::PI * r[p] * r[p] * r[p];
                for q in 0..st.len as usize {
                    let wv = st.weight[q] * vol;
                    let sum = &mut sums[st.node[q] as usize];
                    sum[0] += wv;
                    for c in 0..3 {
                        sum[1 + c] += wv * v[p][c];
                    }
                }
            }
            let mut expected = GranularFields::default();
            finish_deposit(g, &[NodeSums { node: sums }], &mut expected);
            let bits = |f: &GranularFields| -> Vec<u64> {
                f.porosity
                    .iter()
                    .chain(f.velocity.iter().flatten())
                    .map(|v| v.to_bits())
                    .collect()
            };
            assert!(x.len() > 1000, "grid {gi}: {} grains", x.len());
            assert_eq!(bits(&fields), bits(&expected), "grid {gi}");
        }
    }

    /// A deposit cut into ranges (as the engine's team members make it) and finished
    /// together gives the one-range deposit's fields up to the order of the node sums
    /// (a few ulps), the same stencils, and the same fields again for the same cut.
    #[test]
    fn a_deposit_in_ranges_matches_the_whole() {
        let g = paper_grid();
        let mut next = uniform_stream(12345);
        let n = 3000;
        let x: Vec<Vec3> = (0..n)
            .map(|_| {
                let (a, r) = (next() * std::f64::consts::TAU, 3.0e-3 * next().sqrt());
                [r * a.cos(), r * a.sin(), 0.53 * next()]
            })
            .collect();
        let v: Vec<Vec3> = (0..n)
            .map(|_| [next() - 0.5, next() - 0.5, next()])
            .collect();
        let r = vec![0.7e-3; n];
        let mut whole = GranularFields::default();
        deposit(&g, &x, &v, &r, &mut whole);
        let split = |cuts: &[usize]| -> GranularFields {
            let mut f = GranularFields::default();
            f.stencils.resize(n, None);
            let mut parts = vec![NodeSums::default(); cuts.len() - 1];
            for (k, part) in parts.iter_mut().enumerate() {
                let (lo, hi) = (cuts[k], cuts[k + 1]);
                deposit_part(
                    &g,
                    &x[lo..hi],
                    &v[lo..hi],
                    &r[lo..hi],
                    &mut f.stencils[lo..hi],
                    part,
                );
            }
            finish_deposit(&g, &parts, &mut f);
            f
        };
        let (a, b) = (split(&[0, 1500, 3000]), split(&[0, 1500, 3000]));
        assert_eq!(a.porosity, b.porosity);
        for j in 0..g.len() {
            // Two partial sums of ~30 terms each added instead of one running sum: the
            // roundings differ by a few ulps of the node's solid volume.
            assert!(
                (a.porosity[j] - whole.porosity[j]).abs() < 1e-13,
                "node {j}"
            );
            for c in 0..3 {
                assert!(
                    (a.velocity[j][c] - whole.velocity[j][c]).abs() < 1e-12,
                    "node {j}"
                );
            }
        }
        let outside = whole.stencils.iter().filter(|s| s.is_none()).count();
        assert!(outside > 0, "some grains lie past the tube's end");
        for (p, q) in a.stencils.iter().zip(&whole.stencils) {
            assert_eq!(p.map(|s| s.node), q.map(|s| s.node));
        }
    }

    #[test]
    fn deposit_conserves_grain_volume_and_reads_uniform_packing() {
        // A regular array of grains filling the tube uniformly at solid fraction s: every
        // node away from the ends must read φ = 1 − s (the wall-cut normalisation).
        let g = paper_grid();
        let (r, h) = (0.2e-3, 0.5e-3);
        let mut x = Vec::new();
        let mut z = 0.5 * h;
        while z < 0.525 {
            let mut a = -3.5e-3 + 0.5 * h;
            while a < 3.5e-3 {
                let mut b = -3.5e-3 + 0.5 * h;
                while b < 3.5e-3 {
                    if a * a + b * b < (3.5e-3f64).powi(2) {
                        x.push([a, b, z]);
                    }
                    b += h;
                }
                a += h;
            }
            z += h;
        }
        let v = vec![[0.0, 0.0, 0.1]; x.len()];
        let rr = vec![r; x.len()];
        let mut f = GranularFields::default();
        deposit(&g, &x, &v, &rr, &mut f);
        let vol_p = 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
        let solid: Real = (0..g.len())
            .map(|j| (1.0 - f.porosity[j]) * g.volume[j])
            .sum();
        assert!((solid / (vol_p * x.len() as Real) - 1.0).abs() < 1e-12);
        let s = vol_p / h.powi(3);
        for k in 5..145 {
            for c in 0..4 {
                let j = k * 4 + c;
                // Grains sit on a lattice, the cells are quarter discs: the staircase of the
                // lattice at the wall differs from the disc by ~h/R ≈ 3 % of the area.
                assert!(
                    (f.porosity[j] - (1.0 - s)).abs() < 0.03 * s,
                    "node {j}: {}",
                    f.porosity[j]
                );
                assert!((f.velocity[j][2] - 0.1).abs() < 1e-12);
            }
        }
        // Over whole cells (`porosity_volume = "whole_cell"`) the same solid is spread over
        // the 7 × 7 mm square the 2 × 2 cells tile: each node reads its open share of it,
        // (π/4)·s, to the lattice staircase's 3 %.
        let mut whole = g.clone();
        whole.whole_cell_porosity = true;
        let mut fw = GranularFields::default();
        deposit(&whole, &x, &v, &rr, &mut fw);
        let cell = g.dz * g.dx * g.dy;
        for j in 0..g.len() {
            let solid_open = (1.0 - f.porosity[j]) * g.volume[j];
            let solid_whole = (1.0 - fw.porosity[j]) * cell;
            assert!((solid_whole - solid_open).abs() <= 1e-12 * solid_open.max(1e-18));
        }
        let quarter = std::f64::consts::FRAC_PI_4 * s;
        for j in 20..580 {
            assert!(
                ((1.0 - fw.porosity[j]) - quarter).abs() < 0.03 * quarter,
                "node {j}: {}",
                fw.porosity[j]
            );
        }
    }

    /// A slab of width w through the axis of a tube of radius R: the cells hold its area
    /// (≈ w × 2√(R² − (w/2)²) for a thin slab; 2 rows: half each) to the sampling's 0.1 %.
    #[test]
    fn slab_cells_hold_the_slab_area() {
        let (r, w) = (0.04, 3.3e-3);
        let g = TubeGrid::new_in_slab([0.0; 3], [1.0, 0.0, 0.0], r, 1.0, [10, 1, 2], Some(0.5 * w));
        let half = 0.5 * w;
        // Exact area of {|u| ≤ w/2} ∩ disc: 2 ∫ √(R² − u²) du over [−w/2, w/2].
        let f = |u: f64| u * (r * r - u * u).sqrt() + r * r * (u / r).asin();
        let exact = f(half) - f(-half);
        let sum: f64 = g.face_z.iter().sum();
        assert!((sum / exact - 1.0).abs() < 1e-3, "{sum} vs {exact}");
        assert!((g.face_z[0] / g.face_z[1] - 1.0).abs() < 1e-3);
        // The faces between the two rows: the slab's width along the axis.
        assert!(
            (g.face_y[0] / (w * g.dz) - 1.0).abs() < 1e-9,
            "{}",
            g.face_y[0]
        );
    }
}

/// The deposit spread over a length L (Lethe's and CFDEMcoupling's smoothing of the void
/// fraction): solid volume and momentum diffuse between open neighbour nodes, conserving
/// both, until the spread of a point deposit has variance L² per direction (D·T = L²/2).
/// A grid whose cells are small against the grain resolves a packing's loose rim at the wall
/// as a channel the gas takes; smoothing over about 2 d weighs the rim as the bed around it.
/// Explicit passes, each stable and positive: κ Σ_f (A_f / h_f) / V ≤ ½ at every node.
#[derive(Debug, Clone)]
pub struct Smoothing {
    /// Node pairs and their face conductance A_f / h_f, m.
    faces: Vec<(u32, u32, Real)>,
    /// κ = D Δt per pass, m².
    kappa: Real,
    passes: usize,
    /// Scratch: the concentrations of the pass (solid, 3 momentum).
    c: Vec<[Real; 4]>,
    /// Scratch: each node's change over one pass.
    delta: Vec<[Real; 4]>,
}

impl Smoothing {
    /// The passes that spread a deposit on `grid` over `length` (m, > 0).
    pub fn new(grid: &TubeGrid, length: Real) -> Self {
        let mut faces = Vec::new();
        let (nx, ny, nz) = (grid.nx, grid.ny, grid.nz);
        let col_open = |i: usize, j: usize| grid.open[i + nx * j];
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    if !col_open(i, j) {
                        continue;
                    }
                    let a = grid.node(k, i, j) as u32;
                    if i + 1 < nx && col_open(i + 1, j) {
                        let g = grid.face_x[i + (nx - 1) * j] / grid.dx;
                        faces.push((a, grid.node(k, i + 1, j) as u32, g));
                    }
                    if j + 1 < ny && col_open(i, j + 1) {
                        let g = grid.face_y[i + nx * j] / grid.dy;
                        faces.push((a, grid.node(k, i, j + 1) as u32, g));
                    }
                    let next = match (k + 1 < nz, grid.periodic && nz > 1) {
                        (true, _) => Some(k + 1),
                        (false, true) => Some(0),
                        (false, false) => None,
                    };
                    if let Some(kn) = next {
                        let g = grid.face_z[i + nx * j] / grid.dz;
                        faces.push((a, grid.node(kn, i, j) as u32, g));
                    }
                }
            }
        }
        faces.retain(|f| f.2 > 0.0);
        // The stiffest node: Σ_f g_f / V.
        let mut sum_g = vec![0.0; grid.len()];
        for &(a, b, g) in &faces {
            sum_g[a as usize] += g;
            sum_g[b as usize] += g;
        }
        let stiffest = sum_g
            .iter()
            .zip(&grid.volume)
            .filter(|(_, &v)| v > 0.0)
            .map(|(s, v)| s / v)
            .fold(0.0, Real::max);
        let total = 0.5 * length * length; // D·T, m²
        let passes = ((total * stiffest / 0.5).ceil() as usize).max(1);
        Self {
            faces,
            kappa: total / passes as Real,
            passes,
            c: Vec::new(),
            delta: Vec::new(),
        }
    }

    /// Diffusion passes per exchange.
    pub fn passes(&self) -> usize {
        self.passes
    }

    /// Explicit conservative diffusion of the concentrations in `c` (per node volume).
    fn diffuse(&mut self, volume: &[Real]) {
        let (c, delta) = (&mut self.c, &mut self.delta);
        delta.clear();
        delta.resize(c.len(), [0.0; 4]);
        for _ in 0..self.passes {
            delta.fill([0.0; 4]);
            for &(a, b, g) in &self.faces {
                let (a, b) = (a as usize, b as usize);
                for q in 0..4 {
                    // Volume crossing the face in this pass (m³ of solid, or m³·m/s).
                    let flux = self.kappa * g * (c[a][q] - c[b][q]);
                    delta[a][q] -= flux;
                    delta[b][q] += flux;
                }
            }
            for ((c, d), &v) in c.iter_mut().zip(delta.iter()).zip(volume) {
                if v > 0.0 {
                    for q in 0..4 {
                        c[q] += d[q] / v;
                    }
                }
            }
        }
    }

    /// Smooth the solid fraction and granular velocity of a deposit (and the fed grains'
    /// solid fraction, when any), in place.
    pub fn apply(&mut self, grid: &TubeGrid, fields: &mut GranularFields) {
        let n = grid.len();
        // Concentrations: solid fraction s = 1 − φ and momentum density s u.
        self.c.clear();
        self.c.extend((0..n).map(|j| {
            let s = 1.0 - fields.porosity[j];
            let u = fields.velocity[j];
            [s, s * u[0], s * u[1], s * u[2]]
        }));
        self.diffuse(&grid.volume);
        for j in 0..n {
            let [s, m0, m1, m2] = self.c[j];
            fields.porosity[j] = 1.0 - s;
            fields.velocity[j] = match s > 0.0 {
                true => [m0 / s, m1 / s, m2 / s],
                false => [0.0; 3],
            };
        }
        if !fields.fed_solid.is_empty() {
            self.c.clear();
            self.c
                .extend(fields.fed_solid.iter().map(|&f| [f, 0.0, 0.0, 0.0]));
            self.diffuse(&grid.volume);
            for (f, c) in fields.fed_solid.iter_mut().zip(&self.c) {
                *f = c[0];
            }
        }
    }
}
