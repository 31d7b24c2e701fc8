//! The scene file schema (TOML, `schema_version = 1`). Every field: meaning, unit, default.
//!
//! Sections a scene leaves out are not computed: no `[inlet]`, no feeding; no `[[walls]]`,
//! no extra planes; `dem.rotation = false`, no angular velocities at all.

use serde::Deserialize;

use super::units::{
    Acceleration, Damping, Density, Finite, Length, MassFlow, Pressure, Rate, Stiffness, Time,
    Velocity, Viscosity, VolumeFlow, Q,
};

/// Current schema version; a scene must state it.
pub const SCHEMA_VERSION: u32 = 1;

/// A scene as written in the file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// Must equal [`SCHEMA_VERSION`].
    pub schema_version: u32,
    /// Case name; the default output folder is `results/<name>/`.
    pub name: String,
    /// Simulated time of the run, s (overridden by `plugflow run --duration`).
    pub duration: Q<Time>,
    /// Seed of the random numbers (inlet and initial placement). Default 1.
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// Gravity vector, m/s² (e.g. `[0, 0, -9.81]`; `[0, -9.81, 0]` for a horizontal tube along z).
    pub gravity: [Q<Acceleration>; 3],
    /// The conveying tube: an inner cylinder wall with optional end caps.
    pub tube: Option<TubeSpec>,
    /// Axis-aligned simulation box for scenes without a tube, m.
    pub domain: Option<DomainSpec>,
    /// Grain size and material.
    pub particles: ParticleSpec,
    /// Contact laws and their parameters.
    pub contact: ContactSpec,
    /// Engine settings. All fields have defaults.
    #[serde(default)]
    pub dem: DemSpec,
    /// Mass-flow inlet at the tube's inlet end.
    pub inlet: Option<InletSpec>,
    /// Grains placed before the run starts.
    pub initial: Option<InitialSpec>,
    /// Extra plane walls.
    #[serde(default)]
    pub walls: Vec<PlaneSpec>,
    /// Output settings.
    #[serde(default)]
    pub output: OutputSpec,
    /// The gas phase. Absent: no gas is solved (dry DEM).
    pub gas: Option<GasSpec>,
    /// Gas–grain coupling (needs `[gas]`).
    pub coupling: Option<CouplingSpec>,
}

/// Time scheme of the gas solver.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GasScheme {
    /// θ = 1: first order, L-stable.
    BackwardEuler,
    /// θ = ½: second order, rings at sharp porosity jumps (not L-stable).
    CrankNicolson,
    /// θ from `gas.theta`.
    Theta,
    /// Second-order backward differences: second order and L-stable.
    Bdf2,
}

/// Linear solution path of the gas solver.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GasSolverPath {
    /// Sparse Cholesky of the whole system (reference).
    Monolithic,
    /// Tridiagonal sweeps direction by direction (fast, O(Δt) splitting error).
    Splitting,
}

/// The gas: McNamara–Flekkøy pressure diffusion (`model = "darcy"`).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GasSpec {
    /// `darcy` (McNamara–Flekkøy pressure diffusion) or `simple` (volume-averaged
    /// Navier–Stokes, seed 004; 2D in the plane of the axis and the grid's second
    /// cross direction).
    pub model: String,
    /// Gas density, kg/m³ (`simple` only: it carries the gas's inertia), at `pressure`.
    pub density: Option<Q<Density>>,
    /// `simple` only: `constant` density (default) or `ideal_gas` (isothermal: ρ =
    /// density × (P0 + p)/P0, p the gauge pressure, 0 at the outlet). The d'Arcy model is an
    /// ideal gas by construction and takes no choice.
    pub equation_of_state: Option<String>,
    /// (Effective) dynamic viscosity η, Pa·s.
    pub viscosity: Q<Viscosity>,
    /// Background pressure P0, Pa.
    pub pressure: Q<Pressure>,
    /// Superficial gas velocity v_s at the inlet, m/s (give this or `flow`).
    pub superficial_velocity: Option<Q<Velocity>>,
    /// Volume flow of gas at P0, m³/s (v_s = 4 V̇ / (π D²)).
    pub flow: Option<Q<VolumeFlow>>,
    /// A periodic section's flow controller, `simple` gas: what it holds at
    /// `superficial_velocity`'s value. `superficial` (default): the section's mean
    /// superficial velocity (1/V) ∫ ε u dV; `interstitial`: the gas's own mean velocity
    /// ∫ ε u dV / ∫ ε dV (Lethe's flow control), larger by 1/ε̄.
    pub controlled_velocity: Option<String>,
    /// Nodes along the axis and across the tube, e.g. `[150, 2, 2]`. d'Arcy: 1 or 2 across;
    /// simple: `[nz, 1, ny]` (2D, ny ≤ 8) or 2–64 in each cross direction (3D cut-cell tube).
    pub grid: [usize; 3],
    /// Time scheme. Default `bdf2`.
    #[serde(default = "default_scheme")]
    pub scheme: GasScheme,
    /// θ of the `theta` scheme, in [0.5, 1].
    pub theta: Option<Finite>,
    /// Linear solution path. Default `monolithic`.
    #[serde(default = "default_path")]
    pub solver: GasSolverPath,
    /// Porosity clamp, lower bound. Default 0.3.
    #[serde(default = "default_phi_min")]
    pub porosity_min: Finite,
    /// Porosity clamp, upper bound (κ diverges at φ = 1). Default 0.99.
    #[serde(default = "default_phi_max")]
    pub porosity_max: Finite,
}

fn default_scheme() -> GasScheme {
    GasScheme::Bdf2
}
fn default_path() -> GasSolverPath {
    GasSolverPath::Monolithic
}
fn default_phi_min() -> Finite {
    Finite(0.3)
}
fn default_phi_max() -> Finite {
    Finite(0.99)
}

/// Gas–grain coupling.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CouplingSpec {
    /// Coupling interval Δt_c, s: a whole number of DEM steps. Default 10 DEM steps.
    pub interval: Option<Q<Time>>,
    /// Drag law: `darcy` (the seeds' volume force, with the `darcy` gas), `ergun_wen_yu`
    /// (seed 004 eqs. 12–13) or `di_felice` (with the `simple` gas). Default `darcy`.
    #[serde(default = "default_drag")]
    pub drag: String,
    /// C_V of seed 004 eq. 11, in (0, 1]: the `ergun_wen_yu` drag sees the voidage C_V ε, for
    /// a two-dimensional model whose cells, one grain thick, hold more void than the bed it
    /// stands for. Only with `ergun_wen_yu`. Default 1 (the voidage as it is).
    pub voidage_factor: Option<Finite>,
    /// Fluid forces on the grains besides the drag, by name (`pressure_gradient`,
    /// `buoyancy`, `saffman_mei_lift`; coupling/src/fluid_force/). Default: the
    /// `pressure_gradient` with the `simple` gas (its momentum equation needs it), none with
    /// the `darcy` gas (the d'Arcy volume force is the whole fluid force).
    pub fluid_forces: Option<Vec<String>>,
    /// Spread the deposited solid fraction and granular velocity over this length (as
    /// Lethe's and CFDEMcoupling's smoothing of the void fraction; ~2 grain diameters), by
    /// a diffusion that conserves both: on cells near the grain size the loose rim of a
    /// packing at the wall otherwise shows as a channel. Default: none (the tent deposit).
    pub smoothing_length: Option<Q<Length>>,
    /// The volume a node's solid fraction is taken over: `open` (default: the fluid volume
    /// of its wall-cut cell) or `whole_cell` (the whole grid cell l_z l_x l_y, walls
    /// ignored: seed 000 eq. 8 read with the tent function normalised by the cubic grid's
    /// cell, as a grid that does not know the tube's wall deposits; a 2 × 2 grid across a
    /// tube then sees (π/4) of the solid fraction). A reading of the paper, to test how far
    /// it moves the results; `darcy` gas, full tube, no smoothing.
    #[serde(default)]
    pub porosity_volume: PorosityVolume,
}

/// See [`CouplingSpec::porosity_volume`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PorosityVolume {
    #[default]
    Open,
    WholeCell,
}

impl SceneFile {
    /// The fluid forces besides the drag this scene switches on, in its order (the default
    /// of [`CouplingSpec::fluid_forces`] when it names none).
    pub fn fluid_forces(&self) -> Vec<String> {
        let simple = self.gas.as_ref().is_some_and(|g| g.model == "simple");
        match self.coupling.as_ref().and_then(|c| c.fluid_forces.clone()) {
            Some(names) => names,
            None if simple => vec!["pressure_gradient".into()],
            None => Vec::new(),
        }
    }
}

fn default_drag() -> String {
    "darcy".into()
}

fn default_seed() -> u64 {
    1
}

/// An end of the tube: closed by a flat cap wall, or open (grains past it leave the domain).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TubeEnd {
    /// A flat wall (gas-permeable for the gas solver) stops the grains.
    Closed,
    /// Grains whose centre passes the end are removed and counted.
    Open,
}

/// The tube: a cylinder from `origin` (inlet end) along `axis` for `length`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TubeSpec {
    /// Inner diameter, m.
    pub diameter: Q<Length>,
    /// Length, m.
    pub length: Q<Length>,
    /// Direction from inlet to outlet (normalised on load). Default `[0, 0, 1]`.
    #[serde(default = "default_axis")]
    pub axis: [Finite; 3],
    /// Centre of the inlet end, m. Default origin.
    #[serde(default = "default_origin")]
    pub origin: [Q<Length>; 3],
    /// Inlet end. Default `closed`.
    pub inlet_end: Option<TubeEnd>,
    /// Outlet end. Default `open`.
    pub outlet_end: Option<TubeEnd>,
    /// A periodic section of a long pipe: grains leaving one end come back at the other,
    /// touching grains across the seam (no ends, no inlet). Axis along x, y or z. Default
    /// false.
    #[serde(default)]
    pub periodic: bool,
    /// Quasi-2D (as seed 004's model): the grains live in a slab this thick through the axis,
    /// between two planes normal to the gas grid's first cross direction; the gas grid
    /// counts only the slab's volume. At least one grain diameter, below the tube's.
    pub slab: Option<Q<Length>>,
    /// Friction coefficient of the slab's two planes. Default 0: in the 2D model the slab
    /// stands for, nothing rubs the grains front and back; give `contact.wall_friction` here
    /// to model a real Hele-Shaw cell. Needs `slab`.
    pub slab_friction: Option<Finite>,
}

fn default_axis() -> [Finite; 3] {
    [Finite(0.0), Finite(0.0), Finite(1.0)]
}
fn default_origin() -> [Q<Length>; 3] {
    [Q::si(0.0), Q::si(0.0), Q::si(0.0)]
}

/// An axis-aligned box, m. Grains leaving it are removed (counted as lost).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DomainSpec {
    /// Lower corner, m.
    pub min: [Q<Length>; 3],
    /// Upper corner, m.
    pub max: [Q<Length>; 3],
    /// Per direction (x, y, z): grains leaving one face come back at the opposite one.
    /// Default none (grains leaving the box are removed).
    #[serde(default)]
    pub periodic: [bool; 3],
}

impl TubeSpec {
    /// The inlet end as the tube has it (`closed` unless given; none when periodic).
    pub fn inlet(&self) -> TubeEnd {
        self.inlet_end.unwrap_or(TubeEnd::Closed)
    }

    /// The outlet end as the tube has it (`open` unless given; none when periodic).
    pub fn outlet(&self) -> TubeEnd {
        self.outlet_end.unwrap_or(TubeEnd::Open)
    }
}

/// Grain size and material: either `diameter` (monodisperse) or `diameter_min` and
/// `diameter_max` (uniform distribution of diameters).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParticleSpec {
    /// Diameter of monodisperse spheres, m.
    pub diameter: Option<Q<Length>>,
    /// Smallest diameter of a polydisperse mix, m.
    pub diameter_min: Option<Q<Length>>,
    /// Largest diameter of a polydisperse mix, m.
    pub diameter_max: Option<Q<Length>>,
    /// Material density, kg/m³.
    pub density: Q<Density>,
}

/// Normal contact law.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NormalLawName {
    /// Linear spring–dashpot (seeds 000, 002).
    Hooke,
    /// Hertz with Tsuji damping (seed 004 eqs. 4–9).
    Hertz,
}

/// Tangential contact law.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TangentialLawName {
    /// The seeds' regularised Coulomb law: min(μ|F_n|, γ_t |v_t|) against the slip.
    CoulombViscous,
    /// Cundall–Strack spring with contact history, capped by μ|F_n| (LAMMPS's
    /// `gran/hooke/history` conventions).
    History,
    /// The same spring with LIGGGHTS's conventions (`tangential history`: the spring alone
    /// capped by μ|F_n|, no dashpot while sliding), to cross-validate against LIGGGHTS.
    LiggghtsHistory,
}

/// Rolling-resistance law.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RollingLawName {
    /// Free rolling: no torque but the tangential force's (the default).
    #[default]
    None,
    /// Constant directional torque μ_r R* F_n,el against the relative rolling, as LIGGGHTS's
    /// `rolling_friction cdt` reads it: the elastic normal force, twisting not resisted.
    ConstantTorque,
    /// The same torque as Lethe's `constant_resistance` reads it: μ_r R* |F_n| with the
    /// whole normal force, against the whole relative rotation (twist included).
    ConstantResistance,
}

impl RollingLawName {
    /// The name a scene file gives the law (`contact.rolling`).
    pub fn scene_name(self) -> &'static str {
        match self {
            RollingLawName::None => "none",
            RollingLawName::ConstantTorque => "constant_torque",
            RollingLawName::ConstantResistance => "constant_resistance",
        }
    }
}

/// Contact parameters.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactSpec {
    /// `hooke` or `hertz`.
    pub normal: NormalLawName,
    /// `history` (default), `liggghts_history` or `coulomb_viscous`.
    #[serde(default = "default_tangential")]
    pub tangential: TangentialLawName,
    /// Coulomb friction coefficient μ ≥ 0, grain–grain.
    pub friction: Finite,
    /// Coefficient of normal restitution e in (0, 1], grain–grain.
    pub restitution: Finite,
    /// Hooke: normal spring stiffness k_n, N/m (give this or `contact_time`).
    pub stiffness: Option<Q<Stiffness>>,
    /// Hooke: duration of a binary collision of two mean grains, s (sets k_n).
    pub contact_time: Option<Q<Time>>,
    /// Hooke + history: k_t / k_n. Default 2/7 (equal normal and tangential periods).
    pub tangential_stiffness_ratio: Option<Finite>,
    /// Hertz: Young's modulus E, Pa.
    pub youngs_modulus: Option<Q<Pressure>>,
    /// Hertz: Poisson ratio ν in [0, 0.5).
    pub poisson_ratio: Option<Finite>,
    /// Tangential viscous coefficient γ_t, kg/s. `coulomb_viscous`: default the pair's
    /// normal damping coefficient (η_t = η_n as in seed 004); `history`: the shear spring's
    /// dashpot, default the normal law's damping ratio on k_t (0: none, LAMMPS's dampflag 0).
    pub tangential_damping: Option<Q<Damping>>,
    /// Grain–wall friction: the pair's coefficient, as LIGGGHTS's `coefficientFriction`
    /// holds it for the grain and wall types. (A code that gives the wall a value of its own
    /// combines it with the grain's: Lethe takes the harmonic mean 2 μ_p μ_w/(μ_p + μ_w).)
    /// Default: `friction`.
    pub wall_friction: Option<Finite>,
    /// Grain–wall restitution (the pair's, as `wall_friction`). Default: `restitution`.
    pub wall_restitution: Option<Finite>,
    /// Rolling resistance: `none` (default), `constant_torque` (LIGGGHTS's `cdt`) or
    /// `constant_resistance` (Lethe's reading of the same law).
    #[serde(default)]
    pub rolling: RollingLawName,
    /// `constant_torque`, `constant_resistance`: coefficient of rolling friction μ_r ≥ 0,
    /// grain–grain.
    pub rolling_friction: Option<Finite>,
    /// `constant_torque`, `constant_resistance`: grain–wall μ_r. Default: `rolling_friction`.
    pub wall_rolling_friction: Option<Finite>,
}

fn default_tangential() -> TangentialLawName {
    TangentialLawName::History
}

/// Engine settings.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DemSpec {
    /// DEM engine: `native` (default, built in), `native_abi` (the built-in engine through
    /// the C ABI, libplugflow_dem_native.so), `liggghts` (LIGGGHTS through the C ABI,
    /// libplugflow_dem_liggghts.so, built with the `liggghts` feature).
    #[serde(default = "default_engine")]
    pub engine: String,
    /// Shared library implementing the DEM ABI for `engine` (default: the plugflow build's
    /// own, next to the `plugflow` executable).
    pub library: Option<String>,
    /// Your own LIGGGHTS input for the DEM part (engine `liggghts` only), written as for
    /// CFDEMcoupling: plugflow drops its `run` lines and `couple/cfd` fixes and adds only
    /// the fluid-force fixes it needs. Relative to the scene file's folder.
    pub liggghts_input: Option<String>,
    /// Run an ABI engine in a child process (`plugflow-dem-host`): an engine that ends its
    /// process (LIGGGHTS on an error) ends only the child, and the run stops with the
    /// engine's last words and keeps what it computed. Default false.
    #[serde(default)]
    pub isolate: bool,
    /// Time step, s. Default: contact time / `dt_fraction`. Refused above the stability limit.
    pub dt: Option<Q<Time>>,
    /// Steps per contact time when `dt` is derived. Default 30: at steady state the vertical
    /// case's V1–V5 at t_c/30 and t_c/50 agree within one standard error over three seeds
    /// (README, "Choosing accuracy"), for 35 % less wall time.
    #[serde(default = "default_dt_fraction")]
    pub dt_fraction: Finite,
    /// Integrate rotations. Default true; false computes no angular velocity at all.
    #[serde(default = "default_true")]
    pub rotation: bool,
    /// Verlet skin, m. Default 0.1 × largest diameter.
    pub skin: Option<Q<Length>>,
    /// Worker threads of the force loop. Default 1 (results are bitwise reproducible for a
    /// given thread count).
    #[serde(default = "default_threads")]
    pub threads: usize,
    /// Largest impact velocity expected, m/s: sets the Hertz contact time. Default 1 m/s.
    #[serde(default = "default_impact_velocity")]
    pub max_impact_velocity: Q<Velocity>,
    /// Let the `[initial]` grains settle under gravity, the DEM alone, for this long before
    /// the run starts (its clock starts after: the gas and the inlet see a bed at rest).
    pub settle: Option<Q<Time>>,
}

impl Default for DemSpec {
    fn default() -> Self {
        Self {
            engine: default_engine(),
            library: None,
            liggghts_input: None,
            isolate: false,
            dt: None,
            dt_fraction: default_dt_fraction(),
            rotation: true,
            skin: None,
            threads: default_threads(),
            max_impact_velocity: default_impact_velocity(),
            settle: None,
        }
    }
}

fn default_engine() -> String {
    "native".into()
}
fn default_dt_fraction() -> Finite {
    Finite(30.0)
}
fn default_true() -> bool {
    true
}
fn default_threads() -> usize {
    1
}
fn default_impact_velocity() -> Q<Velocity> {
    Q::si(1.0)
}

/// How the inlet puts grains into the tube.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InletMode {
    /// Batches placed at random without overlap wherever the slab has room, moving along the
    /// axis at `velocity` (as LIGGGHTS's `insert/rate/region`): a bed pressing on the slab
    /// slows or stops the feed, and random placement cannot exceed ~38 % solids.
    #[default]
    Slab,
    /// A column packed at `porosity` pushed into the tube at `velocity` and held to that
    /// motion over the slab (grains released as they leave it): the mass flow is enforced
    /// whatever presses on the slab, as the seeds' simulations inject (seed 000 §4: "injected
    /// from the bottom at a constant mass flow rate", porosity 0.51 at 0.04 m/s).
    Conveyor,
}

/// Mass-flow inlet at the tube's inlet end, feeding grains at `porosity` along the axis at
/// `velocity` over a slab at the tube's start, in one of two [`InletMode`]s. Give
/// `mass_flow` or `rate`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InletSpec {
    /// `"slab"` (default) or `"conveyor"`.
    #[serde(default)]
    pub mode: InletMode,
    /// Granular mass flow, kg/s.
    pub mass_flow: Option<Q<MassFlow>>,
    /// Grains per second.
    pub rate: Option<Q<Rate>>,
    /// Porosity of the fed grains, in (0, 1).
    pub porosity: Finite,
    /// Feed velocity along the tube axis, m/s (≥ 0).
    pub velocity: Q<Velocity>,
    /// Length of the insertion slab, m. Default 3 × largest diameter.
    pub slab_length: Option<Q<Length>>,
    /// Feeding stops at this time, s (a feeder valve closing; seed 004 at 10 s). Default:
    /// feeds to the end.
    pub until: Option<Q<Time>>,
}

/// Grains placed at random lattice sites between two axial positions before the run.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InitialSpec {
    /// Number of grains placed at random (not with `file`).
    pub count: Option<u64>,
    /// Start of the filled stretch along the tube axis (or z without a tube), m. With
    /// `from` and `to` the stretch is filled across the whole section: a plug.
    pub from: Option<Q<Length>>,
    /// End of the filled stretch, m.
    pub to: Option<Q<Length>>,
    /// Initial velocity of every grain, m/s. Default zero.
    pub velocity: Option<[Q<Velocity>; 3]>,
    /// A resting layer this high above the tube's lowest line (against gravity), along the
    /// whole tube, m; with `from`/`to` as well, the grains fill the plug and the layer.
    pub layer_height: Option<Q<Length>>,
    /// The plug's end faces inclined to the axis by this angle, degrees (90: square ends;
    /// 45: each face leans out by the tube's height, the plug longer at the bottom).
    pub end_angle: Option<Finite>,
    /// Grains from a file instead of placed ones: CSV with the header `x,y,z,radius` and
    /// optionally `vx,vy,vz` (SI units), one grain per line; relative to the scene's folder.
    pub file: Option<String>,
}

/// A plane wall; grains live on the side its normal points to.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlaneSpec {
    /// Name used in wall-force reports.
    pub name: String,
    /// A point on the plane, m.
    pub point: [Q<Length>; 3],
    /// Normal pointing into the domain (normalised on load).
    pub normal: [Finite; 3],
}

/// Output settings.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSpec {
    /// Interval between samples of the tube content, s. Default 0.01 s.
    #[serde(default = "default_sample")]
    pub sample_interval: Q<Time>,
    /// Time before which samples do not enter the means (the tube fills), s. Default 0.
    #[serde(default)]
    pub settling_time: Option<Q<Time>>,
    /// Slice length of the plug statistics, m. Default 3.5 mm (the seeds').
    pub slice_length: Option<Q<Length>>,
    /// Rows of shared/TARGETS.md this case reproduces (e.g. `["V1", "V2"]`); the summary
    /// lists each with the measured value, the paper's and the band.
    #[serde(default)]
    pub reproduces: Vec<String>,
    /// Particle snapshots (positions, velocities, radii, ids). None unless asked: a scene
    /// without this table writes none and pays nothing for them.
    pub snapshots: Option<SnapshotSpec>,
    /// Which plugs the profiles average over (default: 1–6 cm long, 0–1 m/s, centre in the
    /// middle 20 % of the tube).
    pub profiles: Option<ProfileSpec>,
    /// Differential pressure transducers (seed 004's DP1): p(from) − p(to) at every sample,
    /// written to `pressure_taps.csv`, drawn in `pressure_taps.png`, summarised in the
    /// summary's `pressure_taps`. Needs a gas.
    #[serde(default)]
    pub pressure_taps: Vec<PressureTapSpec>,
    /// Simulated time between checkpoints, s (rounded to whole samples; the last two are
    /// kept in `checkpoints/`, and one is written at the run's end or stop): `plugflow run
    /// --resume DIR` goes on from the latest, bit for bit as if never stopped. None: no
    /// checkpoints (the built-in engine only).
    pub checkpoint_interval: Option<Q<Time>>,
}

/// A differential pressure transducer between two positions along the tube axis.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PressureTapSpec {
    /// Name in outputs (e.g. "DP1").
    pub name: String,
    /// Upstream tap, m from the inlet end.
    pub from: Q<Length>,
    /// Downstream tap, m from the inlet end.
    pub to: Q<Length>,
}

/// Plug selection windows of the profiles.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProfileSpec {
    /// Plug length range [lo, hi], m.
    pub plug_length: Option<[Q<Length>; 2]>,
    /// Tracked plug velocity range [lo, hi], m/s.
    pub plug_velocity: Option<[Q<Velocity>; 2]>,
    /// Plug centre range along the tube, as fractions of its length [lo, hi].
    pub centre: Option<[Finite; 2]>,
}

impl Default for OutputSpec {
    fn default() -> Self {
        Self {
            sample_interval: default_sample(),
            settling_time: None,
            slice_length: None,
            reproduces: Vec::new(),
            snapshots: None,
            profiles: None,
            pressure_taps: Vec::new(),
            checkpoint_interval: None,
        }
    }
}

/// Particle snapshots written while the run goes.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SnapshotSpec {
    /// Interval between snapshots, s (rounded up to whole sample intervals).
    pub interval: Q<Time>,
    /// Where: `"hdf5"` (group `/particles` of run.h5) and/or `"vtk"` (ParaView's VTK XML:
    /// `particles_NNNNNN.vtp`, `gas_NNNNNN.vts`, the series `particles.pvd` and `gas.pvd`
    /// with the simulated times, `geometry.vtp`).
    pub formats: Vec<SnapshotFormat>,
}

/// A particle snapshot format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SnapshotFormat {
    /// Into run.h5.
    Hdf5,
    /// Legacy VTK files readable by ParaView.
    Vtk,
}

fn default_sample() -> Q<Time> {
    Q::si(0.01)
}
