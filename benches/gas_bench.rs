//! The 3D SIMPLE gas alone on Lethe's dense-conveying grid (`cases/lethe_dense_conveying.toml`:
//! a periodic 84 mm × 1 m pipe, 90 × 8 × 8 cut cells, Di Felice's interphase drag, the flow
//! controller holding 3 m/s interstitial): a slug 0.5 m long (porosity 0.42, grains at
//! 0.83 m/s) over a resting layer 21 mm high, the slug moving on at 1.3 m/s from step to
//! step, the gas stepped every 5e-4 s as the coupled run steps it. Prints the milliseconds
//! per gas step (median over the repeats) and the SIMPLE iterations per step: the gas's
//! share of a 3D coupled run. Not a test: numbers depend on the machine.
//!
//! cargo bench --bench gas_bench [-- --steps N] [--repeat R]

use std::time::Instant;

use plugflow::gas::SimpleTubeGas;
use plugflow::Real;
use plugflow_coupling::drag::DiFelice;
use plugflow_coupling::{GasSolver, GranularFields, TubeGrid};

mod common;
use common::flag;

/// Lethe's pipe: radius, length, m; the grid's cells along and across.
const RADIUS: Real = 0.042;
const LENGTH: Real = 1.0;
const CELLS: [usize; 3] = [90, 8, 8];
/// The gas step (Lethe's CFD step), s.
const DT: Real = 5e-4;

/// The granular fields at time t: a resting layer below `LAYER` m from the bottom and a slug
/// of `SLUG` m centred at s = 0.5 + 1.3 t (periodic), both at the loose packing's porosity,
/// with smooth (tanh) ends a grain wide; the slug's grains move along the axis.
fn fields_at(grid: &TubeGrid, t: Real) -> GranularFields {
    const LAYER: Real = 0.021;
    const SLUG: Real = 0.5;
    const PACKED: Real = 0.42;
    const D: Real = 0.005;
    let n = grid.len();
    let mut f = GranularFields {
        porosity: vec![1.0; n],
        velocity: vec![[0.0; 3]; n],
        ..Default::default()
    };
    let centre = (0.5 + 1.3 * t).rem_euclid(LENGTH);
    for k in 0..grid.nz {
        let s = (k as Real + 0.5) * grid.dz;
        // Distance from the slug's centre across the seam.
        let mut ds = (s - centre).abs();
        ds = ds.min(LENGTH - ds);
        let in_slug = 0.5 * (1.0 - ((ds - 0.5 * SLUG) / D).tanh());
        for j in 0..grid.ny {
            let height = (j as Real + 0.5) * grid.dy; // from the bottom of the pipe
            let in_layer = 0.5 * (1.0 - ((height - LAYER) / D).tanh());
            let solid = (1.0 - PACKED) * in_slug.max(in_layer);
            for i in 0..grid.nx {
                let node = grid.node(k, i, j);
                f.porosity[node] = 1.0 - solid;
                f.velocity[node] = [0.83 * in_slug, 0.0, 0.0];
            }
        }
    }
    f
}

fn main() {
    let steps = flag::<usize>("--steps").unwrap_or(100).max(1);
    let repeat = flag::<usize>("--repeat").unwrap_or(3).max(1);
    let mut grid = TubeGrid::new(
        [0.0; 3],
        [1.0, 0.0, 0.0],
        RADIUS,
        LENGTH,
        CELLS[0],
        CELLS[1],
        CELLS[2],
    );
    grid.periodic = true;
    let viscosity = 1.80825e-5;
    let mut per_step = Vec::new();
    let mut iterations = 0;
    let mut solves = (0, 0);
    for _ in 0..repeat {
        let mut gas = SimpleTubeGas::new(grid.clone(), 1.205, viscosity, 3.0, 0.005, 0.2, None);
        gas.set_drag_law(std::sync::Arc::new(DiFelice { viscosity }))
            .expect("di_felice is a law of the slip");
        gas.gas.control_interstitial = true;
        // Settle the gas on the slug first (the first steps start from rest).
        for s in 0..10 {
            gas.step(&fields_at(&grid, s as Real * DT), DT)
                .expect("gas step");
        }
        let fields: Vec<GranularFields> = (0..steps)
            .map(|s| fields_at(&grid, (10 + s) as Real * DT))
            .collect();
        iterations = 0;
        let solves_before = gas.gas.pressure_solves();
        let start = Instant::now();
        for f in &fields {
            gas.step(f, DT).expect("gas step");
            iterations += gas.last_iterations;
        }
        per_step.push(start.elapsed().as_secs_f64() / steps as f64);
        let after = gas.gas.pressure_solves();
        solves = (after.0 - solves_before.0, after.1 - solves_before.1);
    }
    per_step.sort_by(f64::total_cmp);
    println!(
        "simple gas, {}×{}×{} periodic cut cells: {:.2} ms per step (median of {repeat}), \
         {:.1} SIMPLE iterations, {:.2} factorisations and {:.1} CG iterations per step",
        CELLS[0],
        CELLS[1],
        CELLS[2],
        1e3 * per_step[repeat / 2],
        iterations as f64 / steps as f64,
        solves.0 as f64 / steps as f64,
        solves.1 as f64 / steps as f64,
    );
}
