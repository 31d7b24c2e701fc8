//! Scene → LIGGGHTS input. Everything is checked here, before LIGGGHTS sees a line: a
//! scene this mapping cannot express exactly is refused with the field and the reason.

use plugflow_model::dem::config::{InitialConfig, InletMode, LawSet, RollingSet, TangentialSet};
use plugflow_model::dem::contact::TorqueReading;
use plugflow_model::dem::external::{
    beta_form_restitution, linear_pairs, single_grain_mass, LinearPair,
};
use plugflow_model::dem::walls::WallShape;
use plugflow_model::dem::DemConfig;
use plugflow_model::scene::Scene;

/// A refused scene: field and reason.
#[derive(Debug)]
pub struct Refusal {
    pub field: String,
    pub reason: String,
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "field `{}`: {} (LIGGGHTS backend)",
            self.field, self.reason
        )
    }
}

fn refuse(field: &str, reason: impl Into<String>) -> Refusal {
    Refusal {
        field: field.into(),
        reason: reason.into(),
    }
}

/// Where grains leave: past `position` along coordinate `axis` in direction `sign`.
#[derive(Debug, Clone, Copy)]
pub struct Outlet {
    pub axis: usize,
    pub sign: f64,
    pub position: f64,
}

/// The LIGGGHTS input of a scene and what the engine needs to run it.
#[derive(Debug, Clone)]
pub struct Mapped {
    /// Input commands, in order.
    pub commands: Vec<String>,
    /// Walls: (plugflow name, LIGGGHTS fix id).
    pub walls: Vec<(String, String)>,
    /// Mass of one grain, kg.
    pub grain_mass: f64,
    /// Grain radius, m.
    pub grain_radius: f64,
    /// Grain density, kg/m³.
    pub grain_density: f64,
    /// Outlet of the tube, if open.
    pub outlet: Option<Outlet>,
    /// Grains leave through the open inlet end too.
    pub inlet_end_open: Option<Outlet>,
    /// The feed stops at this time, s (`inlet.until`: the insertion fix is removed then).
    pub feed_until: Option<f64>,
}

/// The id of the scene inlet's insertion fix.
pub const INSERT_FIX: &str = "pf_ins";

/// The group of the conveyor's grains held to the feed motion (`fix freeze`).
pub const HELD_GROUP: &str = "pf_held";

fn axis_index(axis: [f64; 3]) -> Option<(usize, f64)> {
    (0..3).find_map(|k| {
        let others = (0..3).filter(|&j| j != k).all(|j| axis[j].abs() < 1e-12);
        (others && (axis[k].abs() - 1.0).abs() < 1e-12).then_some((k, axis[k].signum()))
    })
}

const AXES: [&str; 3] = ["x", "y", "z"];

/// Quasi-2D slabs are the native engine's alone (LIGGGHTS's inlet inserts grains across the
/// whole tube, and its walls are not set up for them).
fn refuse_slab(cfg: &DemConfig) -> Result<(), Refusal> {
    if cfg.tube.is_some_and(|t| t.slab_half.is_some()) {
        return Err(refuse(
            "tube.slab",
            "quasi-2D slabs are not mapped to LIGGGHTS (its inlet inserts grains across the \
             whole tube); use dem.engine = \"native\"",
        ));
    }
    Ok(())
}

/// A user's own input feeds with its own insertion fixes: the conveyor (plugflow's column,
/// held by `fix freeze`) is mapped only with plugflow's input.
fn refuse_conveyor(cfg: &DemConfig) -> Result<(), Refusal> {
    if cfg.inlet.is_some_and(|i| i.mode == InletMode::Conveyor) {
        return Err(refuse(
            "inlet.mode",
            "the conveyor inlet is not mapped onto a user's own LIGGGHTS input (its \
             insertion fixes place grains free, not held to the feed motion); use \
             inlet.mode = \"slab\" or plugflow's own mapping of the scene",
        ));
    }
    Ok(())
}

/// Frozen grains (`initial.file`'s `frozen` column) are the built-in engine's alone.
fn refuse_frozen(cfg: &DemConfig) -> Result<(), Refusal> {
    if let Some(InitialConfig::Given(grains)) = &cfg.initial {
        if grains.iter().any(|g| g.frozen) {
            return Err(refuse(
                "initial.file",
                "frozen grains are not mapped to LIGGGHTS yet (its `fix freeze` group is not \
                 written); use dem.engine = \"native\"",
            ));
        }
    }
    Ok(())
}

/// Map a checked scene.
/// Hertz with either history law: LIGGGHTS's own `model hertz` (E, ν and the restitution
/// of its β form into `hertz`); the pairs carry only the friction.
fn hertz_history(
    scene: &Scene,
    hertz: &mut Option<(f64, f64, f64, f64)>,
    alpha: (f64, f64),
    mu: (f64, f64),
    dashpot_given: bool,
) -> Result<(LinearPair, LinearPair, bool), Refusal> {
    if dashpot_given {
        return Err(refuse(
            "contact.tangential_damping",
            "LIGGGHTS's `model hertz` damps the shear spring with its own γ_t; not mapped \
             with the scene's",
        ));
    }
    // LIGGGHTS's `model hertz` damps with γ = −2√(5/6) β √(S_n m*), S_n = 2Y*√(Rδ):
    // the built-in Tsuji form with the restitution of `beta_form_restitution`.
    // k_n = 4/3 Y*√(Rδ), k_t = 8G*√(Rδ) and the tangential damping follow from the
    // same E, ν and β in both engines.
    let e_of = |alpha: f64, field: &str| -> Result<f64, Refusal> {
        beta_form_restitution(alpha).ok_or_else(|| {
            refuse(
                field,
                "this restitution needs more damping than LIGGGHTS's Hertz model can \
                 express (|β| ≥ 1)",
            )
        })
    };
    let c = &scene.file.contact;
    *hertz = Some((
        c.youngs_modulus.map(|q| q.si).unwrap_or(0.0),
        c.poisson_ratio.map(|q| q.0).unwrap_or(0.0),
        e_of(alpha.0, "contact.restitution")?,
        e_of(alpha.1, "contact.wall_restitution")?,
    ));
    let unused = LinearPair {
        kn: 0.0,
        kt: 0.0,
        gamma_n: 0.0,
        gamma_t: 0.0,
        mu: mu.0,
    };
    Ok((unused, LinearPair { mu: mu.1, ..unused }, true))
}

pub fn map(scene: &Scene, cfg: &DemConfig) -> Result<Mapped, Refusal> {
    refuse_slab(cfg)?;
    refuse_frozen(cfg)?;
    let Some(m) = single_grain_mass(cfg) else {
        return Err(refuse(
            "particles.diameter_min",
            "grains of several sizes are not mapped (the damping per material pair is exact \
             for one size only); give `particles.diameter`",
        ));
    };
    let (r, rho) = (cfg.radius_min, cfg.density);
    // Hertz: (E, ν, e_L grain–grain, e_L grain–wall) for LIGGGHTS's own `model hertz`.
    let mut hertz: Option<(f64, f64, f64, f64)> = None;
    let (pp, pw, history) = match &cfg.laws {
        LawSet::Hooke(_) => {
            // The seeds' regularised Coulomb law min(μ F_n, γ_t |v_t|) is LIGGGHTS's
            // `tangential no_history`.
            let (pp, pw) = linear_pairs(cfg).expect("one grain size, Hooke");
            (pp, pw, cfg.laws.uses_history())
        }
        LawSet::Hertz(TangentialSet::History(l)) => hertz_history(
            scene,
            &mut hertz,
            (l.pp_normal.alpha, l.pw_normal.alpha),
            (l.pp_tangential.mu, l.pw_tangential.mu),
            l.pp_tangential.gamma_t.is_some(),
        )?,
        LawSet::Hertz(TangentialSet::LiggghtsHistory(l)) => hertz_history(
            scene,
            &mut hertz,
            (l.pp_normal.alpha, l.pw_normal.alpha),
            (l.pp_tangential.mu, l.pw_tangential.mu),
            l.pp_tangential.gamma_t.is_some(),
        )?,
        LawSet::Hertz(TangentialSet::CoulombViscous(_)) => {
            return Err(refuse(
                "contact.tangential",
                "`coulomb_viscous` with `hertz`: LIGGGHTS's `no_history` damps with the Hertz \
                 tangential γ_t, not the built-in engine's γ_n; use `history` (or `hooke`)",
            ))
        }
    };
    let mut c: Vec<String> = Vec::new();
    let mut push = |s: String| c.push(s);
    push("atom_style granular".into());
    push("atom_modify map array".into());
    // Periodic directions (a periodic tube's axis, a box's periodic faces) wrap in LIGGGHTS
    // as in the built-in engine: the box spans the period exactly.
    let edge = |k: usize| if cfg.periodic[k] { "p" } else { "f" };
    push(format!("boundary {} {} {}", edge(0), edge(1), edge(2)));
    push("newton off".into());
    push("communicate single vel yes".into());
    push("units si".into());
    let (lo, hi) = (cfg.box_lo, cfg.box_hi);
    push(format!(
        "region pf_box block {:e} {:e} {:e} {:e} {:e} {:e} units box",
        lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]
    ));
    push("create_box 2 pf_box".into());
    push(format!("neighbor {:e} bin", cfg.skin));
    push("neigh_modify delay 0".into());
    let matrix = |name: &str, pp: f64, pw: f64| {
        format!("fix pf_{name} all property/global {name} peratomtypepair 2 {pp:e} {pw:e} {pw:e} {pw:e}")
    };
    let tangential = if history { "history" } else { "no_history" };
    // Model keywords follow the model names in `pair_style` but the wall arguments in
    // `fix wall/gran`.
    let (model, keywords) = match hertz {
        Some((e_mod, nu, e_pp, e_pw)) => {
            push(format!(
                "fix pf_E all property/global youngsModulus peratomtype {e_mod:e} {e_mod:e}"
            ));
            push(format!(
                "fix pf_nu all property/global poissonsRatio peratomtype {nu:e} {nu:e}"
            ));
            push(matrix("coefficientRestitution", e_pp, e_pw));
            push(matrix("coefficientFriction", pp.mu, pw.mu));
            (
                format!("model hertz tangential {tangential}"),
                "tangential_damping on",
            )
        }
        None => {
            push(matrix("kn", pp.kn, pw.kn));
            push(matrix("kt", pp.kt, pw.kt));
            push(matrix("gamman_abs", pp.gamma_n, pw.gamma_n));
            push(matrix("gammat_abs", pp.gamma_t, pw.gamma_t));
            push(matrix("coefficientFriction", pp.mu, pw.mu));
            (
                format!("model hooke/stiffness tangential {tangential}"),
                "absolute_damping on tangential_damping on",
            )
        }
    };
    // Rolling resistance: LIGGGHTS's `cdt` is the built-in `constant_torque` term for term
    // (μ_r k_n δ R*, normalised by |ω_i − ω_j|, twist removed).
    let model = match &cfg.rolling {
        RollingSet::None => model,
        RollingSet::ConstantTorque(r) => {
            if r.pp.reading != TorqueReading::ElasticNoTwist {
                return Err(refuse(
                    "contact.rolling",
                    "`constant_resistance` (Lethe's reading: the whole normal force, twist \
                     resisted) is not LIGGGHTS's `cdt` (the elastic force, twist not \
                     resisted); use `constant_torque` or dem.engine = \"native\"",
                ));
            }
            push(matrix("coefficientRollingFriction", r.pp.mu_r, r.pw.mu_r));
            format!("{model} rolling_friction cdt")
        }
    };
    push(format!("pair_style gran {model} {keywords}"));
    push("pair_coeff * *".into());
    push(format!("timestep {:e}", cfg.dt));
    let g = cfg.gravity;
    let gn = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
    if gn > 0.0 {
        push(format!(
            "fix pf_gravity all gravity {gn:e} vector {:e} {:e} {:e}",
            g[0] / gn,
            g[1] / gn,
            g[2] / gn
        ));
    }
    let mut walls = Vec::new();
    let mut outlet = None;
    let mut inlet_end_open = None;
    for (k, w) in cfg.walls.iter().enumerate() {
        let id = format!("pf_wall{k}");
        let primitive = match &w.shape {
            WallShape::Cylinder {
                point,
                axis,
                radius,
            } => {
                let (a, _) = axis_index(*axis).ok_or_else(|| {
                    refuse("tube.axis", "LIGGGHTS's cylinder walls lie along x, y or z")
                })?;
                let others: Vec<f64> = (0..3).filter(|&j| j != a).map(|j| point[j]).collect();
                format!(
                    "{}cylinder {:e} {:e} {:e}",
                    AXES[a], radius, others[0], others[1]
                )
            }
            WallShape::Plane { point, normal } => {
                let (a, _) = axis_index(*normal).ok_or_else(|| {
                    refuse(
                        &format!("walls ({})", w.name),
                        "LIGGGHTS's plane walls are normal to x, y or z",
                    )
                })?;
                format!("{}plane {:e}", AXES[a], point[a])
            }
        };
        push(format!(
            "fix {id} all wall/gran {model} primitive type 2 {primitive} store_force yes {keywords}"
        ));
        walls.push((w.name.clone(), id));
    }
    if let Some(t) = cfg.tube {
        let (a, sign) = axis_index(t.axis)
            .ok_or_else(|| refuse("tube.axis", "must be along x, y or z for LIGGGHTS"))?;
        if t.outlet_open {
            outlet = Some(Outlet {
                axis: a,
                sign,
                position: t.origin[a] + sign * t.length,
            });
        }
        if t.inlet_open {
            inlet_end_open = Some(Outlet {
                axis: a,
                sign: -sign,
                position: t.origin[a],
            });
        }
        if let Some(inl) = cfg.inlet.as_ref().filter(|i| i.mode != InletMode::Conveyor) {
            let (lo_s, hi_s) = (t.origin[a], t.origin[a] + sign * inl.slab_length);
            let others: Vec<f64> = (0..3).filter(|&j| j != a).map(|j| t.origin[j]).collect();
            push(format!(
                "fix pf_pts all particletemplate/sphere 15485863 atom_type 1 density constant {rho:e} radius constant {r:e}"
            ));
            push("fix pf_pdd all particledistribution/discrete 32452843 1 pf_pts 1.0".into());
            push(format!(
                "region pf_inlet cylinder {} {:e} {:e} {:e} {:e} {:e} units box",
                AXES[a],
                others[0],
                others[1],
                // The tube's own radius: with `all_in yes` LIGGGHTS keeps the whole grain in
                // the region, so centres lie within R − r and r of the slab's ends, as the
                // built-in inlet places them. (A region of R − r with all_in left centres
                // only R − 2r: 56 % of the cross-section, and LIGGGHTS fed 348 grains of 514
                // in the horizontal case's first second.)
                t.radius,
                lo_s.min(hi_s),
                lo_s.max(hi_s)
            ));
            // A batch every 5 ms: a few grains per batch at the seeds' feed rates; 300
            // placement attempts per grain, as the built-in inlet makes (LIGGGHTS's default
            // of 50 drops grains once the slab holds a resting bed).
            let every = ((5e-3 / cfg.dt).round() as u64).max(1);
            let v = [
                t.axis[0] * inl.velocity,
                t.axis[1] * inl.velocity,
                t.axis[2] * inl.velocity,
            ];
            push(format!(
                "fix {INSERT_FIX} all insert/rate/region seed 49979687 distributiontemplate pf_pdd nparticles INF massrate {:e} insert_every {every} overlapcheck yes all_in yes maxattempt 300 vel constant {:e} {:e} {:e} region pf_inlet ntry_mc 10000",
                inl.rate * m,
                v[0],
                v[1],
                v[2]
            ));
        }
    } else if cfg.inlet.is_some() {
        return Err(refuse(
            "inlet",
            "an inlet needs a [tube] in the LIGGGHTS backend",
        ));
    }
    push("fix pf_integrate all nve/sphere".into());
    push_fluid_force(&mut c);
    if cfg.inlet.is_some_and(|i| i.mode == InletMode::Conveyor) {
        // The conveyor's column: plugflow creates its grains (create_atoms) and keeps the
        // ones in the slab in this group, whose force and torque `fix freeze` zeroes after
        // gravity, the walls and the fluid force (it is the last fix): they move at the feed
        // velocity they were given with no spin, as the built-in engine's 1/m = 0. The
        // group starts empty (no grain has the walls' type 2); the engine moves grains in
        // and out by the group's mask bit.
        c.push(format!("group {HELD_GROUP} type 2"));
        c.push(format!("fix pf_hold {HELD_GROUP} freeze"));
    }
    c.push("thermo 100000000".into());
    Ok(Mapped {
        commands: c,
        walls,
        grain_mass: m,
        grain_radius: r,
        grain_density: rho,
        outlet,
        inlet_end_open,
        feed_until: cfg.inlet.and_then(|i| i.until),
    })
}

/// Commands of a user's input that plugflow drops: it drives the runs itself, and its
/// own fixes replace CFDEMcoupling's.
fn dropped(words: &[&str]) -> bool {
    matches!(words.first(), Some(&"run") | Some(&"write_restart"))
        || (words.first() == Some(&"fix")
            && words.get(3).is_some_and(|s| s.starts_with("couple/cfd")))
}

/// Commands plugflow cannot follow in a user's input.
const REFUSED: [&str; 8] = [
    "include", "shell", "quit", "clear", "jump", "label", "next", "if",
];

/// A user's own LIGGGHTS input (CFDEMcoupling style) with plugflow's coupling fixes.
pub fn map_user(cfg: &DemConfig, path: &str) -> Result<Mapped, Refusal> {
    refuse_slab(cfg)?;
    refuse_conveyor(cfg)?;
    refuse_frozen(cfg)?;
    let field = "dem.liggghts_input";
    let text = std::fs::read_to_string(path)
        .map_err(|e| refuse(field, format!("cannot read `{path}`: {e}")))?;
    let mut lines: Vec<(usize, String)> = Vec::new();
    let mut pending = String::new();
    for (k, raw) in text.lines().enumerate() {
        let code = raw.split('#').next().unwrap_or("").trim_end();
        if let Some(head) = code.strip_suffix('&') {
            pending.push_str(head);
            pending.push(' ');
            continue;
        }
        pending.push_str(code);
        let line = std::mem::take(&mut pending).trim().to_string();
        if !line.is_empty() {
            lines.push((k + 1, line));
        }
    }
    let mut c = Vec::new();
    let (mut style, mut integrator, mut timestep) = (false, false, None);
    for (n, line) in &lines {
        let w: Vec<&str> = line.split_whitespace().collect();
        if REFUSED.contains(&w[0]) {
            return Err(refuse(
                field,
                format!(
                    "line {n}: `{}` is not supported in a coupled input (plugflow feeds the \
                     commands one by one); inline or remove it",
                    w[0]
                ),
            ));
        }
        if line.contains("${") || w.iter().any(|x| x.starts_with("$")) {
            return Err(refuse(
                field,
                format!("line {n}: variable substitution (`$`) is not supported; write the values"),
            ));
        }
        if w[0] == "atom_style" {
            style = matches!(w.get(1), Some(&"granular") | Some(&"sphere"));
            if !style {
                return Err(refuse(
                    field,
                    format!(
                        "line {n}: atom_style must be `granular` (spheres with radius and mass)"
                    ),
                ));
            }
        }
        if w[0] == "fix" && w.get(3).is_some_and(|s| s.starts_with("nve/sphere")) {
            integrator = true;
        }
        if w[0] == "timestep" {
            timestep = w.get(1).and_then(|t| t.parse::<f64>().ok());
        }
        if w[0] == "fix" && w.get(1) == Some(&"pf_extf") {
            return Err(refuse(
                field,
                format!("line {n}: fix ids `pf_*` are plugflow's own"),
            ));
        }
        if !dropped(&w) {
            c.push(line.clone());
        }
    }
    if !style {
        return Err(refuse(
            field,
            "no `atom_style granular`: plugflow couples spheres",
        ));
    }
    if !integrator {
        return Err(refuse(
            field,
            "no `fix … nve/sphere`: the grains must be integrated by LIGGGHTS",
        ));
    }
    let dt = timestep.ok_or_else(|| refuse(field, "no `timestep`"))?;
    if (dt - cfg.dt).abs() > 1e-9 * cfg.dt {
        return Err(refuse(
            "dem.dt",
            format!(
                "{:e} s differs from the input's `timestep {dt:e}`: the coupling counts steps of \
                 the scene's dt; set `[dem] dt = \"{dt:e} s\"`",
                cfg.dt
            ),
        ));
    }
    push_fluid_force(&mut c);
    let r = cfg.radius_min;
    let rho = cfg.density;
    let outlet = cfg.tube.filter(|t| t.outlet_open).and_then(|t| {
        axis_index(t.axis).map(|(a, sign)| Outlet {
            axis: a,
            sign,
            position: t.origin[a] + sign * t.length,
        })
    });
    Ok(Mapped {
        commands: c,
        walls: Vec::new(),
        grain_mass: rho * 4.0 / 3.0 * std::f64::consts::PI * r * r * r,
        grain_radius: r,
        grain_density: rho,
        outlet,
        inlet_end_open: None,
        feed_until: None,
    })
}

/// The fluid force: one per-atom vector LIGGGHTS integrates through fix addforce; grains
/// leaving the box within a run must not stop LIGGGHTS.
fn push_fluid_force(c: &mut Vec<String>) {
    c.push("fix pf_extf all property/atom extf vector yes no no 0. 0. 0.".into());
    for (k, x) in AXES.iter().enumerate() {
        c.push(format!("variable pf_f{x} atom f_pf_extf[{}]", k + 1));
    }
    c.push("fix pf_fluid all addforce v_pf_fx v_pf_fy v_pf_fz".into());
    c.push("thermo_modify lost ignore norm no".into());
}
