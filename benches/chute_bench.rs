//! LAMMPS's own granular benchmark, `bench/in.chute`, on plugflow and on Debian's LAMMPS
//! (issue 22): ~32 000 spheres (d = 1, m = 1 in LJ units, here the same numbers in SI)
//! flowing down a chute periodic in x and y over a base of frozen grains, gravity 1 tilted
//! 26°, `gran/hooke/history` with k_n = 2e5, k_t = 2/7 k_n, γ_n = 50 (force m* γ_n v_n),
//! no shear damping (dampflag 0), μ = 0.5, dt = 1e-4, skin 0.1.
//!
//! LAMMPS's own data file is not shipped by Debian, so both engines start from one state
//! plugflow makes: a base of 800 frozen grains on a jittered 40 × 20 lattice and 31 104 free
//! grains on a loose lattice above, poured for `--pour` steps by plugflow, then written as a
//! LAMMPS data file (positions, velocities, spins) and as plugflow's `initial.file`. From it:
//!
//! - speed: `--steps N` steps on each engine, one core each, `--repeat R` times interleaved
//!   (a fresh engine each time, set-up not timed); medians; last line
//!   `ratio plugflow/lammps: X`;
//! - physics (`--profile M`): the mean down-slope velocity in layers of 2 d after M steps
//!   on both, beside plugflow's own run from the state nudged by 1e-12 d (the flow's chaos:
//!   how far two realisations of the same flow drift apart in M steps).
//!
//! Where the laws cannot be the same: plugflow's damping is a damping ratio from a
//! restitution, so a grain against a frozen one (m* = m, LAMMPS γ = 50 m) is damped by
//! γ = 2 ζ √(k m) = 35 m instead; grain pairs (m* = m/2) are damped alike.
//!
//! cargo bench --bench chute_bench [-- --steps N] [--repeat R] [--pour P] [--profile M]
//! (LAMMPS's `lmp` from `apt-get install lammps`; skipped with a message when missing)

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use plugflow::dem::NativeDem;
use plugflow::scene::Scene;
use plugflow_coupling::DemBackend;

mod common;
use common::flag;

const LX: f64 = 40.0;
const LY: f64 = 20.0;
const ZLO: f64 = -2.0;
const ZHI: f64 = 80.0;
/// LAMMPS's γ_n (1/time; its damping force is m* γ_n v_n) and k_n.
const GAMMA_N: f64 = 50.0;
const KN: f64 = 2e5;

/// One grain of the shared state.
#[derive(Clone, Copy)]
struct Grain {
    x: [f64; 3],
    v: [f64; 3],
    w: [f64; 3],
    frozen: bool,
}

fn main() {
    let steps = flag::<u64>("--steps").unwrap_or(1000);
    let repeat = flag::<u64>("--repeat").unwrap_or(5).max(1) as usize;
    let pour = flag::<u64>("--pour").unwrap_or(50_000);
    let profile = flag::<u64>("--profile").unwrap_or(0);
    let dir = std::env::temp_dir().join(format!("plugflow-chute-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch folder");

    // The shared state: the lattice, poured by plugflow.
    let lattice = initial_lattice();
    write_csv(&dir.join("lattice.csv"), &lattice);
    let mut pourer = engine(&dir, "lattice.csv");
    pourer.advance(pour).expect("pour");
    let state = grains_of(&pourer, &lattice);
    let n = state.len();
    write_csv(&dir.join("state.csv"), &state);
    write_lammps_data(&dir.join("data.chute"), &state);
    println!(
        "chute: {n} grains ({} frozen), poured {pour} steps by plugflow; timing {steps} steps, \
         {repeat} times each, one core",
        state.iter().filter(|g| g.frozen).count()
    );

    let lmp = which("lmp");
    if lmp.is_none() {
        println!("LAMMPS (`lmp`) not found: install it with `apt-get install lammps`; timing plugflow only");
    }
    let (mut ours, mut theirs) = (Vec::new(), Vec::new());
    for _ in 0..repeat {
        let mut e = engine(&dir, "state.csv");
        let t0 = Instant::now();
        e.advance(steps).expect("plugflow run");
        ours.push((n as u64 * steps) as f64 / t0.elapsed().as_secs_f64());
        if let Some(lmp) = &lmp {
            theirs.push(lammps_rate(lmp, &dir, steps, n));
        }
    }
    let (a, b) = (median(&mut ours), median(&mut theirs));
    println!("plugflow: {a:.3e} particle-steps/s (median of {repeat})");
    if lmp.is_some() {
        println!("LAMMPS  : {b:.3e} atom-steps/s (median of {repeat})");
        if profile > 0 {
            compare_profiles(lmp.as_deref().expect("found"), &dir, profile, &state);
        }
        println!("ratio plugflow/lammps: {:.2}", a / b);
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// The median (NaN for none).
fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// A base of frozen grains on a 1 d lattice with its heights jittered by up to ±0.15 d (a
/// rough floor), and free grains on a 1.1 d lattice above, at rest: fixed numbers, no
/// random source.
fn initial_lattice() -> Vec<Grain> {
    let mut g = Vec::new();
    let jitter = |k: usize, m: usize| ((k * 7919 + m * 104_729) % 1000) as f64 / 1000.0 - 0.5;
    for j in 0..LY as usize {
        for i in 0..LX as usize {
            let k = j * LX as usize + i;
            g.push(Grain {
                x: [i as f64 + 0.5, j as f64 + 0.5, 0.3 * jitter(k, 1)],
                v: [0.0; 3],
                w: [0.0; 3],
                frozen: true,
            });
        }
    }
    let (nx, ny) = ((LX / 1.1) as usize, (LY / 1.1) as usize);
    for l in 0..48 {
        for j in 0..ny {
            for i in 0..nx {
                let k = (l * ny + j) * nx + i;
                g.push(Grain {
                    x: [
                        (i as f64 + 0.5) * LX / nx as f64 + 0.02 * jitter(k, 2),
                        (j as f64 + 0.5) * LY / ny as f64 + 0.02 * jitter(k, 3),
                        1.2 + 1.1 * l as f64,
                    ],
                    v: [0.0; 3],
                    w: [0.0; 3],
                    frozen: false,
                });
            }
        }
    }
    g
}

/// The chute scene for plugflow, its grains from `file` in `dir`.
fn engine(dir: &Path, file: &str) -> NativeDem {
    let m_eff: f64 = 0.5;
    let zeta = m_eff * GAMMA_N / (2.0 * (KN * m_eff).sqrt());
    let restitution = (-std::f64::consts::PI * zeta / (1.0 - zeta * zeta).sqrt()).exp();
    let tilt = 26f64.to_radians();
    let text = format!(
        r#"
schema_version = 1
name = "chute"
duration = "1000 s"
gravity = [{gx}, 0, {gz}]
[domain]
min = [0, 0, {ZLO}]
max = [{LX}, {LY}, {ZHI}]
periodic = [true, true, false]
[particles]
diameter = "1 m"
density = "{rho} kg/m^3"
[contact]
normal = "hooke"
tangential = "history"
stiffness = "{KN} N/m"
restitution = {restitution}
friction = 0.5
tangential_damping = "0 kg/s"
[dem]
dt = "1e-4 s"
skin = "0.1 m"
threads = 1
[initial]
file = "{file}"
"#,
        gx = tilt.sin(),
        gz = -tilt.cos(),
        rho = 6.0 / std::f64::consts::PI,
    );
    let path = dir.join("chute.toml");
    std::fs::write(&path, text).expect("scene");
    let scene = Scene::load(&path, &[]).unwrap_or_else(|e| panic!("chute scene: {e}"));
    let cfg = plugflow::setup::dem_config(&scene).unwrap_or_else(|e| panic!("chute: {e}"));
    NativeDem::new(cfg).unwrap_or_else(|e| panic!("chute engine: {e}"))
}

/// The engine's grains in id order (ids number the file's lines), with the file's frozen
/// flags.
fn grains_of(e: &NativeDem, file: &[Grain]) -> Vec<Grain> {
    let p = e.particles();
    let mut out = file.to_vec();
    for k in 0..p.len() {
        let g = &mut out[p.id[k] as usize];
        g.x = p.position[k];
        // Back into the periodic box (a grain may stray past a face between builds).
        g.x[0] = g.x[0].rem_euclid(LX);
        g.x[1] = g.x[1].rem_euclid(LY);
        g.v = p.velocity[k];
        g.w = p.angular_velocity[k];
    }
    assert_eq!(p.len(), file.len(), "no grain lost while pouring");
    out
}

fn write_csv(path: &Path, g: &[Grain]) {
    let mut s = String::from("x,y,z,radius,vx,vy,vz,frozen\n");
    for g in g {
        s += &format!(
            "{:e},{:e},{:e},0.5,{:e},{:e},{:e},{}\n",
            g.x[0], g.x[1], g.x[2], g.v[0], g.v[1], g.v[2], g.frozen as u8
        );
    }
    std::fs::write(path, s).expect("csv");
}

/// The state as a LAMMPS data file (`atom_style sphere`: id type diameter density x y z;
/// velocities with spins), type 2 the frozen base, as `bench/in.chute` groups it.
fn write_lammps_data(path: &Path, g: &[Grain]) {
    let rho = 6.0 / std::f64::consts::PI;
    let mut s = format!(
        "plugflow chute state\n\n{} atoms\n2 atom types\n\n0 {LX} xlo xhi\n0 {LY} ylo yhi\n{ZLO} {ZHI} zlo zhi\n\nAtoms # sphere\n\n",
        g.len()
    );
    for (k, g) in g.iter().enumerate() {
        s += &format!(
            "{} {} 1 {rho:.17e} {:.17e} {:.17e} {:.17e}\n",
            k + 1,
            if g.frozen { 2 } else { 1 },
            g.x[0],
            g.x[1],
            g.x[2]
        );
    }
    s += "\nVelocities\n\n";
    for (k, g) in g.iter().enumerate() {
        s += &format!(
            "{} {:.17e} {:.17e} {:.17e} {:.17e} {:.17e} {:.17e}\n",
            k + 1,
            g.v[0],
            g.v[1],
            g.v[2],
            g.w[0],
            g.w[1],
            g.w[2]
        );
    }
    std::fs::write(path, s).expect("data file");
}

/// `bench/in.chute` on our data file for `steps` steps, dumping id z vx at the end.
fn lammps_input(steps: u64) -> String {
    format!(
        "units lj\natom_style sphere\nboundary p p fm\nnewton off\ncomm_modify vel yes\n\
         read_data data.chute\n\
         pair_style gran/hooke/history {KN} NULL {GAMMA_N} NULL 0.5 0\npair_coeff * *\n\
         neighbor 0.1 bin\nneigh_modify delay 5 every 1\ntimestep 0.0001\n\
         group bottom type 2\ngroup active subtract all bottom\n\
         neigh_modify exclude group bottom bottom\n\
         fix 1 all gravity 1.0 chute 26.0\nfix 2 bottom freeze\nfix 3 active nve/sphere\n\
         thermo 1000\nrun {steps}\n\
         write_dump all custom final.dump id z vx modify sort id\n"
    )
}

/// Atom-steps per second of one LAMMPS run (its own "Loop time").
fn lammps_rate(lmp: &Path, dir: &Path, steps: u64, n: usize) -> f64 {
    std::fs::write(dir.join("in.chute"), lammps_input(steps)).expect("input");
    let out = Command::new(lmp)
        .current_dir(dir)
        .args(["-in", "in.chute", "-log", "log.lammps"])
        .output()
        .expect("run lmp");
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text
        .lines()
        .find(|l| l.starts_with("Loop time of"))
        .unwrap_or_else(|| {
            panic!(
                "LAMMPS failed:\n{text}\n{}",
                String::from_utf8_lossy(&out.stderr)
            )
        });
    let secs: f64 = line
        .split_whitespace()
        .nth(3)
        .and_then(|s| s.parse().ok())
        .expect("loop time");
    let atoms = line
        .split_whitespace()
        .rev()
        .nth(1)
        .and_then(|s| s.parse::<usize>().ok())
        .expect("atom count");
    assert_eq!(atoms, n, "LAMMPS lost atoms");
    (n as u64 * steps) as f64 / secs
}

/// Mean down-slope velocity (x) of the free grains in layers 2 d thick, bottom up.
fn profile_of(z_vx: &[(f64, f64)]) -> Vec<f64> {
    let layers = 30;
    let (mut sum, mut count) = (vec![0.0; layers], vec![0usize; layers]);
    for &(z, vx) in z_vx {
        let k = ((z / 2.0).floor().max(0.0) as usize).min(layers - 1);
        sum[k] += vx;
        count[k] += 1;
    }
    sum.iter()
        .zip(&count)
        .map(|(s, &c)| if c >= 50 { s / c as f64 } else { f64::NAN })
        .collect()
}

/// Velocity profiles after `steps` steps: plugflow, plugflow from a nudged state, LAMMPS.
fn compare_profiles(lmp: &Path, dir: &Path, steps: u64, state: &[Grain]) {
    let run = |nudge: f64| {
        let mut s = state.to_vec();
        for (k, g) in s.iter_mut().enumerate() {
            if !g.frozen {
                g.x[2] += nudge * ((k % 7) as f64 - 3.0);
            }
        }
        write_csv(&dir.join("nudged.csv"), &s);
        let mut e = engine(dir, "nudged.csv");
        e.advance(steps).expect("profile run");
        let p = e.particles();
        let free: Vec<(f64, f64)> = (0..p.len())
            .filter(|&k| !state[p.id[k] as usize].frozen)
            .map(|k| (p.position[k][2], p.velocity[k][0]))
            .collect();
        profile_of(&free)
    };
    let (a, b) = (run(0.0), run(1e-12));
    std::fs::write(dir.join("in.chute"), lammps_input(steps)).expect("input");
    let out = Command::new(lmp)
        .current_dir(dir)
        .args(["-in", "in.chute", "-log", "log.lammps"])
        .output()
        .expect("run lmp");
    assert!(out.status.success(), "LAMMPS failed");
    let dump = std::fs::read_to_string(dir.join("final.dump")).expect("dump");
    let rows: Vec<(f64, f64)> = dump
        .lines()
        .skip_while(|l| !l.starts_with("ITEM: ATOMS"))
        .skip(1)
        .filter_map(|l| {
            let v: Vec<f64> = l
                .split_whitespace()
                .filter_map(|x| x.parse().ok())
                .collect();
            (v.len() == 3 && !state[v[0] as usize - 1].frozen).then(|| (v[1], v[2]))
        })
        .collect();
    let c = profile_of(&rows);
    println!("mean down-slope velocity after {steps} steps, layers of 2 d:");
    println!("| z | plugflow | plugflow nudged | LAMMPS |");
    let (mut chaos2, mut apart2, mut layers) = (0.0, 0.0, 0usize);
    for k in 0..a.len() {
        if a[k].is_nan() || b[k].is_nan() || c[k].is_nan() {
            continue;
        }
        println!(
            "| {:>4.0}–{:<4.0} | {:>9.4} | {:>9.4} | {:>9.4} |",
            2.0 * k as f64,
            2.0 * k as f64 + 2.0,
            a[k],
            b[k],
            c[k]
        );
        chaos2 += (a[k] - b[k]).powi(2);
        apart2 += (a[k] - c[k]).powi(2);
        layers += 1;
    }
    // The flow's chaos as the yardstick: how far plugflow's two realisations are apart,
    // layer by layer, against how far plugflow and LAMMPS are.
    let rms = |s: f64| (s / layers.max(1) as f64).sqrt();
    println!(
        "rms over {layers} layers: plugflow − LAMMPS {:.4}, plugflow − plugflow nudged (chaos) {:.4}; {}",
        rms(apart2),
        rms(chaos2),
        if apart2 <= 4.0 * chaos2 {
            "within twice the chaos"
        } else {
            "BEYOND twice the chaos"
        }
    );
}

/// The path of `program` on PATH, if any.
fn which(program: &str) -> Option<PathBuf> {
    std::env::var_os("PATH")?
        .to_str()?
        .split(':')
        .map(|d| Path::new(d).join(program))
        .find(|p| p.is_file())
}
