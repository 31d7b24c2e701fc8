//! Volume-averaged gas momentum and continuity (seed 004 eq. 10) on a staggered grid, solved
//! with SIMPLE:
//!
//!   ∂(ρ ε u)/∂t + ∇·(ρ ε u u) = −ε ∇p + ∇·(μ ε ∇u) − β (u − v),   ∂(ρ ε)/∂t + ∇·(ρ ε u) = 0,
//!
//! u the interstitial gas velocity, v the grains' velocity, β the interphase coefficient of a
//! drag law of the slip ([`DragLaw::slip_coefficient`], the very function the grains' drag
//! uses; Ergun / Wen–Yu unless told otherwise),
//! treated implicitly (it enters the momentum diagonal) so dense beds, where β ρ⁻¹ Δt ≫ 1,
//! do not destabilise the iteration. Density constant or an isothermal ideal gas, ρ = ρ0
//! (P0 + p)/P0; continuity keeps ∂(ρε)/∂t, so grains moving into a cell push its gas out
//! (and an ideal gas stores mass as it is compressed), the pressure correction carrying
//! ∂ρ/∂p on its diagonal.
//!
//! Grid ([`Geometry`]): n₀ cells along the flow (direction 0, inlet → outlet), n₁ × n₂
//! across; pressure and porosity at cell centres, velocity component d on the faces normal
//! to d. Every cell has an open volume and every face an open area (cut cells: a tube's
//! wall crosses the cells of its bounding box), and no-slip walls inside a cell act on the
//! velocity through a wall conductance Σ area/distance. Inlet (first faces along 0): a
//! given mass flux ρ0 U (U the superficial velocity at the outlet's density, u = ρ0 U/(ρ ε)).
//! Outlet (last faces): p = 0 (gauge: P0 absolute), zero gradient of every component.
//! Convection first-order upwind, diffusion central; momentum by Gauss–Seidel sweeps; the
//! pressure correction is symmetric positive definite (5 or 7 points) and solved with faer's
//! sparse Cholesky, the symbolic factorisation kept.
//!
//! [`SimpleTubeGas`] puts it behind the `GasSolver` trait on a tube grid: with one node in
//! the grid's first cross direction the 2D channel of seed 004 (the plane of the axis and
//! the second cross direction, D high, per unit depth); with more, the 3D tube, its wall
//! cutting the cells (validated against Hagen–Poiseuille).

mod geometry;
mod pressure;
mod solver;
#[cfg(test)]
mod tests;
mod tube;

pub use geometry::{Geometry, Wall};
pub use solver::SimpleGas;
pub use tube::SimpleTubeGas;
// The parts see one another's crate-private items.
use geometry::*;
use pressure::{PressureSystem, CG_FLOOR_OF_TOLERANCE};

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{Argsort, Pair, SparseColMat, SymbolicSparseColMat};
use faer::Side;
use plugflow_coupling::drag::ErgunWenYu;
use plugflow_coupling::DragLaw;
use plugflow_coupling::{GasError, GasSolver, GasStepReport, GranularFields, TubeGrid};
use std::sync::Arc;

pub(super) use crate::{Real, Vec3};

/// Gauss–Seidel sweeps of each momentum equation per SIMPLE iteration (the outer
/// iteration converges the coupling; the sweeps need only reduce the momentum residual).
pub(super) const MOMENTUM_SWEEPS: usize = 4;

/// No neighbour (a stencil slot left empty).
pub(super) const NONE: usize = usize::MAX;

/// A time step: its length, s, the velocities at its start and the gas mass per volume of
/// mixture, ρε, of every cell then, kg/m³.
pub(super) type Transient = (Real, [Vec<Real>; 3], Vec<Real>);

/// Parameters of the SIMPLE gas.
#[derive(Debug, Clone, Copy)]
pub struct SimpleParams {
    /// Gas density ρ, kg/m³: the density at the outlet pressure (p = 0) for an ideal gas.
    pub density: Real,
    /// Ideal gas (isothermal): the outlet's absolute pressure P0, Pa, and ρ = ρ0 (P0 + p)/P0
    /// in every cell. None: constant density.
    pub ideal_gas_pressure: Option<Real>,
    /// Gas viscosity μ, Pa·s.
    pub viscosity: Real,
    /// Superficial velocity at the inlet, m/s, at the outlet's density: the inlet's mass
    /// flux is ρ0 U whatever the inlet pressure.
    pub inlet_velocity: Real,
    /// Grain diameter for the Ergun / Wen–Yu drag, m; None: no grains, no drag.
    pub drag_diameter: Option<Real>,
    /// Under-relaxation of velocity and pressure (SIMPLE: 0.7 and 0.3 are the classic pair).
    pub relax_velocity: Real,
    pub relax_pressure: Real,
}

/// Outcome of a solve.
#[derive(Debug, Clone, Copy)]
pub struct SimpleReport {
    /// Outer (SIMPLE) iterations used.
    pub iterations: usize,
    /// Final mass imbalance, largest cell, relative to the inlet mass flow.
    pub mass_residual: Real,
}
