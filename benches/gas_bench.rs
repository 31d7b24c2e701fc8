//! The 3D SIMPLE gas alone on Lethe's dense-conveying grid (`cases/lethe_dense_conveying.toml`:
//! a periodic 84 mm × 1 m pipe, 90 × 8 × 8 cut cells, Di Felice's interphase drag, the flow
//! controller holding 3 m/s interstitial): a slug 0.5 m long (porosity 0.42, grains at
//! 0.83 m/s) over a resting layer 21 mm high, the slug moving on at 1.3 m/s from step to
//! step, the gas stepped every 5e-4 s as the coupled run steps it. Prints the milliseconds
//! per gas step (median over the repeats) and the SIMPLE iterations per step: the gas's
//! share of a 3D coupled run. Not a test: numbers depend on the machine.
//!
//! With `--model darcy`: the seeds' d'Arcy gas instead (`cases/horizontal_slug.toml`: the
//! 7 mm × 0.525 m tube on 150 × 2 × 2 nodes, BDF2, the band Cholesky), plugs 35 mm long
//! moving at 0.5 m/s over a settled layer, stepped every 1e-4 s with the pressure gradient
//! the drag reads after each step: microseconds per exchange, the gas's share of the
//! horizontal case's coupling.
//!
//! cargo bench --bench gas_bench [-- --steps N] [--repeat R] [--model darcy]

use std::time::Instant;

use plugflow::gas::{DarcyGas, DarcyParams, Scheme, SimpleTubeGas, SolvePath};
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

/// The empty tube's fields over n nodes: porosity 1, grains at rest.
fn empty_fields(n: usize) -> GranularFields {
    GranularFields {
        porosity: vec![1.0; n],
        velocity: vec![[0.0; 3]; n],
        ..Default::default()
    }
}

/// The granular fields at time t: a resting layer below `LAYER` m from the bottom and a slug
/// of `SLUG` m centred at s = 0.5 + 1.3 t (periodic), both at the loose packing's porosity,
/// with smooth (tanh) ends a grain wide; the slug's grains move along the axis.
fn fields_at(grid: &TubeGrid, t: Real) -> GranularFields {
    const LAYER: Real = 0.021;
    const SLUG: Real = 0.5;
    const PACKED: Real = 0.42;
    const D: Real = 0.005;
    let n = grid.len();
    let mut f = empty_fields(n);
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

/// The horizontal case's granular fields at time t: a settled layer a third of the tube high
/// (porosity 0.5) and plugs 35 mm long every 0.1 m (porosity 0.45, grains at 0.37 m/s)
/// moving on at 0.5 m/s; above the layer between plugs, the empty tube (clamped to 0.95).
fn horizontal_fields_at(grid: &TubeGrid, t: Real) -> GranularFields {
    const PLUG: Real = 0.035;
    const SPACING: Real = 0.1;
    let n = grid.len();
    let mut f = empty_fields(n);
    for k in 0..grid.nz {
        let s = (k as Real + 0.5) * grid.dz;
        let in_plug = (s - 0.5 * t).rem_euclid(SPACING) < PLUG;
        for j in 0..grid.ny {
            for i in 0..grid.nx {
                let node = grid.node(k, i, j);
                (f.porosity[node], f.velocity[node]) = if in_plug {
                    (0.45, [0.37, 0.0, 0.0])
                } else if j == 0 {
                    (0.5, [0.0; 3])
                } else {
                    (1.0, [0.0; 3])
                };
            }
        }
    }
    f
}

/// The d'Arcy gas on the horizontal case's grid: µs per exchange (a gas step and the
/// pressure gradient at the nodes), median over the repeats.
fn darcy(steps: usize, repeat: usize) {
    const DT: Real = 1e-4;
    let grid = TubeGrid::new([0.0; 3], [1.0, 0.0, 0.0], 0.0035, 0.525, 150, 2, 2);
    let params = DarcyParams {
        p0: 101_325.0,
        viscosity: 6.73e-5,
        grain_diameter: 1.4e-3,
        superficial_velocity: 2.3e-3 / 60.0 / (std::f64::consts::PI * 0.0035 * 0.0035),
        porosity_min: 0.3,
        porosity_max: 0.95,
        scheme: Scheme::Bdf2,
        path: SolvePath::Monolithic,
    };
    let fields: Vec<GranularFields> = (0..steps)
        .map(|s| horizontal_fields_at(&grid, s as Real * DT))
        .collect();
    let mut per_step = Vec::new();
    let mut fingerprint = 0u64;
    for _ in 0..repeat {
        let mut gas = DarcyGas::new(grid.clone(), params);
        let start = Instant::now();
        for f in &fields {
            gas.step(f, DT).expect("gas step");
            let grad = gas.pressure_gradient();
            fingerprint = fingerprint.rotate_left(1) ^ grad[grad.len() / 2][0].to_bits();
        }
        per_step.push(start.elapsed().as_secs_f64() / steps as f64);
        fingerprint ^= gas
            .pressure()
            .iter()
            .fold(0u64, |h, p| h.rotate_left(3) ^ p.to_bits());
    }
    per_step.sort_by(f64::total_cmp);
    println!(
        "darcy gas, 150×2×2 nodes (horizontal case): {:.2} µs per exchange (median of \
         {repeat}; step + pressure gradient), fingerprint {fingerprint:016x}",
        1e6 * per_step[repeat / 2],
    );
}

fn main() {
    let steps = flag::<usize>("--steps").unwrap_or(100).max(1);
    let repeat = flag::<usize>("--repeat").unwrap_or(3).max(1);
    if flag::<String>("--model").as_deref() == Some("darcy") {
        return darcy(steps, repeat);
    }
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
