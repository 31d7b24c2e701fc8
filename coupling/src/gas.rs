//! The gas-solver trait: advance the gas over one coupling interval given the granular
//! fields, then answer pressure and its gradient on the nodes.

use crate::grid::{GranularFields, TubeGrid};
use crate::{Real, Vec3};

/// What one gas step reports.
#[derive(Debug, Clone, Copy, Default)]
pub struct GasStepReport {
    /// Nodes whose porosity was clamped into [φ_min, φ_max] this step.
    pub clamped_nodes: usize,
    /// Of those, the nodes below φ_min (more solid than the model allows: over-packed).
    pub clamped_low_nodes: usize,
    /// |storage change − boundary fluxes − sources| / |inflow| of this step.
    pub mass_error_rel: Real,
}

/// Errors of a gas solve, naming where they arose.
#[derive(Debug, thiserror::Error)]
pub enum GasError {
    /// The linear solve failed.
    #[error("gas solve failed at gas step {step}: {reason}")]
    Solve { step: u64, reason: String },
    /// A checkpoint's gas state does not fit this solver (or it keeps none).
    #[error("gas state: {reason}")]
    State { reason: String },
    /// A pressure became NaN or infinite.
    #[error("gas pressure not finite at gas step {step}, node {node} (slice {slice})")]
    NonFinite {
        step: u64,
        node: usize,
        slice: usize,
    },
}

/// A gas solver on a [`crate::TubeGrid`].
pub trait GasSolver {
    /// Name as the scene writes it.
    fn name(&self) -> &'static str;
    /// The grid the solver works on.
    fn grid(&self) -> &TubeGrid;
    /// Change the inlet's superficial gas velocity, m/s (ramps, step changes).
    fn set_superficial_velocity(&mut self, v: Real);
    /// The inlet's superficial gas velocity now, m/s.
    fn superficial_velocity(&self) -> Real;
    /// Advance over `dt` seconds with the given granular fields.
    fn step(&mut self, fields: &GranularFields, dt: Real) -> Result<GasStepReport, GasError>;
    /// Pressure P' = P − P0 on the nodes, Pa.
    fn pressure(&self) -> &[Real];
    /// Porosity on the nodes as the solver used it (clamped).
    fn porosity(&self) -> &[Real];
    /// Pressure gradient on the nodes, Pa/m.
    fn pressure_gradient(&self) -> Vec<Vec3>;
    /// Pressure drop per length, Pa/m: the mean gradient between the first node plane z₁
    /// (half a cell in from the inlet, its cross-section mean) and the outlet (P' = 0),
    /// P'(z₁)/(L − z₁). Measured where the solver has a value, not extrapolated to z = 0;
    /// every solver reports this one definition (summary, `run.h5`, targets).
    fn pressure_drop_per_length(&self) -> Real;
    /// A periodic section's mean superficial gas velocity along the axis after the last
    /// step, (1/V) ∫ ε u dV, m/s (what its flow controller holds); None for open tubes.
    fn mean_superficial_velocity(&self) -> Option<Real> {
        None
    }
    /// Interstitial gas velocity on the nodes, m/s; None for solvers without one (d'Arcy).
    fn gas_velocity(&self) -> Option<Vec<Vec3>> {
        None
    }
    /// Gas density on the nodes, kg/m³; None for solvers without inertia (d'Arcy: 0).
    fn gas_density(&self) -> Option<Vec<Real>> {
        None
    }
    /// A cheap estimate of the time-discretisation error of a step of `dt` from the
    /// current state: max |P'(one step of dt) − P'(two steps of dt/2)| over max |P'|, the
    /// solver's state left as it was. None for solvers that do not provide it.
    fn step_doubling_error(
        &mut self,
        _fields: &GranularFields,
        _dt: Real,
    ) -> Result<Option<Real>, GasError> {
        Ok(None)
    }
    /// The solver's state between two steps as bytes only it reads back (a checkpoint):
    /// restored into a solver built from the same scene, later steps give the same bits.
    fn save_state(&self) -> Result<Vec<u8>, GasError> {
        Err(GasError::State {
            reason: format!("the `{}` gas cannot write checkpoints", self.name()),
        })
    }
    /// Take back a state [`GasSolver::save_state`] wrote; refused, naming why, when the
    /// bytes are not such a state or the grid differs.
    fn restore_state(&mut self, _state: &[u8]) -> Result<(), GasError> {
        Err(GasError::State {
            reason: format!("the `{}` gas cannot resume from checkpoints", self.name()),
        })
    }
}
