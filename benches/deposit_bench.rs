//! The grain ↔ grid kernels alone (seed 000 eqs. 7–9): the deposit of every grain's volume
//! and momentum onto the gas nodes, and the interpolation of the porosity and the pressure
//! gradient back to the grains, as one exchange of the coupled run does them. Two grids:
//! the horizontal case's 150 × 2 × 2 nodes over the 7 mm tube with 3000 grains (its mean
//! count at steady state, H2), and Lethe's 90 × 8 × 8 cut cells over the 84 mm pipe with
//! 32 000 grains. Grains are placed at random in the tube and sorted along the axis (the DEM
//! keeps them sorted by cell). Prints nanoseconds per grain of each kernel (median over the
//! repeats). Not a test: numbers depend on the machine.
//!
//! cargo bench --bench deposit_bench [-- --exchanges N] [--repeat R]

use std::time::Instant;

use plugflow::Real;
use plugflow_coupling::grid::{interpolate_scalar, interpolate_vec3};
use plugflow_coupling::{deposit, GranularFields, TubeGrid, Vec3};

mod common;
use common::flag;

/// A deterministic uniform stream in [0, 1) (a 64-bit LCG's upper bits).
struct Uniform(u64);

impl Uniform {
    fn next(&mut self) -> Real {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as Real / (1u64 << 53) as Real
    }
}

/// `count` grains of radius `r` at random inside a tube of `radius` and `length` along x,
/// sorted along the axis, with random velocities up to 1 m/s.
fn grains(count: usize, radius: Real, length: Real, r: Real) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut u = Uniform(42);
    let mut x = Vec::with_capacity(count);
    while x.len() < count {
        let (a, b) = (
            (2.0 * u.next() - 1.0) * (radius - r),
            (2.0 * u.next() - 1.0) * (radius - r),
        );
        if a * a + b * b <= (radius - r) * (radius - r) {
            x.push([u.next() * length, a, b]);
        }
    }
    x.sort_by(|p, q| p[0].total_cmp(&q[0]));
    let v = (0..count)
        .map(|_| [u.next(), u.next() - 0.5, u.next() - 0.5])
        .collect();
    (x, v)
}

fn run(label: &str, grid: &TubeGrid, count: usize, r: Real, exchanges: usize, repeat: usize) {
    let (x, v) = grains(count, grid.radius, grid.length, r);
    let radius = vec![r; count];
    let mut fields = GranularFields::default();
    let gradient: Vec<Vec3> = (0..grid.len())
        .map(|n| [1e3 + n as Real, 0.0, -1.0])
        .collect();
    let (mut dep, mut interp) = (Vec::new(), Vec::new());
    let mut checksum = 0.0;
    for _ in 0..repeat {
        let start = Instant::now();
        for _ in 0..exchanges {
            deposit(grid, &x, &v, &radius, &mut fields);
        }
        dep.push(start.elapsed().as_secs_f64() / (exchanges * count) as f64);
        let start = Instant::now();
        for _ in 0..exchanges {
            for st in fields.stencils.iter().flatten() {
                let g = interpolate_vec3(st, &gradient);
                checksum += interpolate_scalar(st, &fields.porosity) + g[0];
            }
        }
        interp.push(start.elapsed().as_secs_f64() / (exchanges * count) as f64);
    }
    // The fields' bits, folded: equal across builds when a change keeps them bitwise.
    let fingerprint = fields
        .porosity
        .iter()
        .chain(fields.velocity.iter().flatten())
        .fold(0u64, |h, v| (h ^ v.to_bits()).wrapping_mul(0x100000001b3));
    dep.sort_by(f64::total_cmp);
    interp.sort_by(f64::total_cmp);
    println!(
        "{label}: deposit {:.1} ns/grain, interpolation {:.1} ns/grain (median of {repeat}; \
         fields {fingerprint:016x}, interpolations' sum {checksum:.6e})",
        1e9 * dep[repeat / 2],
        1e9 * interp[repeat / 2],
    );
}

fn main() {
    let exchanges = flag::<usize>("--exchanges").unwrap_or(2000).max(1);
    let repeat = flag::<usize>("--repeat").unwrap_or(5).max(1);
    let horizontal = TubeGrid::new([0.0; 3], [1.0, 0.0, 0.0], 3.5e-3, 0.525, 150, 2, 2);
    run(
        "horizontal case, 150×2×2 nodes, 3000 grains",
        &horizontal,
        3000,
        0.7e-3,
        exchanges,
        repeat,
    );
    let mut lethe = TubeGrid::new([0.0; 3], [1.0, 0.0, 0.0], 0.042, 1.0, 90, 8, 8);
    lethe.periodic = true;
    run(
        "Lethe's pipe, 90×8×8 cut cells, 32000 grains",
        &lethe,
        32_000,
        2.5e-3,
        (exchanges / 10).max(1),
        repeat,
    );
}
