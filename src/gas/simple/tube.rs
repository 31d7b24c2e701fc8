//! [`SimpleTubeGas`]: the SIMPLE gas behind the `GasSolver` trait on a tube grid (2D
//! channel of seed 004, or the 3D cut-cell tube).

use super::*;

/// SIMPLE iterations per coupling step at most, and the mass residual that ends them.
pub(super) const STEP_ITERATIONS: usize = 200;
pub(super) const STEP_TOLERANCE: Real = 1e-7;

/// What a SIMPLE tube gas carries from step to step (a checkpoint; stencils, patterns
/// and the factorisation's structure come from the geometry again, to the same bits).
#[derive(serde::Serialize, serde::Deserialize)]
struct SimpleState {
    nodes: usize,
    cells: usize,
    vel: [Vec<Real>; 3],
    p: Vec<Real>,
    porosity: Vec<Real>,
    rho: Vec<Real>,
    prev_mass: Option<Vec<Real>>,
    fed_solid: Vec<Real>,
    grain_velocity: Vec<[Real; 3]>,
    inlet_velocity: Real,
    phi: Vec<Real>,
    node_p: Vec<Real>,
    steps: u64,
    last_iterations: usize,
    /// A periodic grid's driving gradient and measured mean superficial velocity.
    #[serde(default)]
    drive_gradient: Real,
    #[serde(default)]
    mean_superficial_velocity: Real,
}

/// The SIMPLE gas behind the `GasSolver` trait on a tube grid: the 2D channel of seed 004
/// when the grid has one node across e1 (node (k, 0, j) is cell (k, 0, j)), the cut-cell
/// 3D tube otherwise.
pub struct SimpleTubeGas {
    pub(super) grid: TubeGrid,
    pub gas: SimpleGas,
    pub(super) porosity_min: Real,
    /// SIMPLE cell of each tube-grid node.
    pub(super) cell_of: Vec<usize>,
    /// Per node (tube-grid order): clamped porosity and pressure.
    pub(super) phi: Vec<Real>,
    pub(super) p: Vec<Real>,
    pub(super) steps: u64,
    /// SIMPLE iterations of the last step.
    pub last_iterations: usize,
}

impl SimpleTubeGas {
    /// The drag law the grains feel, for the gas's side of the exchange
    /// ([`SimpleGas::set_drag_law`]).
    pub fn set_drag_law(&mut self, law: Arc<dyn DragLaw>) -> Result<(), String> {
        self.gas.set_drag_law(law)
    }

    /// SIMPLE on `grid` with the gas's density, viscosity, inlet superficial velocity and the
    /// grains' diameter; an ideal gas when the outlet's absolute pressure is given.
    pub fn new(
        grid: TubeGrid,
        density: Real,
        viscosity: Real,
        superficial_velocity: Real,
        grain_diameter: Real,
        porosity_min: Real,
        ideal_gas_pressure: Option<Real>,
    ) -> Self {
        let mut geometry = if grid.nx == 1 {
            Geometry::channel(
                grid.length,
                [1.0, 2.0 * grid.radius],
                [grid.nz, 1, grid.ny],
                [Wall::Slip, Wall::NoSlip],
            )
        } else {
            Geometry::tube(&grid)
        };
        geometry.periodic = grid.periodic;
        let gas = SimpleGas::new(
            SimpleParams {
                density,
                ideal_gas_pressure,
                viscosity,
                inlet_velocity: superficial_velocity,
                drag_diameter: Some(grain_diameter),
                // Time steps: the ρεV/Δt term dominates the momentum diagonal, so the pressure
                // correction needs little under-relaxation: 0.8 takes ~9 iterations per step
                // where SIMPLE's classic 0.3 takes ~31 (measured: an 8 m × 80 mm pipe with plugs).
                relax_velocity: 0.7,
                relax_pressure: 0.8,
            },
            geometry,
        );
        let n = grid.len();
        let cell_of = (0..n)
            .map(|node| {
                let (k, rest) = (node / (grid.nx * grid.ny), node % (grid.nx * grid.ny));
                let (i, j) = (rest % grid.nx, rest / grid.nx);
                k + grid.nz * (i + grid.nx * j)
            })
            .collect();
        Self {
            grid,
            gas,
            porosity_min,
            cell_of,
            phi: vec![1.0; n],
            p: vec![0.0; n],
            steps: 0,
            last_iterations: 0,
        }
    }

    /// One gas step of `dt` towards the grains' fields: the porosity goes `share` of the
    /// way from the last step's to the fields' (1: all of it; the step-doubling estimate
    /// takes two halves), and `fed_share` of the grains fed since the last exchange count
    /// as present at the step's start.
    pub(super) fn advance(
        &mut self,
        fields: &GranularFields,
        dt: Real,
        share: Real,
        fed_share: Real,
    ) -> Result<GasStepReport, GasError> {
        let (mut clamped, mut low) = (0, 0);
        let (axis, e1, e2) = (self.grid.axis, self.grid.e1, self.grid.e2);
        let three_d = self.grid.nx > 1;
        for n in 0..self.grid.len() {
            let c = self.cell_of[n];
            if self.gas.geometry.volume[c] == 0.0 {
                continue;
            }
            let raw = fields.porosity.get(n).copied().unwrap_or(1.0);
            // Only the lower clamp: the upper one exists for the d'Arcy model, whose
            // Carman–Kozeny permeability diverges at φ = 1; Wen–Yu's drag stays finite.
            let full = raw.clamp(self.porosity_min, 1.0);
            let phi = if self.steps == 0 {
                full
            } else {
                self.phi[n] + share * (full - self.phi[n])
            };
            if full != raw {
                clamped += 1;
                if raw < self.porosity_min {
                    low += 1;
                }
            }
            self.phi[n] = phi;
            self.gas.porosity[c] = phi;
            let v = fields.velocity.get(n).copied().unwrap_or([0.0; 3]);
            let dotp = |a: Vec3| a[0] * v[0] + a[1] * v[1] + a[2] * v[2];
            // (The 2D channel has no motion across its plane.)
            let across = if three_d { dotp(e1) } else { 0.0 };
            self.gas.grain_velocity[c] = [dotp(axis), across, dotp(e2)];
        }
        self.gas.fed_solid.clear();
        if !fields.fed_solid.is_empty() {
            self.gas.fed_solid.resize(self.gas.geometry.cells(), 0.0);
            for n in 0..self.grid.len() {
                self.gas.fed_solid[self.cell_of[n]] += fed_share * fields.fed_solid[n];
            }
        }
        self.steps += 1;
        let r = self
            .gas
            .step(dt, STEP_TOLERANCE, STEP_ITERATIONS)
            .map_err(|reason| GasError::Solve {
                step: self.steps,
                reason,
            })?;
        self.last_iterations = r.iterations;
        if let Some(bad) = self.gas.p.iter().position(|x| !x.is_finite()) {
            let node = self.cell_of.iter().position(|&c| c == bad).unwrap_or(bad);
            return Err(GasError::NonFinite {
                step: self.steps,
                node,
                slice: bad % self.grid.nz,
            });
        }
        for n in 0..self.grid.len() {
            let c = self.cell_of[n];
            self.p[n] = if self.gas.geometry.volume[c] > 0.0 {
                self.gas.p[c]
            } else {
                // A closed node (no grain weighs on it): its slice's mean, for the outputs.
                self.gas.column_pressure(c % self.grid.nz)
            };
        }
        Ok(GasStepReport {
            clamped_nodes: clamped,
            clamped_low_nodes: low,
            mass_error_rel: r.mass_residual,
        })
    }

    /// Cell coordinates of node n.
    pub(super) fn coords(&self, n: usize) -> [usize; 3] {
        let c = self.cell_of[n];
        let (nz, nx) = (self.grid.nz, self.grid.nx);
        [c % nz, (c / nz) % nx, c / (nz * nx)]
    }
}

impl GasSolver for SimpleTubeGas {
    fn name(&self) -> &'static str {
        "simple"
    }

    fn grid(&self) -> &TubeGrid {
        &self.grid
    }

    fn set_superficial_velocity(&mut self, v: Real) {
        self.gas.params.inlet_velocity = v;
    }

    fn superficial_velocity(&self) -> Real {
        self.gas.params.inlet_velocity
    }

    fn step(&mut self, fields: &GranularFields, dt: Real) -> Result<GasStepReport, GasError> {
        self.advance(fields, dt, 1.0, 1.0)
    }

    fn pressure(&self) -> &[Real] {
        &self.p
    }

    fn porosity(&self) -> &[Real] {
        &self.phi
    }

    fn pressure_gradient(&self) -> Vec<Vec3> {
        let g = &self.gas.geometry;
        let (axis, e1, e2) = (self.grid.axis, self.grid.e1, self.grid.e2);
        let p = |x: [usize; 3]| self.gas.p[g.cell(x)];
        let open = |x: [usize; 3]| g.volume[g.cell(x)] > 0.0;
        (0..self.grid.len())
            .map(|n| {
                let x = self.coords(n);
                if !open(x) {
                    return [0.0; 3];
                }
                let grad: [Real; 3] = std::array::from_fn(|d| {
                    let h = g.h[d];
                    if d == 0 && g.periodic {
                        // p = p̃ − G s: p̃'s central difference around the seam, less G
                        // (closed neighbours along the axis do not occur: columns are
                        // open or closed along the whole section).
                        let up = g.cell_after(x, 0).expect("periodic");
                        let down = g.cell_before(x, 0).expect("periodic");
                        return (p(up) - p(down)) / (2.0 * h) - self.gas.drive_gradient;
                    }
                    if d == 0 && x[0] + 1 == g.n[0] {
                        // To the outlet's p = 0 half a cell downstream.
                        return if x[0] > 0 {
                            (0.0 - p(minus(x, 0))) / (1.5 * h)
                        } else {
                            (0.0 - p(x)) / (0.5 * h)
                        };
                    }
                    let up = (x[d] + 1 < g.n[d] && open(plus(x, d))).then(|| p(plus(x, d)));
                    let down = (x[d] > 0 && open(minus(x, d))).then(|| p(minus(x, d)));
                    match (up, down) {
                        (Some(a), Some(b)) => (a - b) / (2.0 * h),
                        (Some(a), None) => (a - p(x)) / h,
                        (None, Some(b)) => (p(x) - b) / h,
                        (None, None) => 0.0,
                    }
                });
                [0, 1, 2].map(|c| grad[0] * axis[c] + grad[1] * e1[c] + grad[2] * e2[c])
            })
            .collect()
    }

    fn mean_superficial_velocity(&self) -> Option<Real> {
        self.gas
            .geometry
            .periodic
            .then_some(self.gas.mean_superficial_velocity)
    }

    fn pressure_drop_per_length(&self) -> Real {
        if self.gas.geometry.periodic {
            // The mean of −∂p/∂s over a period: G (p̃ is periodic).
            return self.gas.drive_gradient;
        }
        // First slice's mean pressure over its distance to the outlet (p = 0).
        let first = self.gas.column_pressure(0);
        first / (self.grid.length - 0.5 * self.gas.geometry.h[0])
    }

    fn gas_velocity(&self) -> Option<Vec<Vec3>> {
        let g = &self.gas.geometry;
        let (axis, e1, e2) = (self.grid.axis, self.grid.e1, self.grid.e2);
        Some(
            (0..self.grid.len())
                .map(|n| {
                    let x = self.coords(n);
                    if g.volume[g.cell(x)] == 0.0 {
                        return [0.0; 3];
                    }
                    let u = self.gas.centre_velocity(x);
                    [0, 1, 2].map(|c| u[0] * axis[c] + u[1] * e1[c] + u[2] * e2[c])
                })
                .collect(),
        )
    }

    fn save_state(&self) -> Result<Vec<u8>, GasError> {
        let g = &self.gas;
        let state = SimpleState {
            nodes: self.grid.len(),
            cells: g.geometry.cells(),
            vel: g.vel.clone(),
            p: g.p.clone(),
            porosity: g.porosity.clone(),
            rho: g.rho.clone(),
            prev_mass: g.prev_mass.clone(),
            fed_solid: g.fed_solid.clone(),
            grain_velocity: g.grain_velocity.clone(),
            inlet_velocity: g.params.inlet_velocity,
            phi: self.phi.clone(),
            node_p: self.p.clone(),
            steps: self.steps,
            last_iterations: self.last_iterations,
            drive_gradient: g.drive_gradient,
            mean_superficial_velocity: g.mean_superficial_velocity,
        };
        crate::gas::encode_state(&state, "SIMPLE")
    }

    fn restore_state(&mut self, bytes: &[u8]) -> Result<(), GasError> {
        let (nodes, cells) = (self.grid.len(), self.gas.geometry.cells());
        let faces = self.gas.vel.each_ref().map(Vec::len);
        let s: SimpleState = crate::gas::decode_state(bytes, "SIMPLE", |s: &SimpleState| {
            let cell_fields = [
                s.p.len(),
                s.porosity.len(),
                s.rho.len(),
                s.grain_velocity.len(),
            ];
            let fits = s.nodes == nodes
                && s.cells == cells
                && s.vel.each_ref().map(Vec::len) == faces
                && cell_fields.iter().all(|&l| l == cells)
                && s.phi.len() == nodes
                && s.node_p.len() == nodes;
            (!fits).then(|| {
                format!(
                    "written for a grid of {} nodes and {} cells, the scene's has {nodes} and \
                     {cells}",
                    s.nodes, s.cells
                )
            })
        })?;
        let g = &mut self.gas;
        g.vel = s.vel;
        g.p = s.p;
        g.porosity = s.porosity;
        g.rho = s.rho;
        g.prev_mass = s.prev_mass;
        g.fed_solid = s.fed_solid;
        g.grain_velocity = s.grain_velocity;
        g.params.inlet_velocity = s.inlet_velocity;
        if g.geometry.periodic {
            g.drive_gradient = s.drive_gradient;
            g.mean_superficial_velocity = s.mean_superficial_velocity;
        }
        self.phi = s.phi;
        self.p = s.node_p;
        self.steps = s.steps;
        self.last_iterations = s.last_iterations;
        Ok(())
    }

    /// One step of dt against two of dt/2 from the same state (the state restored after):
    /// max |Δp| over max |p|.
    fn step_doubling_error(
        &mut self,
        fields: &GranularFields,
        dt: Real,
    ) -> Result<Option<Real>, GasError> {
        let (gas, phi, p, steps) = (
            self.gas.clone(),
            self.phi.clone(),
            self.p.clone(),
            self.steps,
        );
        let run = |this: &mut Self, halves: usize| -> Result<Vec<Real>, GasError> {
            // The porosity changes (and the grains fed) spread evenly over the parts.
            let r = (0..halves).try_for_each(|h| {
                let share = 1.0 / (halves - h) as Real;
                this.advance(fields, dt / halves as Real, share, 1.0 / halves as Real)
                    .map(|_| ())
            });
            let out = this.gas.p.clone();
            this.gas = gas.clone();
            this.phi.clone_from(&phi);
            this.p.clone_from(&p);
            this.steps = steps;
            r.map(|_| out)
        };
        let one = run(self, 1)?;
        let two = run(self, 2)?;
        let scale = two.iter().fold(0.0, |m: Real, x| m.max(x.abs()));
        if scale == 0.0 {
            return Ok(Some(0.0));
        }
        let diff = one
            .iter()
            .zip(&two)
            .fold(0.0, |m: Real, (a, b)| m.max((a - b).abs()));
        Ok(Some(diff / scale))
    }

    fn gas_density(&self) -> Option<Vec<Real>> {
        Some(self.cell_of.iter().map(|&c| self.gas.rho[c]).collect())
    }
}
