//! The SIMPLE iteration on a [`Geometry`]: momentum with the drag implicit, pressure
//! correction by sparse Cholesky, density and porosity on the faces.

use super::*;

/// Buffers of one SIMPLE iteration: the starred velocities, each face's 1/a_P (relaxed),
/// one component's momentum rows, the interphase coefficient of every cell.
#[derive(Clone, Default)]
pub(super) struct IterationScratch {
    star: [Vec<Real>; 3],
    du: [Vec<Real>; 3],
    rows: Vec<Row>,
    beta: Vec<Real>,
}

/// The SIMPLE gas on a staggered grid.
#[derive(Clone)]
pub struct SimpleGas {
    pub params: SimpleParams,
    /// The drag law whose coefficient β/(1 − ε) gives the interphase term (the grains' own:
    /// [`SimpleGas::set_drag_law`]); Ergun / Wen–Yu with the gas's viscosity by default.
    pub(super) drag_law: Arc<dyn DragLaw>,
    pub geometry: Geometry,
    /// Velocity component d on the faces normal to d, m/s (interstitial).
    pub vel: [Vec<Real>; 3],
    /// Pressure at cell centres, Pa (0 at the outlet face).
    pub p: Vec<Real>,
    /// Porosity at cell centres.
    pub porosity: Vec<Real>,
    /// Gas density at cell centres, kg/m³.
    pub rho: Vec<Real>,
    /// ρε of every cell at the end of the last time step (None before the first).
    pub(super) prev_mass: Option<Vec<Real>>,
    /// Solid fraction of the grains fed into each cell since the last step (they enter
    /// with their gas: counted as present at the step's start too). Empty: none.
    pub fed_solid: Vec<Real>,
    /// Grain velocity at cell centres (components along the grid's directions), m/s.
    pub grain_velocity: Vec<[Real; 3]>,
    /// Each component's momentum stencils, in sweep order.
    pub(super) stencils: [Vec<FaceStencil>; 3],
    /// Each stencil's face, cells and area alone, in the same order: what the pressure
    /// correction reads, without dragging the whole stencils through the cache.
    pub(super) links: [Vec<FaceLink>; 3],
    /// The cells beside every face (per direction).
    pub(super) face_cells: [Vec<(usize, usize)>; 3],
    pub(super) symbolic: Option<SymbolicLlt<usize>>,
    /// Scratch of the flow controller: each axial plane's answer to G.
    pub(super) plane_answer: Vec<Real>,
    /// The SIMPLE iteration's buffers (no state: refilled every iteration).
    pub(super) scratch: IterationScratch,
    /// The pressure correction's working storage (and the factorisation of this step).
    pub(super) pressure: PressureSystem,
    /// The pressure-correction matrix's pattern and the order its values are pushed in
    /// (the same every iteration: built once).
    pub(super) pattern: Option<(SymbolicSparseColMat<usize>, Argsort<usize>)>,
    /// A periodic grid's driving gradient G, Pa/m: the pressure is p̃ − G s with p̃ periodic
    /// (`p` holds p̃), so G pushes every axial face's gas as ε G per volume. The flow
    /// controller sets it within each step to hold the mean superficial velocity
    /// `params.inlet_velocity` (Lethe's flow control, taken to convergence).
    pub drive_gradient: Real,
    /// A periodic grid's mean superficial velocity along the flow at the end of the last
    /// solve, m/s: (1/V) ∫ ε u dV (the quantity the controller holds).
    pub mean_superficial_velocity: Real,
    /// The controller holds the gas's mean interstitial velocity ∫ ε u dV / ∫ ε dV (Lethe's
    /// flow control) instead of the mean superficial one.
    pub control_interstitial: bool,
}

impl SimpleGas {
    /// Gas at rest across (u = U along the flow on the open faces), p = 0, porosity 1,
    /// grains at rest.
    pub fn new(params: SimpleParams, geometry: Geometry) -> Self {
        faer::set_global_parallelism(faer::Par::Seq);
        let cells = geometry.cells();
        let vel = std::array::from_fn(|d| {
            (0..geometry.faces(d))
                .map(|f| {
                    if d == 0 && geometry.area[0][f] > 0.0 {
                        params.inlet_velocity
                    } else {
                        0.0
                    }
                })
                .collect()
        });
        let stencils: [Vec<FaceStencil>; 3] = std::array::from_fn(|d| geometry.stencils(d));
        let links = std::array::from_fn(|d| {
            stencils[d]
                .iter()
                .map(|st| FaceLink {
                    face: st.face,
                    lo: st.lo,
                    hi: st.hi,
                    area: st.area,
                })
                .collect()
        });
        let face_cells = std::array::from_fn(|d| geometry.face_cells(d));
        Self {
            drag_law: Arc::new(ErgunWenYu::new(params.viscosity)),
            vel,
            p: vec![0.0; cells],
            porosity: vec![1.0; cells],
            rho: vec![params.density; cells],
            prev_mass: None,
            fed_solid: Vec::new(),
            grain_velocity: vec![[0.0; 3]; cells],
            stencils,
            links,
            face_cells,
            symbolic: None,
            pattern: None,
            plane_answer: Vec::new(),
            scratch: IterationScratch::default(),
            pressure: PressureSystem::default(),
            drive_gradient: 0.0,
            mean_superficial_velocity: params.inlet_velocity,
            control_interstitial: false,
            params,
            geometry,
        }
    }

    /// Density from the pressure (ideal gas); an absolute pressure at or below zero is an
    /// error naming the cell.
    pub(super) fn update_density(&mut self) -> Result<(), String> {
        let Some(p0) = self.params.ideal_gas_pressure else {
            return Ok(());
        };
        for (c, (r, p)) in self.rho.iter_mut().zip(&self.p).enumerate() {
            let ratio = 1.0 + p / p0;
            if ratio <= 0.0 {
                return Err(format!(
                    "absolute pressure {:.4e} Pa ≤ 0 in cell {c} (ideal gas)",
                    p0 + p
                ));
            }
            *r = self.params.density * ratio;
        }
        Ok(())
    }

    /// Gas mass per mixture volume, ρε, of every cell, kg/m³.
    pub(super) fn cell_mass(&self) -> Vec<Real> {
        self.rho
            .iter()
            .zip(&self.porosity)
            .map(|(r, e)| r * e)
            .collect()
    }

    /// The pressure correction's factorisations and conjugate-gradient iterations so far.
    pub fn pressure_solves(&self) -> (usize, usize) {
        (self.pressure.factorisations, self.pressure.cg_iterations)
    }

    /// Gas mass in the grid, kg.
    pub fn gas_mass(&self) -> Real {
        self.cell_mass()
            .iter()
            .zip(&self.geometry.volume)
            .map(|(m, v)| m * v)
            .sum()
    }

    /// A cell-centred field on the face normal to d at x: the mean of the two cells beside
    /// it, the one cell's value on the grid's boundary.
    pub(super) fn on_face(&self, field: &[Real], d: usize, x: [usize; 3]) -> Real {
        let g = &self.geometry;
        if x[d] == 0 {
            field[g.cell(x)]
        } else if x[d] == g.n[d] {
            field[g.cell(minus(x, d))]
        } else {
            0.5 * (field[g.cell(minus(x, d))] + field[g.cell(x)])
        }
    }

    /// Mass flow through the face normal to d at x (positive along d), kg/s.
    pub(super) fn mass_flow(&self, vel: &[Vec<Real>; 3], d: usize, x: [usize; 3]) -> Real {
        let f = self.geometry.face(d, x);
        self.on_face(&self.rho, d, x)
            * self.on_face(&self.porosity, d, x)
            * vel[d][f]
            * self.geometry.area[d][f]
    }

    /// Gas mass flow out through the outlet, kg/s.
    pub fn outlet_mass_flow(&self) -> Real {
        let n = self.geometry.n;
        Geometry::each([1, n[1], n[2]])
            .map(|x| self.mass_flow(&self.vel, 0, [n[0], x[1], x[2]]))
            .sum()
    }

    /// Gas velocity at the centre of cell x (each component the mean of its two faces), m/s.
    pub(super) fn centre_velocity(&self, x: [usize; 3]) -> [Real; 3] {
        let g = &self.geometry;
        std::array::from_fn(|d| {
            0.5 * (self.vel[d][g.face(d, x)] + self.vel[d][g.face(d, plus(x, d))])
        })
    }

    /// Take the interphase coefficient from `law` (the one the grains feel), which must be a
    /// law of the slip.
    pub fn set_drag_law(&mut self, law: Arc<dyn DragLaw>) -> Result<(), String> {
        if law.slip_coefficient(0.5, 1.0, 1e-3, 1.0).is_none() {
            return Err(format!(
                "the `{}` drag is not a law of the gas's slip; the simple gas needs one \
                 (ergun_wen_yu, di_felice)",
                law.name()
            ));
        }
        self.drag_law = law;
        Ok(())
    }

    /// Interphase coefficient β at every cell from the current slip, kg/(m³ s).
    pub(super) fn beta(&self, b: &mut Vec<Real>) {
        let g = &self.geometry;
        b.clear();
        b.resize(g.cells(), 0.0);
        let Some(d) = self.params.drag_diameter else {
            return;
        };
        for x in Geometry::each(g.n) {
            let c = g.cell(x);
            let eps = self.porosity[c];
            if eps >= 1.0 || g.volume[c] == 0.0 {
                continue;
            }
            let u = self.centre_velocity(x);
            let v = self.grain_velocity[c];
            let w = ((u[0] - v[0]).powi(2) + (u[1] - v[1]).powi(2) + (u[2] - v[2]).powi(2)).sqrt();
            // (set_drag_law admits only laws of the slip.)
            let per_solid = self.drag_law.slip_coefficient(eps, w, d, self.rho[c]);
            b[c] = (1.0 - eps) * per_solid.unwrap_or(0.0);
        }
    }

    /// The inlet's mass flux ρ0 U as interstitial u on the inlet's open faces.
    pub(super) fn apply_inlet(&mut self, faces: &FaceFields) {
        let g = &self.geometry;
        if g.periodic {
            return;
        }
        let flux = self.params.density * self.params.inlet_velocity * g.flow_area / g.inlet_area();
        for x in Geometry::each([1, g.n[1], g.n[2]]) {
            let f = g.face(0, x);
            if g.area[0][f] > 0.0 {
                self.vel[0][f] = flux / (faces.density[0][f] * faces.porosity[0][f]);
            }
        }
    }

    /// A cell-centred field on every face (see [`SimpleGas::on_face`]).
    pub(super) fn on_faces(&self, field: &[Real]) -> [Vec<Real>; 3] {
        std::array::from_fn(|d| {
            self.face_cells[d]
                .iter()
                .map(|&(lo, hi)| match (lo, hi) {
                    // (No open cell beside: a closed face, never used.)
                    (NONE, NONE) => 0.0,
                    (lo, NONE) => field[lo],
                    (NONE, hi) => field[hi],
                    (lo, hi) => 0.5 * (field[lo] + field[hi]),
                })
                .collect()
        })
    }

    /// Steady state: SIMPLE iterations until the mass imbalance falls below `tol` of the
    /// inlet mass flow (or `max_iter`).
    pub fn solve_steady(&mut self, tol: Real, max_iter: usize) -> Result<SimpleReport, String> {
        self.iterate(None, tol, max_iter)
    }

    /// One time step of `dt` from the present state (SIMPLE iterations within the step).
    /// Continuity carries ∂(ρε)/∂t: the porosity set since the last step (grains moving in
    /// or out of a cell displace gas) and, for an ideal gas, the density's change.
    pub fn step(&mut self, dt: Real, tol: Real, max_iter: usize) -> Result<SimpleReport, String> {
        let old = self.vel.clone();
        let mut mass_old = self.prev_mass.take().unwrap_or_else(|| self.cell_mass());
        let saved_mass = mass_old.clone();
        for ((m, f), r) in mass_old.iter_mut().zip(&self.fed_solid).zip(&self.rho) {
            *m -= r * f;
        }
        self.fed_solid.clear();
        let r = self.iterate(Some((dt, old, mass_old)), tol, max_iter);
        self.prev_mass = Some(if r.is_ok() {
            self.cell_mass()
        } else {
            saved_mass
        });
        r
    }

    /// The momentum equations of component d on its unknown faces.
    pub(super) fn momentum(
        &self,
        d: usize,
        faces: &FaceFields,
        beta: &[Real],
        transient: Option<&Transient>,
        rows: &mut Vec<Row>,
    ) {
        let g = &self.geometry;
        let hd = g.h[d];
        let mu = self.params.viscosity;
        let alpha = self.params.relax_velocity;
        let (vel, por, rho) = (&self.vel, &self.porosity, &self.rho);
        rows.clear();
        for st in &self.stencils[d] {
            let f = st.face;
            let eps_f = faces.porosity[d][f];
            let rho_f = faces.density[d][f];
            let mut row = Row {
                face: f,
                inv_diag: 0.0,
                b: 0.0,
                nb: [NONE; 6],
                a: [0.0; 6],
            };
            let (mut dirichlet, mut net) = (0.0, 0.0);
            // Along d: through the cells' centres.
            let cl = st.lo;
            let f_lo = rho[cl] * por[cl] * 0.5 * (vel[d][st.next[1]] + vel[d][f]) * st.section[1];
            row.nb[1] = st.next[1];
            row.a[1] = mu * por[cl] * st.section[1] / hd + f_lo.max(0.0);
            net -= f_lo;
            if st.hi != NONE {
                let ch = st.hi;
                let f_hi =
                    rho[ch] * por[ch] * 0.5 * (vel[d][f] + vel[d][st.next[0]]) * st.section[0];
                row.nb[0] = st.next[0];
                row.a[0] = mu * por[ch] * st.section[0] / hd + (-f_hi).max(0.0);
                net += f_hi;
            } else {
                // Outlet: zero gradient.
                net += rho[cl] * por[cl] * vel[d][f] * st.section[1];
            }
            // Across: through the control volume's sides, half of each cell's face.
            for (s, side) in st.sides.iter().enumerate() {
                if side.count == 0 {
                    continue;
                }
                let t = side.t;
                let k = side.count as usize;
                let (mut eps, mut v) = (0.0, 0.0);
                for &sf in &side.faces[..k] {
                    eps += faces.porosity[t][sf];
                    v += vel[t][sf];
                }
                eps /= side.count as Real;
                v /= side.count as Real;
                let flux = rho_f * eps * v * side.area;
                if side.neighbour != NONE {
                    row.nb[2 + s] = side.neighbour;
                    row.a[2 + s] = mu * eps * side.area / side.gap
                        + if side.up {
                            (-flux).max(0.0)
                        } else {
                            flux.max(0.0)
                        };
                } else {
                    // The inlet plane, where this component is 0, half a cell upstream.
                    dirichlet += mu * eps * side.area / (0.5 * g.h[0]) + flux.max(0.0);
                }
                net += if side.up { flux } else { -flux };
            }
            let (beta_f, grain) = if st.hi != NONE {
                (
                    0.5 * (beta[cl] + beta[st.hi]),
                    0.5 * (self.grain_velocity[cl][d] + self.grain_velocity[st.hi][d]),
                )
            } else {
                (beta[cl], self.grain_velocity[cl][d])
            };
            let mut ap = row.a.iter().sum::<Real>()
                + dirichlet
                + net.max(0.0)
                + mu * eps_f * st.wall
                + beta_f * st.vol;
            let p_hi = if st.hi != NONE { self.p[st.hi] } else { 0.0 };
            let mut src = eps_f * (self.p[cl] - p_hi) * st.area + beta_f * st.vol * grain;
            if g.periodic && d == 0 {
                // The driving part of the pressure, −∂(−G s)/∂s = G, on the control volume.
                src += eps_f * self.drive_gradient * st.vol;
            }
            if let Some((partner, k_self, k_partner)) = st.partner {
                src -= mu * eps_f * (k_self * vel[d][f] + k_partner * vel[d][partner]);
            }
            if let Some((dt, old, _)) = transient {
                let m = rho_f * eps_f * st.vol / dt;
                ap += m;
                src += m * old[d][f];
            }
            let relaxed = ap / alpha;
            row.inv_diag = if relaxed > 0.0 { 1.0 / relaxed } else { 0.0 };
            row.b = src + (1.0 - alpha) * relaxed * vel[d][f];
            rows.push(row);
        }
    }

    pub(super) fn iterate(
        &mut self,
        transient: Option<Transient>,
        tol: Real,
        max_iter: usize,
    ) -> Result<SimpleReport, String> {
        let pr = self.params;
        let ap_relax = pr.relax_pressure;
        let inflow = pr.density * pr.inlet_velocity * self.geometry.flow_area;
        // ∂ρ/∂p of the ideal gas (for the pressure correction), s²/m².
        let drho_dp = pr.ideal_gas_pressure.map_or(0.0, |p0| pr.density / p0);
        // The step's first iteration factorises (see [`PressureSystem`]).
        self.pressure.new_step();
        self.pressure.residual_floor = CG_FLOOR_OF_TOLERANCE * tol * inflow.abs();
        let mut report = SimpleReport {
            iterations: 0,
            mass_residual: Real::INFINITY,
        };
        // The iteration's buffers (taken, and given back at the end).
        let mut sc = std::mem::take(&mut self.scratch);
        // The porosity holds over the step; an ideal gas's density follows the pressure
        // from iteration to iteration.
        self.update_density()?;
        let mut faces = FaceFields {
            porosity: self.on_faces(&self.porosity),
            density: self.on_faces(&self.rho),
        };
        for it in 0..max_iter {
            if it > 0 && pr.ideal_gas_pressure.is_some() {
                self.update_density()?;
                faces.density = self.on_faces(&self.rho);
            }
            self.apply_inlet(&faces);
            self.beta(&mut sc.beta);
            self.predict_velocities(&faces, transient.as_ref(), &mut sc);
            let (star, du) = (&mut sc.star, &sc.du);
            let worst = self.pressure_correction(&faces, star, du, transient.as_ref(), drho_dp)?;
            let pc = &self.pressure.solution;
            // ---- corrections -------------------------------------------------------------
            for (p, c) in self.p.iter_mut().zip(pc) {
                *p += ap_relax * c;
            }
            for d in 0..3 {
                for l in &self.links[d] {
                    let f = l.face;
                    let hi = if l.hi != NONE { pc[l.hi] } else { 0.0 };
                    star[d][f] += du[d][f] * faces.porosity[d][f] * l.area * (pc[l.lo] - hi);
                }
            }
            std::mem::swap(&mut self.vel, star);
            // A periodic grid's controller: the flow's miss of its target counts as a mass
            // imbalance (of the whole section), so the iteration ends only with G converged.
            let missed = self.control_flow(&faces, du);
            report = SimpleReport {
                iterations: it + 1,
                mass_residual: (worst / inflow.abs().max(1e-300)).max(missed),
            };
            if !self
                .vel
                .iter()
                .flatten()
                .chain(&self.p)
                .all(|x| x.is_finite())
            {
                return Err(format!("SIMPLE diverged at iteration {}", it + 1));
            }
            if report.mass_residual < tol && it > 2 {
                break;
            }
        }
        self.scratch = sc;
        Ok(report)
    }

    /// The momentum equations, each component by Gauss–Seidel sweeps: the starred
    /// velocities, and d(velocity)/d(pressure difference × area × ε) of each face (1/a_P;
    /// 0 where fixed).
    fn predict_velocities(
        &self,
        faces: &FaceFields,
        transient: Option<&Transient>,
        sc: &mut IterationScratch,
    ) {
        let IterationScratch {
            star,
            du,
            rows,
            beta,
        } = sc;
        for d in 0..3 {
            star[d].clone_from(&self.vel[d]);
            // d(velocity)/d(pressure difference × area × ε) of each face: 1/a_P (0: fixed).
            du[d].clear();
            du[d].resize(self.vel[d].len(), 0.0);
        }
        for d in 0..3 {
            if self.stencils[d].is_empty() {
                continue;
            }
            self.momentum(d, faces, beta, transient, rows);
            let s = &mut star[d];
            for _ in 0..MOMENTUM_SWEEPS {
                for row in rows.iter() {
                    let mut acc = row.b;
                    for (&k, &a) in row.nb.iter().zip(&row.a) {
                        if k != NONE {
                            acc += a * s[k];
                        }
                    }
                    s[row.face] = acc * row.inv_diag;
                }
            }
            for row in rows.iter() {
                du[d][row.face] = row.inv_diag;
            }
        }
    }

    /// The pressure correction p' (into `self.pressure.solution`) from the starred
    /// velocities' mass imbalance: symmetric positive definite, solved by
    /// [`PressureSystem::solve`]. Returns the largest cell imbalance, kg/s.
    fn pressure_correction(
        &mut self,
        faces: &FaceFields,
        star: &[Vec<Real>; 3],
        du: &[Vec<Real>; 3],
        transient: Option<&Transient>,
        drho_dp: Real,
    ) -> Result<Real, String> {
        let cells = self.geometry.cells();
        let g = &self.geometry;
        let sys = &mut self.pressure;
        sys.reset(cells, &self.links);
        let (diag, rhs) = (&mut sys.diag, &mut sys.rhs);
        // Mass flows with the starred velocities into and out of every cell.
        for d in 0..3 {
            for (f, &(lo, hi)) in self.face_cells[d].iter().enumerate() {
                let flow = faces.density[d][f] * faces.porosity[d][f] * star[d][f] * g.area[d][f];
                if flow == 0.0 {
                    continue;
                }
                if lo != NONE {
                    rhs[lo] -= flow;
                }
                if hi != NONE {
                    rhs[hi] += flow;
                }
            }
        }
        let mut worst: Real = 0.0;
        let mut pin = None;
        for c in 0..cells {
            if g.volume[c] == 0.0 {
                // Outside the flow: p' = 0, decoupled.
                diag[c] = 1.0;
                rhs[c] = 0.0;
                continue;
            }
            if let Some((dt, _, mass_old)) = transient {
                // Gas mass gained by the cell over the step leaves less to flow out; an
                // ideal gas also stores mass as its pressure rises.
                let vol = g.volume[c];
                rhs[c] -= (self.rho[c] * self.porosity[c] - mass_old[c]) * vol / dt;
                diag[c] += self.porosity[c] * vol / dt * drho_dp;
            }
            worst = worst.max(rhs[c].abs());
        }
        if g.periodic && drho_dp == 0.0 {
            // No boundary fixes the level of p': the system is singular, compatible when the
            // cells' imbalances sum to zero. They do up to the grains' volume the porosity's
            // clamp adds or removes: that part is spread over the cells by volume (a uniform
            // compression of the incompressible gas, below the tolerance), and the first open
            // cell's p' is pinned (any δ > 0 on one diagonal entry of a compatible system
            // gives exactly the solution with p' = 0 there).
            let open: Real = g.volume.iter().sum();
            let excess: Real = rhs.iter().sum::<Real>() / open;
            for (r, v) in rhs.iter_mut().zip(&g.volume) {
                *r -= excess * v;
            }
            worst = rhs.iter().fold(0.0, |m: Real, r| m.max(r.abs()));
            if let Some(first) = g.volume.iter().position(|&v| v > 0.0) {
                pin = Some(first);
            }
        }
        // The faces' couplings, in the stencils' order (the system's pairs).
        for d in 0..3 {
            for l in &self.links[d] {
                let f = l.face;
                let eps = faces.porosity[d][f];
                let a = faces.density[d][f] * eps * eps * l.area * l.area * du[d][f];
                // (The outlet's faces: p' = 0 beyond.)
                diag[l.lo] += a;
                if l.hi != NONE {
                    diag[l.hi] += a;
                    sys.coupling.push(a);
                }
            }
        }
        if let Some(c) = pin {
            diag[c] *= 2.0;
        }
        sys.solve(&mut self.pattern, &mut self.symbolic)?;
        Ok(worst)
    }

    /// A periodic grid's flow controller, after each SIMPLE iteration: the mean superficial
    /// velocity U = Σ ε u A / (n₀ A_flow) over the axial faces (each plane once), and the
    /// change of G that brings it to the target. Each face alone answers as its momentum
    /// equation does, Δu = ε V ΔG / a_P, the faces of one plane in parallel (their sum
    /// s_k); but continuity makes the planes carry one flow, in series, so the section's
    /// flow answers as the harmonic mean, ΔU = ΔG n / Σ_k 1/s_k, and every plane takes that
    /// same ΔU at once, shared among its faces as their own answers are (a Newton step: U
    /// is linear in G at fixed p̃). (The faces' plain sum overstates a slug's section: on
    /// Lethe's slug the miss then halved per iteration, 16 iterations per step; see
    /// `gas_bench`.) Returns the measured flow's miss of the target, relative (0 on open
    /// grids).
    fn control_flow(&mut self, faces: &FaceFields, du: &[Vec<Real>; 3]) -> Real {
        let g = &self.geometry;
        if !g.periodic {
            return 0.0;
        }
        let superficial = 1.0 / (g.n[0] as Real * g.flow_area);
        let scale = if self.control_interstitial {
            // The gas's volume over the section's, for the interstitial mean (∫ ε dV over
            // the axial faces' control volumes).
            let gas_share: Real = self.stencils[0]
                .iter()
                .map(|st| faces.porosity[0][st.face] * st.area)
                .sum::<Real>()
                * superficial;
            superficial / gas_share
        } else {
            superficial
        };
        let alpha = self.params.relax_velocity;
        // Axial faces are numbered plane first: the plane of face f is f mod (n₀ + 1).
        let planes = g.face_counts(0)[0];
        let plane_answer = &mut self.plane_answer;
        plane_answer.clear();
        plane_answer.resize(planes, 0.0);
        let mut flow = 0.0;
        for st in &self.stencils[0] {
            let (f, eps) = (st.face, faces.porosity[0][st.face]);
            flow += eps * self.vel[0][f] * st.area * scale;
            // 1/a_P unrelaxed (du holds α/a_P).
            plane_answer[f % planes] += eps * eps * st.vol * du[0][f] / alpha * st.area * scale;
        }
        self.mean_superficial_velocity = flow * superficial / scale;
        let target = self.params.inlet_velocity;
        let missed = (flow - target).abs() / target.abs().max(1e-300);
        let (mut count, mut resistance) = (0.0, 0.0);
        for &s in plane_answer.iter().filter(|&&s| s != 0.0) {
            count += 1.0;
            resistance += 1.0 / s;
        }
        let slope = if resistance > 0.0 {
            count * count / resistance
        } else {
            0.0
        };
        if slope <= 0.0 || !slope.is_finite() {
            g.sync_seam(&mut self.vel[0]);
            return missed;
        }
        let change = (target - flow) / slope;
        self.drive_gradient += change;
        for st in &self.stencils[0] {
            let f = st.face;
            // The face's own answer, scaled so its plane's flow changes by ΔU.
            let share = slope / (count * plane_answer[f % planes]);
            self.vel[0][f] += faces.porosity[0][f] * st.vol * du[0][f] / alpha * change * share;
        }
        g.sync_seam(&mut self.vel[0]);
        missed
    }

    /// Mean pressure over the open cells of slice i along the flow (volume-weighted), Pa.
    pub fn column_pressure(&self, i: usize) -> Real {
        let g = &self.geometry;
        let (mut s, mut v) = (0.0, 0.0);
        for x in Geometry::each([1, g.n[1], g.n[2]]) {
            let c = g.cell([i, x[1], x[2]]);
            s += self.p[c] * g.volume[c];
            v += g.volume[c];
        }
        s / v
    }

    /// Velocity along the flow on the faces of plane i (index order across), m/s.
    pub fn axial_profile(&self, i: usize) -> Vec<Real> {
        let g = &self.geometry;
        Geometry::each([1, g.n[1], g.n[2]])
            .map(|x| self.vel[0][g.face(0, [i, x[1], x[2]])])
            .collect()
    }
}
