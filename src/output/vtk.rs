//! Particle snapshots as legacy VTK polydata (`particles_NNNNNN.vtk`, ASCII), which ParaView
//! opens as one time series: points = grain centres, point data = radius, id, velocity and
//! angular velocity, field data `TIME` = simulated time.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use plugflow_coupling::ParticleView;

use super::{OutputError, RunOutput, Sample};
use crate::Real;

/// Writes one VTK file per snapshot into a folder.
#[derive(Debug)]
pub struct VtkOutput {
    dir: PathBuf,
    written: usize,
}

impl VtkOutput {
    /// Snapshots go to `dir`.
    pub fn new(dir: &Path) -> Self {
        Self {
            dir: dir.to_path_buf(),
            written: 0,
        }
    }

    /// Files written so far.
    pub fn written(&self) -> usize {
        self.written
    }
}

/// The legacy VTK text of one snapshot.
pub fn polydata(time: Real, p: &ParticleView) -> String {
    let n = p.len();
    let mut s = String::with_capacity(120 * n + 256);
    s.push_str("# vtk DataFile Version 3.0\n");
    let _ = writeln!(s, "plugflow particles t = {time:e} s");
    s.push_str("ASCII\nDATASET POLYDATA\n");
    s.push_str("FIELD FieldData 1\nTIME 1 1 double\n");
    let _ = writeln!(s, "{time:e}");
    let _ = writeln!(s, "POINTS {n} double");
    for x in p.position {
        let _ = writeln!(s, "{:e} {:e} {:e}", x[0], x[1], x[2]);
    }
    let _ = writeln!(s, "VERTICES {n} {}", 2 * n);
    for i in 0..n {
        let _ = writeln!(s, "1 {i}");
    }
    let _ = writeln!(s, "POINT_DATA {n}");
    s.push_str("SCALARS radius double 1\nLOOKUP_TABLE default\n");
    for r in p.radius {
        let _ = writeln!(s, "{r:e}");
    }
    s.push_str("SCALARS id long 1\nLOOKUP_TABLE default\n");
    for id in p.id {
        let _ = writeln!(s, "{id}");
    }
    for (name, v) in [
        ("velocity", p.velocity),
        ("angular_velocity", p.angular_velocity),
    ] {
        let _ = writeln!(s, "VECTORS {name} double");
        for w in v {
            let _ = writeln!(s, "{:e} {:e} {:e}", w[0], w[1], w[2]);
        }
    }
    s
}

impl RunOutput for VtkOutput {
    fn sample(&mut self, _sample: &Sample) -> Result<(), OutputError> {
        Ok(())
    }

    fn snapshot(
        &mut self,
        time: Real,
        _step: u64,
        particles: &ParticleView,
    ) -> Result<(), OutputError> {
        let path = self.dir.join(format!("particles_{:06}.vtk", self.written));
        std::fs::write(&path, polydata(time, particles))
            .map_err(|e| OutputError::new(path.display(), e))?;
        self.written += 1;
        Ok(())
    }
}
