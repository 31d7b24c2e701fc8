//! What a run writes while it goes. Each format is one file here behind [`RunOutput`]:
//! [`hdf5::Hdf5Output`] (`run.h5`: field time series, pressure-drop trace, plug table,
//! snapshots), [`csv::CsvOutput`] (`timeseries.csv`), [`vtk::VtkOutput`] (ParaView: VTK XML
//! particles, gas grid, geometry, series). Figures and `summary.json`
//! are written once at the end (`figures.rs`, `run.rs`).
//!
//! Every sample is handed to every output as soon as it is taken, and each output makes it
//! durable before the run goes on, so a run killed at any moment leaves readable files.

pub mod csv;
pub mod figures;
pub mod hdf5;
pub mod room;
pub mod vtk;
pub mod xdmf;

use plugflow_coupling::ParticleView;

use crate::analysis::plugs::{PlugObservation, SliceFrame};
use crate::analysis::profiles::ProfileResult;
use crate::{Real, Vec3};

/// A failure to write an output file.
#[derive(Debug, thiserror::Error)]
#[error("cannot write `{path}`: {reason}")]
pub struct OutputError {
    /// The file.
    pub path: String,
    /// What went wrong.
    pub reason: String,
}

impl OutputError {
    pub(crate) fn new(path: impl std::fmt::Display, reason: impl std::fmt::Display) -> Self {
        Self {
            path: path.to_string(),
            reason: reason.to_string(),
        }
    }
}

/// One sample of the tube, every `output.sample_interval`.
#[derive(Debug, Clone, Copy)]
pub struct Sample<'a> {
    /// Simulated time, s.
    pub time: Real,
    /// Grains inside the tube.
    pub particles_in_tube: usize,
    /// Pressure drop per length, Pa/m (None without gas).
    pub pressure_drop: Option<Real>,
    /// Slices of the tube (None without a tube).
    pub slices: Option<&'a SliceFrame>,
    /// Gas-grid porosity along the axis (cross-section means; None without gas).
    pub gas_porosity: Option<&'a [Real]>,
    /// Gas pressure P − P0 along the axis, Pa (cross-section means; None without gas).
    pub gas_pressure: Option<&'a [Real]>,
    /// Plugs first observed in this sample's frame.
    pub new_plugs: &'a [PlugObservation],
    /// Force of the grains on each wall the engine reports, N, in [`RunMeta::walls`]'s order.
    ///
    /// [`RunMeta::walls`]: hdf5::RunMeta::walls
    pub wall_forces: &'a [Vec3],
}

/// The gas on its grid at a snapshot (gas scenes).
#[derive(Debug, Clone)]
pub struct GasSnapshot<'a> {
    pub grid: &'a plugflow_coupling::TubeGrid,
    /// P − P0 on the nodes, Pa.
    pub pressure: &'a [Real],
    /// Porosity on the nodes as the gas used it (clamped).
    pub porosity: &'a [Real],
    /// Deposited granular velocity on the nodes, m/s.
    pub granular_velocity: &'a [Vec3],
    /// Interstitial gas velocity on the nodes, m/s (None: the d'Arcy gas has none).
    pub gas_velocity: Option<Vec<Vec3>>,
}

/// An output written while the run goes.
pub trait RunOutput {
    /// Record one sample; durable on return (an output of snapshots only takes none).
    fn sample(&mut self, _sample: &Sample) -> Result<(), OutputError> {
        Ok(())
    }
    /// Record one snapshot of the grains (and the gas on its grid, in gas scenes); durable
    /// on return (an output of series only takes none).
    fn snapshot(
        &mut self,
        _time: Real,
        _step: u64,
        _particles: &ParticleView,
        _gas: Option<&GasSnapshot>,
    ) -> Result<(), OutputError> {
        Ok(())
    }
    /// The run is over: record what is only known at the end (profiles).
    fn finish(&mut self, _profiles: Option<&ProfileResult>) -> Result<(), OutputError> {
        Ok(())
    }
    /// The last call, whatever happened before: write what describes the output as a
    /// whole (`run.h5`'s XDMF sidecar).
    fn close(&mut self) -> Result<(), OutputError> {
        Ok(())
    }
}
