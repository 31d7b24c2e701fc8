//! The built-in engine's configuration: contact laws, time step and its stability limit,
//! walls, box, inlet (built from a scene by `crate::dem_config`).

use super::contact::{
    ConstantTorque, CoulombViscous, Hertz, History, Hooke, LiggghtsHistory, NormalLaw, RollingPair,
    TangentialLaw,
};
use super::forces::Laws;
use super::placement::Region;
use super::walls::Wall;
pub use crate::scene::InletMode;
use crate::{Real, Vec3};
use std::f64::consts::PI;

/// The scene's contact laws: one arm per normal law, each holding one arm per tangential law
/// ([`TangentialSet`]), so every pair exists without a hand-written product list and each
/// pair is monomorphised into its own force loop. A new normal law is one arm here, a new
/// tangential law one arm in [`TangentialSet`]; code that runs the laws goes through
/// [`LawSet::visit`] and names no pair.
#[derive(Debug, Clone)]
pub enum LawSet {
    Hooke(TangentialSet<Hooke>),
    Hertz(TangentialSet<Hertz>),
}

/// The tangential law paired with normal law `N`.
#[derive(Debug, Clone)]
pub enum TangentialSet<N> {
    History(Laws<N, History>),
    LiggghtsHistory(Laws<N, LiggghtsHistory>),
    CoulombViscous(Laws<N, CoulombViscous>),
}

/// Something to do with the laws, whichever pair they are: [`LawSet::visit`] calls
/// [`LawVisitor::visit`] with the concrete `Laws<N, T>`, so the work is compiled per pair.
pub trait LawVisitor {
    type Out;
    fn visit<N: NormalLaw, T: TangentialLaw>(self, laws: &Laws<N, T>) -> Self::Out;
}

impl<N: NormalLaw> TangentialSet<N> {
    /// Build the pair from the grain–grain and grain–wall normal laws and the tangential one.
    pub fn new(
        tangential: TangentialChoice,
        pp_normal: N,
        pw_normal: N,
        mu_pp: Real,
        mu_pw: Real,
    ) -> Self {
        fn laws<N, T>(
            pp_normal: N,
            pw_normal: N,
            pp_tangential: T,
            pw_tangential: T,
        ) -> Laws<N, T> {
            Laws {
                pp_normal,
                pp_tangential,
                pw_normal,
                pw_tangential,
                wall_tangential: Vec::new(),
            }
        }
        match tangential {
            TangentialChoice::History { gamma_t } => TangentialSet::History(laws(
                pp_normal,
                pw_normal,
                History { mu: mu_pp, gamma_t },
                History { mu: mu_pw, gamma_t },
            )),
            TangentialChoice::LiggghtsHistory { gamma_t } => TangentialSet::LiggghtsHistory(laws(
                pp_normal,
                pw_normal,
                LiggghtsHistory { mu: mu_pp, gamma_t },
                LiggghtsHistory { mu: mu_pw, gamma_t },
            )),
            TangentialChoice::CoulombViscous { gamma_t } => TangentialSet::CoulombViscous(laws(
                pp_normal,
                pw_normal,
                CoulombViscous { mu: mu_pp, gamma_t },
                CoulombViscous { mu: mu_pw, gamma_t },
            )),
        }
    }

    fn visit<V: LawVisitor>(&self, v: V) -> V::Out {
        match self {
            TangentialSet::History(l) => v.visit(l),
            TangentialSet::LiggghtsHistory(l) => v.visit(l),
            TangentialSet::CoulombViscous(l) => v.visit(l),
        }
    }

    fn attach_walls(&mut self, walls: &[Wall]) {
        match self {
            TangentialSet::History(l) => l.attach_walls(walls),
            TangentialSet::LiggghtsHistory(l) => l.attach_walls(walls),
            TangentialSet::CoulombViscous(l) => l.attach_walls(walls),
        }
    }

    /// The grain–grain and grain–wall normal laws.
    pub fn normal(&self) -> (&N, &N) {
        match self {
            TangentialSet::History(l) => (&l.pp_normal, &l.pw_normal),
            TangentialSet::LiggghtsHistory(l) => (&l.pp_normal, &l.pw_normal),
            TangentialSet::CoulombViscous(l) => (&l.pp_normal, &l.pw_normal),
        }
    }
}

/// The tangential law a scene asks for, with the settings only it takes.
#[derive(Debug, Clone, Copy)]
pub enum TangentialChoice {
    /// Shear spring with history, capped by Coulomb friction; `gamma_t` its dashpot (None:
    /// the normal law's damping ratio on the shear spring).
    History { gamma_t: Option<Real> },
    /// The same spring with LIGGGHTS's conventions (cap on the spring alone, no dashpot
    /// while sliding).
    LiggghtsHistory { gamma_t: Option<Real> },
    /// Viscous shear capped by Coulomb friction; `gamma_t` the damping (None: the normal's).
    CoulombViscous { gamma_t: Option<Real> },
}

impl LawSet {
    /// Run `v` on the concrete pair.
    pub fn visit<V: LawVisitor>(&self, v: V) -> V::Out {
        match self {
            LawSet::Hooke(t) => t.visit(v),
            LawSet::Hertz(t) => t.visit(v),
        }
    }

    /// True when contacts keep a shear history.
    pub fn uses_history(&self) -> bool {
        struct UsesHistory;
        impl LawVisitor for UsesHistory {
            type Out = bool;
            fn visit<N: NormalLaw, T: TangentialLaw>(self, _: &Laws<N, T>) -> bool {
                T::USES_HISTORY
            }
        }
        self.visit(UsesHistory)
    }

    /// Collision time of a grain pair with effective mass and radius at speed `v`, s.
    pub fn pair_contact_time(&self, m_eff: Real, r_eff: Real, v: Real) -> Real {
        struct ContactTime(Real, Real, Real);
        impl LawVisitor for ContactTime {
            type Out = Real;
            fn visit<N: NormalLaw, T: TangentialLaw>(self, l: &Laws<N, T>) -> Real {
                l.pp_normal.contact_time(self.0, self.1, self.2)
            }
        }
        self.visit(ContactTime(m_eff, r_eff, v))
    }

    /// Give each wall its tangential law (see [`Laws::attach_walls`]).
    pub fn attach_walls(&mut self, walls: &[Wall]) {
        match self {
            LawSet::Hooke(t) => t.attach_walls(walls),
            LawSet::Hertz(t) => t.attach_walls(walls),
        }
    }
}

/// The scene's rolling-resistance law, one arm per law (`contact.rolling`): the force loop
/// is compiled once per arm ([`RollingSet::None`] adds no work to it).
#[derive(Debug, Clone, Default)]
pub enum RollingSet {
    /// Free rolling (the default).
    #[default]
    None,
    /// Constant directional torque (`constant_torque`).
    ConstantTorque(RollingPair<ConstantTorque>),
}

/// Tube geometry in engine terms.
#[derive(Debug, Clone, Copy)]
pub struct TubeGeometry {
    /// Centre of the inlet end, m.
    pub origin: Vec3,
    /// Unit axis from inlet to outlet.
    pub axis: Vec3,
    /// Inner radius, m.
    pub radius: Real,
    /// Length, m.
    pub length: Real,
    /// Grains may leave through the inlet end.
    pub inlet_open: bool,
    /// Grains leave through the outlet end (counted as outflow).
    pub outlet_open: bool,
    /// A periodic section: no ends; grains leaving one come back at the other.
    pub periodic: bool,
    /// Quasi-2D: half the slab's thickness, m (the grains keep |(x − origin)·e1| ≤ this).
    pub slab_half: Option<Real>,
}

/// The inlet in engine terms.
#[derive(Debug, Clone, Copy)]
pub struct InletConfig {
    /// Random placement in the slab, or a packed column pushed in.
    pub mode: InletMode,
    /// Grains per second.
    pub rate: Real,
    /// Feed speed along the axis, m/s.
    pub velocity: Real,
    /// Insertion slab length, m.
    pub slab_length: Real,
    /// Grains per full slab at the requested porosity.
    pub batch_target: usize,
    /// Requested porosity (the conveyor's: the one its rate and velocity make).
    pub porosity: Real,
    /// Feeding stops at this time, s (None: never).
    pub until: Option<Real>,
}

/// The open cross-section of a tube of `radius`, or of the slab |u| ≤ `slab_half` of it, m².
pub fn open_cross_section(radius: Real, slab_half: Option<Real>) -> Real {
    match slab_half {
        None => PI * radius * radius,
        Some(h) => {
            let h = h.min(radius);
            // 2 ∫ √(R² − u²) du over [−h, h].
            2.0 * (h * (radius * radius - h * h).sqrt() + radius * radius * (h / radius).asin())
        }
    }
}

/// The initial fill in engine terms.
#[derive(Debug, Clone)]
pub enum InitialConfig {
    /// `count` grains placed at random in `region`, all moving at `velocity`.
    Placed {
        count: u64,
        region: Region,
        velocity: Vec3,
    },
    /// The grains of a file (`initial.file`), as given.
    Given(Vec<GivenGrain>),
}

/// A grain from an `initial.file`.
#[derive(Debug, Clone, Copy)]
pub struct GivenGrain {
    /// Centre, m.
    pub position: Vec3,
    /// Radius, m.
    pub radius: Real,
    /// Velocity, m/s.
    pub velocity: Vec3,
    /// Its line in the file (for messages).
    pub line: usize,
    /// Held in place for the whole run (a rough base: LAMMPS's `fix freeze`): it pushes
    /// on the grains it touches as a partner of infinite mass, and never moves.
    pub frozen: bool,
}

/// Time-step figures, reported with the run.
#[derive(Debug, Clone)]
pub struct TimeStepReport {
    /// Collision time of the smallest grain pair, s.
    pub contact_time: Real,
    /// Rayleigh time (Hertz only), s.
    pub rayleigh_time: Option<Real>,
    /// Largest accepted time step, s.
    pub limit: Real,
    /// What sets the limit.
    pub limit_reason: String,
    /// True when dt was derived rather than given.
    pub derived: bool,
}

/// Everything the native engine needs.
#[derive(Debug, Clone)]
pub struct DemConfig {
    /// Time step, s.
    pub dt: Real,
    /// How dt relates to the contact time and the limit.
    pub dt_report: TimeStepReport,
    /// Integrate rotations.
    pub rotation: bool,
    /// Verlet skin, m.
    pub skin: Real,
    /// Threads of the force loop.
    pub threads: usize,
    /// Gravity, m/s².
    pub gravity: Vec3,
    /// Walls (tube, caps, planes).
    pub walls: Vec<Wall>,
    /// Contact laws.
    pub laws: LawSet,
    /// Rolling resistance.
    pub rolling: RollingSet,
    /// Simulation box, m.
    pub box_lo: Vec3,
    pub box_hi: Vec3,
    /// Lab directions along which the box wraps around (a periodic tube's axis, a
    /// `[domain]`'s periodic faces).
    pub periodic: [bool; 3],
    /// The tube, if any.
    pub tube: Option<TubeGeometry>,
    /// The inlet, if any.
    pub inlet: Option<InletConfig>,
    /// The initial fill, if any.
    pub initial: Option<InitialConfig>,
    /// Grain radii range, m.
    pub radius_min: Real,
    pub radius_max: Real,
    /// Grain material density, kg/m³.
    pub density: Real,
    /// Random seed.
    pub seed: u64,
    /// Grains can leave (open ends or a box).
    pub removes_grains: bool,
    /// Largest impact speed expected (sets the Hertz contact time), m/s.
    pub max_impact_velocity: Real,
    /// Settle the initial grains under gravity, the DEM alone, for this long before the
    /// run's clock starts, s.
    pub settle: Option<Real>,
}
