//! McNamara–Flekkøy gas model (seed 000 eqs. 3–5; seed 002 §2.1): the gas pressure
//! diffuses through the grains,
//!
//!   φ ∂P'/∂t = (P0/η) ∇·(κ(φ) ∇P') − P0 ∇·u,   κ(φ) = d² φ³ / (180 (1 − φ)²)  (eq. 4),
//!
//! discretised by finite volumes on the wall-cut cells of a [`TubeGrid`]:
//!
//!   C_n dP_n/dt = Σ_f c_f (P_nb − P_n) − c_out,n P_n + b_n,
//!
//! with storage C_n = V_n φ_n, face conductance c_f = (P0/η) κ_f A_f / d_f (harmonic mean of
//! κ across the face), the outlet held at P' = 0 half a cell past the last nodes, and the
//! sources b_n = P0 v_s A_n at the inlet slice (the seeds' ∓S term: a gas flux v_s at P0)
//! minus P0 times the outward flux of the granular velocity through the cell's faces.
//!
//! The equation is very stiff (D Δt/Δx² of 1e3–1e6 between plugs), so time stepping is
//! implicit: the θ-scheme (θ = 1 backward Euler, θ = ½ Crank–Nicolson, which rings at sharp
//! porosity jumps: its amplification factor tends to −1 for stiff modes) or BDF2, which is
//! L-stable. Two solution paths: one sparse Cholesky solve of the whole system (faer, the
//! symbolic factorisation kept for the run), or directional splitting with tridiagonal
//! sweeps along each axis in turn (as the seeds did), which adds an O(Δt) splitting error.

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{SparseColMat, Triplet};
use faer::{Mat, Side};
use plugflow_coupling::{GasError, GasSolver, GasStepReport, GranularFields, TubeGrid};

use super::banded::BandCholesky;
use crate::{Real, Vec3};

/// Widest half-bandwidth the band factorisation takes (n b² flops against the sparse
/// factorisation's bookkeeping: a tube grid of up to 4 × 4 nodes across).
const BAND_MAX: usize = 16;

/// Time scheme.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Scheme {
    /// θ-scheme: 1 = backward Euler, ½ = Crank–Nicolson.
    Theta(Real),
    /// Second-order backward differences (L-stable); its first step is backward Euler.
    Bdf2,
}

/// How the linear system of a step is solved.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SolvePath {
    /// One sparse Cholesky solve (reference).
    Monolithic,
    /// Tridiagonal sweeps along the axis, then across (fast; O(Δt) splitting error).
    Splitting,
}

/// Parameters of the d'Arcy gas.
#[derive(Debug, Clone, Copy)]
pub struct DarcyParams {
    /// Background pressure P0, Pa.
    pub p0: Real,
    /// Gas (effective) viscosity η, Pa·s.
    pub viscosity: Real,
    /// Grain diameter in the Carman–Kozeny law, m.
    pub grain_diameter: Real,
    /// Superficial gas velocity at the inlet, m/s.
    pub superficial_velocity: Real,
    /// Porosity clamp, lower bound.
    pub porosity_min: Real,
    /// Porosity clamp, upper bound.
    pub porosity_max: Real,
    /// Time scheme.
    pub scheme: Scheme,
    /// Solution path.
    pub path: SolvePath,
}

/// Carman–Kozeny permeability κ(φ) = d² φ³ / (180 (1 − φ)²), m² (seed 000 eq. 4).
pub fn carman_kozeny(d: Real, phi: Real) -> Real {
    d * d * phi * phi * phi / (180.0 * (1.0 - phi) * (1.0 - phi))
}

/// A face between two nodes.
#[derive(Debug, Clone, Copy)]
struct Edge {
    a: usize,
    b: usize,
    /// Open area / distance, m.
    area_over_dist: Real,
    /// 0 = along the axis, 1 = across (e1), 2 = across (e2).
    dir: u8,
}

/// What a d'Arcy gas carries from step to step (a checkpoint; the matrices and their
/// factorisation's pattern are rebuilt from the grid, to the same bits).
#[derive(serde::Serialize, serde::Deserialize)]
struct DarcyState {
    nodes: usize,
    p: Vec<Real>,
    p_prev: Vec<Real>,
    last_dt: Option<Real>,
    steps: u64,
    phi: Vec<Real>,
    superficial_velocity: Real,
    /// A periodic section's driving gradient, Pa/m.
    #[serde(default)]
    drive_gradient: Real,
}

/// The d'Arcy gas solver.
pub struct DarcyGas {
    grid: TubeGrid,
    params: DarcyParams,
    edges: Vec<Edge>,
    /// P' now and one step ago, Pa.
    p: Vec<Real>,
    p_prev: Vec<Real>,
    /// The dt of the previous step (BDF2 needs equal steps), s.
    last_dt: Option<Real>,
    /// Clamped porosity used by the last step.
    phi: Vec<Real>,
    /// Scratch: conductance per edge, outlet conductance per node, storage, sources.
    cond: Vec<Real>,
    c_out: Vec<Real>,
    storage: Vec<Real>,
    source: Vec<Real>,
    symbolic: Option<SymbolicLlt<usize>>,
    /// The band factorisation, when the grid's system is narrow (a tube's: half-bandwidth
    /// one cross-section); the general sparse one otherwise.
    band: Option<BandCholesky>,
    /// Where each entry of [`DarcyGas::entries`] sits in the band (found on the first step).
    band_slots: Vec<usize>,
    /// The system matrix of the last step, and where each entry of [`DarcyGas::entries`]
    /// sits in its values: the pattern never changes, so later steps write the values in
    /// place instead of assembling (sorting) triplets again.
    matrix: Option<(SparseColMat<usize, Real>, Vec<usize>)>,
    /// Node indices of every grid line along the axis, e1 and e2 (for the sweeps).
    lines: [Vec<Vec<usize>>; 3],
    steps: u64,
    /// A periodic section (the grid's `periodic`): the mean pressure gradient G that drives
    /// the gas, Pa/m. The solver carries the periodic part P̃ of P' = P̃ − G s; the flow
    /// controller sets G after each step so that the section's mean superficial gas velocity
    /// is the scene's (as Lethe's flow control does with its driving force).
    drive_gradient: Real,
    /// The mean superficial gas velocity along the axis after the last step, m/s.
    mean_superficial_velocity: Real,
}

impl DarcyGas {
    /// Solver on `grid`, starting from P' = 0 everywhere.
    pub fn new(grid: TubeGrid, params: DarcyParams) -> Self {
        // 600-node systems: threads cost more than they save, and one thread keeps the
        // solve bitwise reproducible.
        faer::set_global_parallelism(faer::Par::Seq);
        let mut edges = Vec::new();
        for k in 0..grid.nz {
            for j in 0..grid.ny {
                for i in 0..grid.nx {
                    let n = grid.node(k, i, j);
                    if k + 1 < grid.nz {
                        edges.push(Edge {
                            a: n,
                            b: grid.node(k + 1, i, j),
                            area_over_dist: grid.face_z[i + grid.nx * j] / grid.dz,
                            dir: 0,
                        });
                    }
                    if i + 1 < grid.nx {
                        edges.push(Edge {
                            a: n,
                            b: grid.node(k, i + 1, j),
                            area_over_dist: grid.face_x[i + (grid.nx - 1) * j] / grid.dx,
                            dir: 1,
                        });
                    }
                    if j + 1 < grid.ny {
                        edges.push(Edge {
                            a: n,
                            b: grid.node(k, i, j + 1),
                            area_over_dist: grid.face_y[i + grid.nx * j] / grid.dy,
                            dir: 2,
                        });
                    }
                }
            }
        }
        if grid.periodic && grid.nz > 1 {
            // The seam: the last slice joined to the first, as any two neighbours.
            for j in 0..grid.ny {
                for i in 0..grid.nx {
                    edges.push(Edge {
                        a: grid.node(grid.nz - 1, i, j),
                        b: grid.node(0, i, j),
                        area_over_dist: grid.face_z[i + grid.nx * j] / grid.dz,
                        dir: 0,
                    });
                }
            }
        }
        let n = grid.len();
        // The system couples only nodes joined by an edge: its half-bandwidth.
        let half_bandwidth = edges.iter().map(|e| e.a.abs_diff(e.b)).max().unwrap_or(0);
        let (nz, nx, ny) = (grid.nz, grid.nx, grid.ny);
        let lines = [
            (0..nx * ny)
                .map(|c| (0..nz).map(|k| grid.node(k, c % nx, c / nx)).collect())
                .collect(),
            (0..nz * ny)
                .map(|c| (0..nx).map(|i| grid.node(c / ny, i, c % ny)).collect())
                .collect(),
            (0..nz * nx)
                .map(|c| (0..ny).map(|j| grid.node(c / nx, c % nx, j)).collect())
                .collect(),
        ];
        Self {
            lines,
            edges,
            p: vec![0.0; n],
            p_prev: vec![0.0; n],
            last_dt: None,
            phi: vec![1.0; n],
            cond: Vec::new(),
            c_out: vec![0.0; n],
            storage: vec![0.0; n],
            source: vec![0.0; n],
            symbolic: None,
            band: (half_bandwidth <= BAND_MAX).then(|| BandCholesky::new(n, half_bandwidth)),
            band_slots: Vec::new(),
            matrix: None,
            steps: 0,
            // The empty tube's gradient for the target flow: the controller's first guess.
            drive_gradient: params.viscosity * params.superficial_velocity
                / carman_kozeny(params.grain_diameter, params.porosity_max),
            mean_superficial_velocity: 0.0,
            grid,
            params,
        }
    }

    /// A periodic section's driving gradient G, Pa/m (the controller's last value).
    pub fn drive_gradient(&self) -> Real {
        self.drive_gradient
    }

    /// The section's mean superficial gas velocity along the axis after the last step, m/s:
    /// (1/V) ∫ (φ u_s − (κ/η) ∂P/∂s) dV, the d'Arcy flux through every axial face plus the
    /// gas the grains carry.
    pub fn mean_superficial_velocity(&self) -> Real {
        self.mean_superficial_velocity
    }

    /// Periodic sections: the mean superficial gas velocity of the pressures `p` (P̃) under
    /// the gradient G, and dU/dG at fixed P̃ (the flow controller's sensitivity).
    fn section_flow(&self, p: &[Real], velocity: &[Vec3]) -> (Real, Real) {
        let g = &self.grid;
        let p0 = self.params.p0;
        let volume: Real = g.volume.iter().sum();
        let (mut flow, mut slope) = (0.0, 0.0);
        for (e, c) in self.edges.iter().zip(&self.cond) {
            if e.dir == 0 {
                // (c / P0) ΔP is the face's volume flux (m³/s); times dz, its share of ∫ U dV.
                flow += c / p0 * (p[e.a] - p[e.b] + self.drive_gradient * g.dz) * g.dz;
                slope += c / p0 * g.dz * g.dz;
            }
        }
        for n in 0..g.len() {
            flow += g.volume[n] * self.phi[n] * self.component(velocity[n], 0);
        }
        (flow / volume, slope / volume)
    }

    /// Set P' on the nodes (tests and restarts), Pa; forgets the previous step.
    pub fn set_pressure(&mut self, p: &[Real]) {
        self.p.copy_from_slice(p);
        self.p_prev.copy_from_slice(p);
        self.last_dt = None;
    }

    /// Fill conductances, storage and sources for the fields of this step; the nodes whose
    /// porosity was clamped (all, and those below φ_min: over-packed).
    fn assemble(&mut self, fields: &GranularFields) -> (usize, usize) {
        let g = &self.grid;
        let pr = &self.params;
        let (mut clamped, mut low) = (0, 0);
        for (n, &phi) in fields.porosity.iter().enumerate() {
            let c = phi.clamp(pr.porosity_min, pr.porosity_max);
            if c != phi {
                clamped += 1;
                if phi < pr.porosity_min {
                    low += 1;
                }
            }
            self.phi[n] = c;
        }
        let kappa: Vec<Real> = self
            .phi
            .iter()
            .map(|&f| carman_kozeny(pr.grain_diameter, f))
            .collect();
        let scale = pr.p0 / pr.viscosity;
        self.cond.clear();
        for e in &self.edges {
            let (ka, kb) = (kappa[e.a], kappa[e.b]);
            let harmonic = 2.0 * ka * kb / (ka + kb);
            self.cond.push(scale * harmonic * e.area_over_dist);
        }
        for n in 0..g.len() {
            self.storage[n] = g.volume[n] * self.phi[n];
            self.c_out[n] = 0.0;
            self.source[n] = 0.0;
        }
        let last = g.nz - 1;
        if g.periodic {
            // No inlet or outlet: the gradient G drives the gas across every axial face
            // (P_a − P_b = P̃_a − P̃_b + G dz), a known part moved to the sources.
            for (e, c) in self.edges.iter().zip(&self.cond) {
                if e.dir == 0 {
                    let push = c * self.drive_gradient * g.dz;
                    self.source[e.a] -= push;
                    self.source[e.b] += push;
                }
            }
        } else {
            for j in 0..g.ny {
                for i in 0..g.nx {
                    let area = g.face_z[i + g.nx * j];
                    let n_in = g.node(0, i, j);
                    self.source[n_in] += pr.p0 * pr.superficial_velocity * area;
                    let n_out = g.node(last, i, j);
                    self.c_out[n_out] = scale * kappa[n_out] * area / (0.5 * g.dz);
                }
            }
        }
        // −P0 ∇·u in flux form: the granular velocity through each face (average of the
        // two nodes); the inlet end is closed to grains, the outlet lets them pass.
        let u = &fields.velocity;
        for e in &self.edges {
            let d = e.dir as usize;
            let (ua, ub) = (self.component(u[e.a], d), self.component(u[e.b], d));
            let area = e.area_over_dist
                * match d {
                    0 => g.dz,
                    1 => g.dx,
                    _ => g.dy,
                };
            let flux = 0.5 * (ua + ub) * area; // from a to b
            self.source[e.a] -= pr.p0 * flux;
            self.source[e.b] += pr.p0 * flux;
        }
        if !g.periodic {
            for j in 0..g.ny {
                for i in 0..g.nx {
                    let n = g.node(last, i, j);
                    let flux = self.component(u[n], 0).max(0.0) * g.face_z[i + g.nx * j];
                    self.source[n] -= pr.p0 * flux;
                }
            }
        }
        (clamped, low)
    }

    /// Component of a lab-frame vector along grid direction `d`.
    fn component(&self, v: Vec3, d: usize) -> Real {
        let a = match d {
            0 => self.grid.axis,
            1 => self.grid.e1,
            _ => self.grid.e2,
        };
        v[0] * a[0] + v[1] * a[1] + v[2] * a[2]
    }

    /// (L P)_n = Σ_f c_f (P_n − P_nb) + c_out P_n.
    fn apply_l(&self, p: &[Real], out: &mut [Real]) {
        for n in 0..out.len() {
            out[n] = self.c_out[n] * p[n];
        }
        for (e, c) in self.edges.iter().zip(&self.cond) {
            let f = c * (p[e.a] - p[e.b]);
            out[e.a] += f;
            out[e.b] -= f;
        }
    }

    /// Solve (diag + w L) x = rhs over the whole grid with sparse Cholesky.
    /// (row, column) of each entry of the lower triangle of the system matrix, in the order
    /// of [`DarcyGas::entries`]: the edges' off-diagonal entries, then the diagonal.
    fn entry_positions(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        let n = self.c_out.len();
        self.edges
            .iter()
            .map(|e| if e.a > e.b { (e.a, e.b) } else { (e.b, e.a) })
            .chain((0..n).map(|k| (k, k)))
    }

    /// The values of the lower triangle of diag + w (L + outflow), in the order of
    /// [`DarcyGas::entry_positions`].
    fn entries(&self, diag: &[Real], w: Real) -> Vec<Real> {
        let n = diag.len();
        let mut d: Vec<Real> = (0..n).map(|k| diag[k] + w * self.c_out[k]).collect();
        let mut values = Vec::with_capacity(self.edges.len() + n);
        for (e, c) in self.edges.iter().zip(&self.cond) {
            d[e.a] += w * c;
            d[e.b] += w * c;
            values.push(-w * c);
        }
        values.extend_from_slice(&d);
        values
    }

    fn solve_monolithic(
        &mut self,
        diag: &[Real],
        w: Real,
        rhs: &[Real],
    ) -> Result<Vec<Real>, String> {
        let n = rhs.len();
        let values = self.entries(diag, w);
        // (Taken out while in use, so that the grid's entries and residual can be read.)
        if let Some(mut band) = self.band.take() {
            if self.band_slots.is_empty() {
                let slots: Result<Vec<usize>, String> = self
                    .entry_positions()
                    .map(|(i, j)| band.slot(i, j))
                    .collect();
                match slots {
                    Ok(slots) => self.band_slots = slots,
                    Err(e) => {
                        self.band = Some(band);
                        return Err(e);
                    }
                }
            }
            band.set_at(&self.band_slots, &values);
            let solved = band.factor().map(|_| {
                let mut x = rhs.to_vec();
                band.solve_in_place(&mut x);
                // One step of iterative refinement, as below.
                let mut residual = self.residual(diag, w, rhs, &x);
                band.solve_in_place(&mut residual);
                (0..n).map(|i| x[i] + residual[i]).collect()
            });
            self.band = Some(band);
            return solved;
        }
        if self.matrix.is_none() {
            // The pattern once, from triplets; then where each entry landed, read off a
            // matrix whose values are the entries' own indices (every entry is distinct).
            let trip = |v: &dyn Fn(usize) -> Real| -> Result<SparseColMat<usize, Real>, String> {
                let t: Vec<Triplet<usize, usize, Real>> = self
                    .entry_positions()
                    .enumerate()
                    .map(|(k, (r, c))| Triplet::new(r, c, v(k)))
                    .collect();
                SparseColMat::<usize, Real>::try_new_from_triplets(n, n, &t)
                    .map_err(|e| format!("matrix assembly: {e:?}"))
            };
            let numbered = trip(&|k| k as Real)?;
            let mut slot = vec![0usize; values.len()];
            for (at, &k) in numbered.val().iter().enumerate() {
                slot[k as usize] = at;
            }
            let mat = trip(&|k| values[k])?;
            self.matrix = Some((mat, slot));
        } else if let Some((mat, slot)) = self.matrix.as_mut() {
            let val = mat.val_mut();
            for (k, &at) in slot.iter().enumerate() {
                val[at] = values[k];
            }
        }
        let mat = &self.matrix.as_ref().expect("just built").0;
        if self.symbolic.is_none() {
            self.symbolic = Some(
                SymbolicLlt::try_new(mat.symbolic(), Side::Lower)
                    .map_err(|e| format!("symbolic factorisation: {e:?}"))?,
            );
        }
        let sym = self.symbolic.clone().expect("just built");
        let llt = Llt::try_new_with_symbolic(sym, mat.as_ref(), Side::Lower)
            .map_err(|e| format!("numeric factorisation: {e:?}"))?;
        let mut x = Mat::<Real>::from_fn(n, 1, |i, _| rhs[i]);
        llt.solve_in_place(x.as_mut());
        // One step of iterative refinement: the stiff systems (conductances 1e5 × storage/dt)
        // leave ~1e-10 relative round-off after one solve; refinement brings the gas mass
        // balance back to ~1e-14.
        let xs: Vec<Real> = (0..n).map(|i| x[(i, 0)]).collect();
        let r = self.residual(diag, w, rhs, &xs);
        let mut residual = Mat::<Real>::from_fn(n, 1, |i, _| r[i]);
        llt.solve_in_place(residual.as_mut());
        Ok((0..n).map(|i| xs[i] + residual[(i, 0)]).collect())
    }

    /// rhs − (diag + w (L + outflow)) x.
    fn residual(&self, diag: &[Real], w: Real, rhs: &[Real], x: &[Real]) -> Vec<Real> {
        let mut r: Vec<Real> = (0..x.len())
            .map(|i| rhs[i] - (diag[i] + w * self.c_out[i]) * x[i])
            .collect();
        for (e, c) in self.edges.iter().zip(&self.cond) {
            let f = w * c * (x[e.a] - x[e.b]);
            r[e.a] -= f;
            r[e.b] += f;
        }
        r
    }

    /// Solve (diag + w L_d) x = rhs along the lines of direction `d`, with one step of
    /// iterative refinement (as the monolithic path: stiff lines leave ~1e-10 round-off).
    fn sweep(&self, diag: &[Real], w: Real, rhs: &[Real], d: u8) -> Vec<Real> {
        let mut x = self.thomas(diag, w, rhs, d);
        let mut r: Vec<Real> = (0..rhs.len())
            .map(|k| {
                let out = if d == 0 { self.c_out[k] } else { 0.0 };
                rhs[k] - (diag[k] + w * out) * x[k]
            })
            .collect();
        for (e, c) in self.edges.iter().zip(&self.cond) {
            if e.dir == d {
                let f = w * c * (x[e.a] - x[e.b]);
                r[e.a] -= f;
                r[e.b] += f;
            }
        }
        let dx = self.thomas(diag, w, &r, d);
        for (xi, di) in x.iter_mut().zip(dx) {
            *xi += di;
        }
        x
    }

    /// Tridiagonal solves of (diag + w L_d) x = rhs along every line of direction `d`.
    fn thomas(&self, diag: &[Real], w: Real, rhs: &[Real], d: u8) -> Vec<Real> {
        let n = rhs.len();
        // Tridiagonal rows: lower[n], main[n], upper[n] in line order.
        let mut main: Vec<Real> = diag.to_vec();
        if d == 0 {
            for k in 0..n {
                main[k] += w * self.c_out[k];
            }
        }
        let mut to_next = vec![0.0; n]; // coupling of node with its successor on the line
        for (e, c) in self.edges.iter().zip(&self.cond) {
            if e.dir == d {
                main[e.a] += w * c;
                main[e.b] += w * c;
                to_next[e.a] = -w * c;
            }
        }
        let lines = &self.lines[d as usize];
        let len = lines.first().map_or(0, |l| l.len());
        let mut x = vec![0.0; n];
        let mut cp = vec![0.0; len];
        let mut dp = vec![0.0; len];
        for line in lines {
            for m in 0..len {
                let node = line[m];
                let lower = if m > 0 { to_next[line[m - 1]] } else { 0.0 };
                let upper = if m + 1 < len { to_next[node] } else { 0.0 };
                let denom = main[node] - if m > 0 { lower * cp[m - 1] } else { 0.0 };
                cp[m] = upper / denom;
                dp[m] = (rhs[node] - if m > 0 { lower * dp[m - 1] } else { 0.0 }) / denom;
            }
            for m in (0..len).rev() {
                let node = line[m];
                x[node] = dp[m]
                    - if m + 1 < len {
                        cp[m] * x[line[m + 1]]
                    } else {
                        0.0
                    };
            }
        }
        x
    }
}

impl GasSolver for DarcyGas {
    fn name(&self) -> &'static str {
        "darcy"
    }

    fn grid(&self) -> &TubeGrid {
        &self.grid
    }

    fn set_superficial_velocity(&mut self, v: Real) {
        self.params.superficial_velocity = v;
    }

    fn superficial_velocity(&self) -> Real {
        self.params.superficial_velocity
    }

    fn step(&mut self, fields: &GranularFields, dt: Real) -> Result<GasStepReport, GasError> {
        let n = self.grid.len();
        let (clamped, clamped_low) = self.assemble(fields);
        let step = self.steps + 1;
        let bdf2 = self.params.scheme == Scheme::Bdf2
            && self.last_dt.is_some_and(|h| (h - dt).abs() <= 1e-12 * dt);
        let theta = match self.params.scheme {
            Scheme::Theta(t) => t,
            Scheme::Bdf2 => 1.0, // first step (or a changed dt): backward Euler
        };
        // diag·P^{n+1} + w L P^{n+1} = rhs
        let (diag, w, rhs): (Vec<Real>, Real, Vec<Real>) = if bdf2 {
            let diag: Vec<Real> = self.storage.iter().map(|c| 1.5 * c / dt).collect();
            let rhs = (0..n)
                .map(|k| {
                    self.storage[k] / dt * (2.0 * self.p[k] - 0.5 * self.p_prev[k]) + self.source[k]
                })
                .collect();
            (diag, 1.0, rhs)
        } else {
            let mut lp = vec![0.0; n];
            self.apply_l(&self.p, &mut lp);
            let diag: Vec<Real> = self.storage.iter().map(|c| c / dt).collect();
            let rhs = (0..n)
                .map(|k| diag[k] * self.p[k] - (1.0 - theta) * lp[k] + self.source[k])
                .collect();
            (diag, theta, rhs)
        };
        // Outflow through the outlet as the scheme counts it, for the mass balance.
        let c_out = self.c_out.clone();
        let out_flux = |p: &[Real]| -> Real { (0..n).map(|k| c_out[k] * p[k]).sum() };
        let explicit_out = if bdf2 {
            0.0
        } else {
            (1.0 - theta) * out_flux(&self.p)
        };
        let (new_p, implicit_out) = match self.params.path {
            SolvePath::Monolithic => {
                let x = self
                    .solve_monolithic(&diag, w, &rhs)
                    .map_err(|reason| GasError::Solve { step, reason })?;
                let o = w * out_flux(&x);
                (x, o)
            }
            SolvePath::Splitting => {
                let p1 = self.sweep(&diag, w, &rhs, 0);
                let o = w * out_flux(&p1);
                let mut x = p1;
                for d in 1..3u8 {
                    let has = self.edges.iter().any(|e| e.dir == d);
                    if has {
                        let r: Vec<Real> = (0..n).map(|k| diag[k] * x[k]).collect();
                        x = self.sweep(&diag, w, &r, d);
                    }
                }
                (x, o)
            }
        };
        if let Some(bad) = new_p.iter().position(|v| !v.is_finite()) {
            return Err(GasError::NonFinite {
                step,
                node: bad,
                slice: bad / (self.grid.nx * self.grid.ny),
            });
        }
        // Global balance: Σ storage change = sources − outflow (interior fluxes cancel).
        let storage_change: Real = if bdf2 {
            (0..n)
                .map(|k| {
                    self.storage[k] * (1.5 * new_p[k] - 2.0 * self.p[k] + 0.5 * self.p_prev[k]) / dt
                })
                .sum()
        } else {
            (0..n)
                .map(|k| self.storage[k] * (new_p[k] - self.p[k]) / dt)
                .sum()
        };
        let sources: Real = self.source.iter().sum();
        let balance = storage_change - (sources - implicit_out - explicit_out);
        let scale = sources.abs() + implicit_out.abs() + explicit_out.abs() + storage_change.abs();
        let mass_error_rel = if scale > 0.0 {
            balance.abs() / scale
        } else {
            0.0
        };
        if self.grid.periodic {
            // The flow controller: U is linear in G at fixed P̃ with slope dU/dG; the step
            // to the target is taken whole (a uniform bed then holds U exactly; P̃ answers
            // a non-uniform one within a few steps).
            let (flow, slope) = self.section_flow(&new_p, &fields.velocity);
            self.mean_superficial_velocity = flow;
            if slope > 0.0 {
                self.drive_gradient += (self.params.superficial_velocity - flow) / slope;
            }
        }
        self.p_prev = std::mem::replace(&mut self.p, new_p);
        self.last_dt = Some(dt);
        self.steps = step;
        Ok(GasStepReport {
            clamped_nodes: clamped,
            clamped_low_nodes: clamped_low,
            mass_error_rel,
        })
    }

    fn pressure(&self) -> &[Real] {
        &self.p
    }

    fn save_state(&self) -> Result<Vec<u8>, GasError> {
        let state = DarcyState {
            nodes: self.grid.len(),
            p: self.p.clone(),
            p_prev: self.p_prev.clone(),
            last_dt: self.last_dt,
            steps: self.steps,
            phi: self.phi.clone(),
            superficial_velocity: self.params.superficial_velocity,
            drive_gradient: self.drive_gradient,
        };
        super::encode_state(&state, "d'Arcy")
    }

    fn restore_state(&mut self, bytes: &[u8]) -> Result<(), GasError> {
        let n = self.grid.len();
        let s: DarcyState = super::decode_state(bytes, "d'Arcy", |s: &DarcyState| {
            let fits = [s.nodes, s.p.len(), s.p_prev.len(), s.phi.len()]
                .iter()
                .all(|&l| l == n);
            (!fits).then(|| {
                format!(
                    "written for a grid of {} nodes, the scene's has {n}",
                    s.nodes
                )
            })
        })?;
        self.p = s.p;
        self.p_prev = s.p_prev;
        self.last_dt = s.last_dt;
        self.steps = s.steps;
        self.phi = s.phi;
        self.params.superficial_velocity = s.superficial_velocity;
        if self.grid.periodic {
            self.drive_gradient = s.drive_gradient;
        }
        Ok(())
    }

    fn step_doubling_error(
        &mut self,
        fields: &GranularFields,
        dt: Real,
    ) -> Result<Option<Real>, GasError> {
        // What a step changes: pressures, the scheme's memory, the step count and the
        // porosity it used (scratch arrays are rebuilt by every step).
        // (And a periodic section's driving gradient and measured flow.)
        let saved = (
            self.p.clone(),
            self.p_prev.clone(),
            self.last_dt,
            self.steps,
            self.phi.clone(),
            (self.drive_gradient, self.mean_superficial_velocity),
        );
        type Saved = (
            Vec<Real>,
            Vec<Real>,
            Option<Real>,
            u64,
            Vec<Real>,
            (Real, Real),
        );
        let restore = |me: &mut Self, s: &Saved| {
            me.p.clone_from(&s.0);
            me.p_prev.clone_from(&s.1);
            me.last_dt = s.2;
            me.steps = s.3;
            me.phi.clone_from(&s.4);
            (me.drive_gradient, me.mean_superficial_velocity) = s.5;
        };
        let one = self.step(fields, dt).map(|_| self.p.clone());
        restore(self, &saved);
        let two = one.and_then(|one| {
            self.step(fields, 0.5 * dt)?;
            self.step(fields, 0.5 * dt)?;
            Ok(one)
        });
        let half = self.p.clone();
        restore(self, &saved);
        let one = two?;
        let scale = half.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
        let diff = one
            .iter()
            .zip(&half)
            .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
        Ok(Some(if scale > 0.0 { diff / scale } else { diff }))
    }

    fn porosity(&self) -> &[Real] {
        &self.phi
    }

    fn pressure_gradient(&self) -> Vec<Vec3> {
        let g = &self.grid;
        let pr = &self.params;
        let mut grad = vec![[0.0; 3]; g.len()];
        for k in 0..g.nz {
            for j in 0..g.ny {
                for i in 0..g.nx {
                    let n = g.node(k, i, j);
                    let p = &self.p;
                    // Along the axis: central differences; at the inlet the flux condition
                    // −(κ/η) ∂P/∂s = v_s, at the outlet P' = 0 half a cell beyond.
                    let ds = if g.periodic && g.nz > 1 {
                        // P' = P̃ − G s: P̃'s central difference around the seam, less G.
                        let up = p[g.node((k + 1) % g.nz, i, j)];
                        let down = p[g.node((k + g.nz - 1) % g.nz, i, j)];
                        (up - down) / (2.0 * g.dz) - self.drive_gradient
                    } else if g.nz == 1 {
                        -p[n] / (0.5 * g.dz)
                    } else if k == 0 {
                        let inlet = -pr.viscosity * pr.superficial_velocity
                            / carman_kozeny(pr.grain_diameter, self.phi[n]);
                        0.5 * (inlet + (p[g.node(1, i, j)] - p[n]) / g.dz)
                    } else if k + 1 == g.nz {
                        0.5 * ((p[n] - p[g.node(k - 1, i, j)]) / g.dz + (0.0 - p[n]) / (0.5 * g.dz))
                    } else {
                        (p[g.node(k + 1, i, j)] - p[g.node(k - 1, i, j)]) / (2.0 * g.dz)
                    };
                    // Across: one-sided at the wall's nodes, central inside; the m-th node
                    // of the line is at base + m·stride (no closure object per node: this
                    // runs for every node at every exchange).
                    let across = |m: usize, count: usize, h: Real, base: usize, stride: usize| {
                        let at = |q: usize| p[base + q * stride];
                        if count == 1 {
                            0.0
                        } else if m == 0 {
                            (at(1) - at(0)) / h
                        } else if m + 1 == count {
                            (at(m) - at(m - 1)) / h
                        } else {
                            (at(m + 1) - at(m - 1)) / (2.0 * h)
                        }
                    };
                    let du = across(i, g.nx, g.dx, g.node(k, 0, j), 1);
                    let dw = across(j, g.ny, g.dy, g.node(k, i, 0), g.nx);
                    for c in 0..3 {
                        grad[n][c] = ds * g.axis[c] + du * g.e1[c] + dw * g.e2[c];
                    }
                }
            }
        }
        grad
    }

    fn mean_superficial_velocity(&self) -> Option<Real> {
        self.grid.periodic.then_some(self.mean_superficial_velocity)
    }

    fn pressure_drop_per_length(&self) -> Real {
        if self.grid.periodic {
            // The mean of −∂P'/∂s over a period: G (P̃ is periodic).
            return self.drive_gradient;
        }
        let g = &self.grid;
        let (mut sum, mut area) = (0.0, 0.0);
        for j in 0..g.ny {
            for i in 0..g.nx {
                let a = g.face_z[i + g.nx * j];
                sum += a * self.p[g.node(0, i, j)];
                area += a;
            }
        }
        // The first nodes sit half a cell above the inlet; the outlet is at P' = 0.
        (sum / area) / (g.length - 0.5 * g.dz)
    }
}
