//! The range checks a scene's types alone cannot express, one function per section; each
//! refusal names the field and the reason.

use super::*;
use crate::Real;
use plugflow_coupling::drag::{drag_law, drag_law_names};
use plugflow_coupling::fluid_force::{fluid_force, fluid_force_names};

/// Range checks that the types alone cannot express.
/// Most grains a scene may ask for at the start.
pub const MAX_GRAINS: u64 = 20_000_000;
/// Most gas nodes.
pub const MAX_GAS_NODES: usize = 4_000_000;
/// Most slices the sampling may cut the tube into.
pub const MAX_SLICES: usize = 1_000_000;
/// Widest tube, in grain diameters.
const MAX_GRAINS_ACROSS: Real = 1e4;
/// Longest tube, in grain diameters.
const MAX_GRAINS_ALONG: Real = 1e7;

pub(super) fn check(f: &SceneFile) -> Result<(), SceneError> {
    if f.schema_version != SCHEMA_VERSION {
        return Err(field_err(
            "schema_version",
            format!(
                "version {} is not supported (this build reads version {SCHEMA_VERSION})",
                f.schema_version
            ),
        ));
    }
    if f.name.trim().is_empty()
        || f.name.contains(['/', '\\'])
        || f.name.chars().any(char::is_control)
        || f.name.trim_matches('.').is_empty()
    {
        return Err(field_err(
            "name",
            "must be a non-empty name without path separators or control characters, and \
             not `.` or `..` (outputs go into a folder of that name)",
        ));
    }
    if f.duration.si <= 0.0 {
        return Err(field_err("duration", "must be positive"));
    }
    let dmax = check_particles(f)?;
    check_contact(f)?;
    check_rolling(f)?;
    check_dem(f)?;
    check_geometry(f, dmax)?;
    check_feed(f, dmax)?;
    // (The sampling interval before the gas: the order of the refusals is the scene's
    // order of sections, as it always was.)
    if f.output.sample_interval.si <= 0.0 {
        return Err(field_err("output.sample_interval", "must be positive"));
    }
    if let Some(c) = f.output.checkpoint_interval {
        if c.si < f.output.sample_interval.si {
            return Err(field_err(
                "output.checkpoint_interval",
                format!(
                    "{} s is shorter than `output.sample_interval` ({} s): checkpoints are \
                     taken at samples",
                    c.si, f.output.sample_interval.si
                ),
            ));
        }
        // The built-in engine saves its own state; LIGGGHTS through its restart files
        // (the scene's mapping only: a user's own input builds its box its own way).
        if f.dem.engine == "liggghts" && f.dem.liggghts_input.is_some() {
            return Err(field_err(
                "output.checkpoint_interval",
                "checkpoints of a user's own LIGGGHTS input (`dem.liggghts_input`) are not \
                 supported (plugflow cannot put a restart file in place of the input's own \
                 box and grains); use `write_restart` in the input, or drop the field",
            ));
        }
        if !matches!(f.dem.engine.as_str(), "native" | "liggghts") {
            return Err(field_err(
                "output.checkpoint_interval",
                format!(
                    "the `{}` engine cannot write checkpoints (the built-in `native` engine \
                     and `liggghts` can); drop the field or run on one of those",
                    f.dem.engine
                ),
            ));
        }
    }
    check_gas(f)?;
    check_output(f)
}

/// `[particles]`; returns the largest diameter, m.
fn check_particles(f: &SceneFile) -> Result<Real, SceneError> {
    let p = &f.particles;
    let (dmin, dmax) = match (p.diameter, p.diameter_min, p.diameter_max) {
        (Some(d), None, None) => {
            if d.si <= 0.0 {
                return Err(field_err("particles.diameter", "must be positive"));
            }
            (d.si, d.si)
        }
        (None, Some(a), Some(b)) => {
            if a.si <= 0.0 {
                return Err(field_err("particles.diameter_min", "must be positive"));
            }
            if b.si < a.si {
                return Err(field_err(
                    "particles.diameter_max",
                    "must not be smaller than diameter_min",
                ));
            }
            (a.si, b.si)
        }
        (Some(_), _, _) => {
            return Err(field_err(
                "particles.diameter",
                "give either `diameter` or `diameter_min` + `diameter_max`, not both",
            ))
        }
        _ => {
            return Err(field_err(
                "particles.diameter",
                "missing: give `diameter` (monodisperse) or `diameter_min` + `diameter_max`",
            ))
        }
    };
    let _ = dmin;
    if p.density.si <= 0.0 {
        return Err(field_err("particles.density", "must be positive"));
    }
    Ok(dmax)
}

/// `[contact]`.
fn check_contact(f: &SceneFile) -> Result<(), SceneError> {
    let c = &f.contact;
    if c.friction.0 < 0.0 {
        return Err(field_err("contact.friction", "must be ≥ 0"));
    }
    if !(c.restitution.0 > 0.0 && c.restitution.0 <= 1.0) {
        return Err(field_err("contact.restitution", "must lie in (0, 1]"));
    }
    if let Some(m) = c.wall_friction {
        if m.0 < 0.0 {
            return Err(field_err("contact.wall_friction", "must be ≥ 0"));
        }
    }
    if let Some(e) = c.wall_restitution {
        if !(e.0 > 0.0 && e.0 <= 1.0) {
            return Err(field_err("contact.wall_restitution", "must lie in (0, 1]"));
        }
    }
    match c.normal {
        NormalLawName::Hooke => {
            match (c.stiffness, c.contact_time) {
                (Some(k), None) if k.si <= 0.0 => {
                    return Err(field_err("contact.stiffness", "must be positive"))
                }
                (None, Some(t)) if t.si <= 0.0 => {
                    return Err(field_err("contact.contact_time", "must be positive"))
                }
                (Some(_), Some(_)) => {
                    return Err(field_err(
                        "contact.stiffness",
                        "give `stiffness` or `contact_time`, not both",
                    ))
                }
                (None, None) => {
                    return Err(field_err(
                        "contact.stiffness",
                        "missing: the hooke law needs `stiffness` or `contact_time`",
                    ))
                }
                _ => {}
            }
            if c.youngs_modulus.is_some() || c.poisson_ratio.is_some() {
                return Err(field_err(
                    "contact.youngs_modulus",
                    "belongs to the hertz law; the hooke law takes `stiffness` or `contact_time`",
                ));
            }
            if let Some(r) = c.tangential_stiffness_ratio {
                if r.0 <= 0.0 {
                    return Err(field_err(
                        "contact.tangential_stiffness_ratio",
                        "must be positive",
                    ));
                }
            }
        }
        NormalLawName::Hertz => {
            let e = c.youngs_modulus.ok_or_else(|| {
                field_err("contact.youngs_modulus", "missing: the hertz law needs it")
            })?;
            if e.si <= 0.0 {
                return Err(field_err("contact.youngs_modulus", "must be positive"));
            }
            let nu = c.poisson_ratio.ok_or_else(|| {
                field_err("contact.poisson_ratio", "missing: the hertz law needs it")
            })?;
            if !(0.0..0.5).contains(&nu.0) {
                return Err(field_err("contact.poisson_ratio", "must lie in [0, 0.5)"));
            }
            if c.stiffness.is_some() || c.contact_time.is_some() {
                return Err(field_err(
                    "contact.stiffness",
                    "belongs to the hooke law; the hertz law derives stiffness from E and ν",
                ));
            }
            if c.tangential_stiffness_ratio.is_some() {
                return Err(field_err(
                    "contact.tangential_stiffness_ratio",
                    "belongs to the hooke law; hertz uses the Mindlin stiffness",
                ));
            }
        }
    }
    if let Some(g) = c.tangential_damping {
        if g.si < 0.0 {
            return Err(field_err("contact.tangential_damping", "must be ≥ 0"));
        }
    }
    Ok(())
}

/// `contact.rolling` and its coefficients: given exactly when the law takes them, and a
/// rolling law only where grains rotate.
fn check_rolling(f: &SceneFile) -> Result<(), SceneError> {
    let c = &f.contact;
    match c.rolling {
        RollingLawName::None => {
            for (given, name) in [
                (c.rolling_friction.is_some(), "contact.rolling_friction"),
                (
                    c.wall_rolling_friction.is_some(),
                    "contact.wall_rolling_friction",
                ),
            ] {
                if given {
                    return Err(field_err(
                        name,
                        "given without a rolling law: set `contact.rolling = \"constant_torque\"` \
                         or remove it",
                    ));
                }
            }
        }
        RollingLawName::ConstantTorque | RollingLawName::ConstantResistance => {
            let mu = c.rolling_friction.ok_or_else(|| {
                field_err(
                    "contact.rolling_friction",
                    format!("missing: the {} law needs μ_r", c.rolling.scene_name()),
                )
            })?;
            for (m, name) in [
                (Some(mu), "contact.rolling_friction"),
                (c.wall_rolling_friction, "contact.wall_rolling_friction"),
            ] {
                if let Some(m) = m {
                    if m.0 < 0.0 {
                        return Err(field_err(name, "must be ≥ 0"));
                    }
                }
            }
            if !f.dem.rotation {
                return Err(field_err(
                    "contact.rolling",
                    "a rolling law acts on rotations; `dem.rotation = false` has none",
                ));
            }
        }
    }
    Ok(())
}

/// `tube.periodic` and `domain.periodic`: a periodic section has no ends and no inlet; its
/// gas is the d'Arcy gas (monolithic solve, no pressure taps) under a flow controller.
fn check_periodic(f: &SceneFile) -> Result<(), SceneError> {
    let periodic = match (&f.tube, &f.domain) {
        (Some(t), _) => {
            if t.periodic {
                for (given, name) in [
                    (t.inlet_end.is_some(), "tube.inlet_end"),
                    (t.outlet_end.is_some(), "tube.outlet_end"),
                ] {
                    if given {
                        return Err(field_err(
                            name,
                            "a periodic tube has no ends (grains leaving one come back at the \
                             other); remove it",
                        ));
                    }
                }
            }
            t.periodic
        }
        (None, Some(d)) => d.periodic.iter().any(|&p| p),
        (None, None) => false,
    };
    if !periodic {
        return Ok(());
    }
    if f.inlet.is_some() {
        return Err(field_err(
            "inlet",
            "a periodic section has no inlet: it starts from its `[initial]` grains",
        ));
    }
    if let Some(g) = &f.gas {
        if g.equation_of_state.as_deref() == Some("ideal_gas") {
            return Err(field_err(
                "gas.equation_of_state",
                "a periodic section has no outlet to fix the absolute pressure an ideal gas's \
                 density follows: use `constant` (the section's gas is incompressible)",
            ));
        }
        if g.solver == GasSolverPath::Splitting {
            return Err(field_err(
                "gas.solver",
                "`splitting` solves along open lines; a periodic section's axial lines close \
                 on themselves: use `monolithic`",
            ));
        }
        if !f.output.pressure_taps.is_empty() {
            return Err(field_err(
                "output.pressure_taps",
                "a periodic section has no inlet and outlet pressures to tap; its driving \
                 gradient is the run's pressure drop",
            ));
        }
    }
    Ok(())
}

/// `[dem]`.
fn check_dem(f: &SceneFile) -> Result<(), SceneError> {
    let d = &f.dem;
    if !ENGINES.contains(&d.engine.as_str()) {
        return Err(field_err(
            "dem.engine",
            format!(
                "unknown engine `{}` (known: {})",
                d.engine,
                ENGINES.join(", ")
            ),
        ));
    }
    if d.liggghts_input.is_some() && d.engine != "liggghts" {
        return Err(field_err(
            "dem.liggghts_input",
            format!(
                "a LIGGGHTS input needs `dem.engine = \"liggghts\"` (the scene has `{}`)",
                d.engine
            ),
        ));
    }
    if d.liggghts_input.is_some() && f.inlet.is_some() {
        return Err(field_err(
            "inlet",
            "the LIGGGHTS input inserts the grains itself: drop [inlet] (plugflow would feed \
             a second stream)",
        ));
    }
    if d.isolate && d.engine == "native" {
        return Err(field_err(
            "dem.isolate",
            "the built-in engine runs in plugflow's process; isolation is for ABI engines \
             (`native_abi`, `liggghts`)",
        ));
    }
    if d.library.is_some() && d.engine == "native" {
        return Err(field_err(
            "dem.library",
            "the built-in engine (`native`) loads no library; set `dem.engine` too",
        ));
    }
    if let Some(dt) = d.dt {
        if dt.si <= 0.0 {
            return Err(field_err("dem.dt", "must be positive"));
        }
    }
    if d.dt_fraction.0 < 10.0 {
        return Err(field_err(
            "dem.dt_fraction",
            "must be ≥ 10 (the stability limit is a tenth of the contact time)",
        ));
    }
    if let Some(s) = d.skin {
        if s.si <= 0.0 {
            return Err(field_err("dem.skin", "must be positive"));
        }
    }
    if d.threads == 0 || d.threads > 256 {
        return Err(field_err("dem.threads", "must lie in 1..=256"));
    }
    if d.max_impact_velocity.si <= 0.0 {
        return Err(field_err("dem.max_impact_velocity", "must be positive"));
    }
    Ok(())
}

/// `[tube]` or `[domain]`, and `[[walls]]`.
fn check_geometry(f: &SceneFile, dmax: Real) -> Result<(), SceneError> {
    match (&f.tube, &f.domain) {
        (None, None) => {
            return Err(field_err(
                "tube",
                "missing: a scene needs a [tube] or, without one, a [domain] box",
            ))
        }
        (Some(_), Some(_)) => {
            return Err(field_err(
                "domain",
                "a scene with a [tube] takes its box from the tube; remove [domain]",
            ))
        }
        _ => {}
    }
    check_periodic(f)?;
    if let Some(t) = &f.tube {
        if t.length.si <= 0.0 {
            return Err(field_err("tube.length", "must be positive"));
        }
        if t.diameter.si <= 0.0 {
            return Err(field_err("tube.diameter", "must be positive"));
        }
        if t.diameter.si <= dmax {
            return Err(field_err(
                "tube.diameter",
                format!(
                    "{} m is not wider than the largest grain ({} m)",
                    t.diameter.si, dmax
                ),
            ));
        }
        let n = norm(&t.axis.map(|a| a.0));
        if n == 0.0 {
            return Err(field_err("tube.axis", "must not be the zero vector"));
        }
        if !n.is_finite() {
            return Err(field_err(
                "tube.axis",
                "is too long to normalise (its length overflows); give a direction such as \
                 [0, 0, 1]",
            ));
        }
        // Beyond these a run cannot hold the grains or the cells it implies (every figure is
        // far past any conveying line: 1e4 grains across, 1e7 grains along).
        if t.diameter.si > MAX_GRAINS_ACROSS * dmax {
            return Err(field_err(
                "tube.diameter",
                format!(
                    "{:e} m is over {MAX_GRAINS_ACROSS:e} grain diameters: beyond what a DEM run \
                     can hold",
                    t.diameter.si
                ),
            ));
        }
        if t.length.si > MAX_GRAINS_ALONG * dmax {
            return Err(field_err(
                "tube.length",
                format!(
                    "{:e} m is over {MAX_GRAINS_ALONG:e} grain diameters: beyond what a DEM run \
                     can hold",
                    t.length.si
                ),
            ));
        }
        match (t.slab_friction, t.slab) {
            (Some(_), None) => {
                return Err(field_err(
                    "tube.slab_friction",
                    "applies to the quasi-2D slab's planes; give tube.slab or remove it",
                ))
            }
            (Some(m), Some(_)) if m.0 < 0.0 => {
                return Err(field_err("tube.slab_friction", "must be ≥ 0"))
            }
            _ => {}
        }
    }
    if let Some(b) = &f.domain {
        for k in 0..3 {
            if b.max[k].si - b.min[k].si <= dmax {
                return Err(field_err(
                    format!("domain.max[{k}]"),
                    "the box must be wider than the largest grain in every direction",
                ));
            }
        }
    }
    for (k, w) in f.walls.iter().enumerate() {
        if norm(&w.normal.map(|a| a.0)) == 0.0 {
            return Err(field_err(
                format!("walls[{k}].normal"),
                "must not be the zero vector",
            ));
        }
        if w.name.trim().is_empty() {
            return Err(field_err(format!("walls[{k}].name"), "must not be empty"));
        }
    }
    Ok(())
}

/// `[inlet]` and `[initial]`.
fn check_feed(f: &SceneFile, dmax: Real) -> Result<(), SceneError> {
    if let Some(i) = &f.inlet {
        if f.tube.is_none() {
            return Err(field_err("inlet", "an inlet needs a [tube] to feed"));
        }
        match (i.mass_flow, i.rate) {
            (Some(m), None) if m.si <= 0.0 => {
                return Err(field_err("inlet.mass_flow", "must be positive"))
            }
            (None, Some(r)) if r.si <= 0.0 => {
                return Err(field_err("inlet.rate", "must be positive"))
            }
            (Some(_), Some(_)) => {
                return Err(field_err(
                    "inlet.rate",
                    "give `mass_flow` or `rate`, not both",
                ))
            }
            (None, None) => {
                return Err(field_err(
                    "inlet.mass_flow",
                    "missing: give `mass_flow` (e.g. \"2.49 kg/h\") or `rate` (grains/s)",
                ))
            }
            _ => {}
        }
        if !(i.porosity.0 > 0.0 && i.porosity.0 < 1.0) {
            return Err(field_err("inlet.porosity", "must lie in (0, 1)"));
        }
        if i.velocity.si < 0.0 {
            return Err(field_err(
                "inlet.velocity",
                "must be ≥ 0 (it points along the tube axis, into the tube)",
            ));
        }
        if let Some(s) = i.slab_length {
            if s.si < dmax {
                return Err(field_err(
                    "inlet.slab_length",
                    "must be at least one grain diameter",
                ));
            }
        }
    }
    if let Some(ini) = &f.initial {
        check_initial(f, ini)?;
    }
    if let Some(t) = f.dem.settle {
        if t.si <= 0.0 {
            return Err(field_err("dem.settle", "must be positive"));
        }
        if f.initial.is_none() {
            return Err(field_err(
                "dem.settle",
                "settles the `[initial]` grains, and this scene has none",
            ));
        }
    }
    Ok(())
}

/// `[initial]`: a file, or placed grains in a plug stretch and/or a resting layer.
fn check_initial(f: &SceneFile, ini: &InitialSpec) -> Result<(), SceneError> {
    if ini.file.is_some() {
        for (given, name) in [
            (ini.count.is_some(), "initial.count"),
            (ini.from.is_some(), "initial.from"),
            (ini.to.is_some(), "initial.to"),
            (ini.layer_height.is_some(), "initial.layer_height"),
            (ini.end_angle.is_some(), "initial.end_angle"),
            (ini.velocity.is_some(), "initial.velocity"),
        ] {
            if given {
                return Err(field_err(
                    name,
                    "the grains come from `initial.file` (velocities in its vx, vy, vz \
                     columns); remove it",
                ));
            }
        }
        return Ok(());
    }
    let count = ini.count.ok_or_else(|| {
        field_err(
            "initial.count",
            "missing: give the number of grains to place (or `initial.file`)",
        )
    })?;
    if count > MAX_GRAINS {
        return Err(field_err(
            "initial.count",
            format!(
                "{count} grains is over the limit of {MAX_GRAINS} (≈ 1 kB of memory each, and \
                 the steps to move them)"
            ),
        ));
    }
    match (ini.from, ini.to) {
        (Some(from), Some(to)) => {
            if to.si <= from.si {
                return Err(field_err(
                    "initial.to",
                    "must be greater than `initial.from`",
                ));
            }
        }
        (None, None) if ini.layer_height.is_some() => {}
        (None, None) => {
            return Err(field_err(
                "initial.from",
                "missing: give the stretch `from`/`to`, a `layer_height`, or both",
            ))
        }
        (Some(_), None) => return Err(field_err("initial.to", "missing: `from` needs `to`")),
        (None, Some(_)) => return Err(field_err("initial.from", "missing: `to` needs `from`")),
    }
    if let Some(a) = ini.end_angle {
        if ini.from.is_none() {
            return Err(field_err(
                "initial.end_angle",
                "inclines the ends of the `from`/`to` stretch, which is not given",
            ));
        }
        if !(a.0 > 0.0 && a.0 <= 90.0) {
            return Err(field_err(
                "initial.end_angle",
                "must lie in (0, 90] degrees (90: square ends)",
            ));
        }
    }
    if ini.layer_height.is_some() || ini.end_angle.is_some() {
        let name = if ini.layer_height.is_some() {
            "initial.layer_height"
        } else {
            "initial.end_angle"
        };
        let Some(t) = &f.tube else {
            return Err(field_err(
                name,
                "shapes a fill of the tube; this scene has none",
            ));
        };
        // "Up" is against gravity across the tube: gravity must have a part across it.
        let a = crate::dem::vec3::normalized(t.axis.map(|c| c.0));
        let g = f.gravity.map(|q| q.si);
        let along = g[0] * a[0] + g[1] * a[1] + g[2] * a[2];
        let across = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2] - along * along)
            .max(0.0)
            .sqrt();
        if across <= 1e-9 * (g[0].abs() + g[1].abs() + g[2].abs()) {
            return Err(field_err(
                name,
                "measures height against gravity across the tube; here gravity has no part \
                 across it",
            ));
        }
        if let Some(h) = ini.layer_height {
            if !(h.si > 0.0 && h.si <= t.diameter.si) {
                return Err(field_err(
                    "initial.layer_height",
                    format!("must lie in (0, {}] m (the tube's diameter)", t.diameter.si),
                ));
            }
        }
    }
    Ok(())
}

/// `[output]`.
fn check_output(f: &SceneFile) -> Result<(), SceneError> {
    if let Some(p) = &f.output.profiles {
        let ranges = [
            (
                "output.profiles.plug_length",
                p.plug_length.map(|r| (r[0].si, r[1].si)),
            ),
            (
                "output.profiles.plug_velocity",
                p.plug_velocity.map(|r| (r[0].si, r[1].si)),
            ),
            ("output.profiles.centre", p.centre.map(|r| (r[0].0, r[1].0))),
        ];
        for (field, range) in ranges {
            if let Some((lo, hi)) = range {
                if lo > hi {
                    return Err(field_err(field, format!("[{lo}, {hi}] is empty (lo > hi)")));
                }
            }
        }
        if let Some(c) = p.centre {
            if c[0].0 < 0.0 || c[1].0 > 1.0 {
                return Err(field_err(
                    "output.profiles.centre",
                    "fractions of the tube length lie in [0, 1]",
                ));
            }
        }
    }
    if let Some(sn) = &f.output.snapshots {
        if sn.interval.si <= 0.0 {
            return Err(field_err("output.snapshots.interval", "must be positive"));
        }
        if sn.formats.is_empty() {
            return Err(field_err(
                "output.snapshots.formats",
                "names no format (use [\"hdf5\"], [\"vtk\"] or both), or drop the table",
            ));
        }
    }
    for (k, id) in f.output.reproduces.iter().enumerate() {
        if crate::targets::find(id).is_none() {
            let known: Vec<&str> = crate::targets::TARGETS.iter().map(|t| t.id).collect();
            return Err(field_err(
                format!("output.reproduces[{k}]"),
                format!("unknown target `{id}` (known: {})", known.join(", ")),
            ));
        }
    }
    for (k, t) in f.output.pressure_taps.iter().enumerate() {
        let field = format!("output.pressure_taps[{k}]");
        if f.gas.is_none() {
            return Err(field_err(field, "a pressure transducer needs a [gas]"));
        }
        let length = f.tube.as_ref().map_or(0.0, |t| t.length.si);
        if !(0.0 <= t.from.si && t.from.si < t.to.si && t.to.si <= length) {
            return Err(field_err(
                field,
                format!(
                    "`{}`: the taps need 0 ≤ from < to ≤ the tube's length {length} m (got {} \
                     and {} m)",
                    t.name, t.from.si, t.to.si
                ),
            ));
        }
        if t.name.is_empty() || f.output.pressure_taps[..k].iter().any(|o| o.name == t.name) {
            return Err(field_err(
                field,
                format!("the name `{}` is empty or used twice", t.name),
            ));
        }
    }
    if let Some(s) = f.output.slice_length {
        if s.si <= 0.0 {
            return Err(field_err("output.slice_length", "must be positive"));
        }
        if let Some(t) = &f.tube {
            let slices = t.length.si / s.si;
            if slices > MAX_SLICES as Real {
                return Err(field_err(
                    "output.slice_length",
                    format!(
                        "cuts the tube into {slices:.3e} slices, over the limit of {MAX_SLICES} \
                         (each sample keeps a value per slice)"
                    ),
                ));
            }
        }
    }
    if let Some(s) = f.output.settling_time {
        if s.si < 0.0 || s.si >= f.duration.si {
            return Err(field_err(
                "output.settling_time",
                "must lie in [0, duration): means are taken after it",
            ));
        }
    }
    Ok(())
}

fn check_gas(f: &SceneFile) -> Result<(), SceneError> {
    let Some(g) = &f.gas else {
        if f.coupling.is_some() {
            return Err(field_err("coupling", "coupling needs a [gas] section"));
        }
        return Ok(());
    };
    if f.tube.is_none() {
        return Err(field_err(
            "gas",
            "the gas is solved in a [tube]; the scene has none",
        ));
    }
    let simple = match g.model.as_str() {
        "darcy" => false,
        "simple" => true,
        other => {
            return Err(field_err(
                "gas.model",
                format!("unknown gas model `{other}` (this build has: darcy, simple)"),
            ))
        }
    };
    match (simple, g.density) {
        (true, None) => {
            return Err(field_err(
                "gas.density",
                "missing: the simple gas carries the gas's inertia (e.g. \"1.2 kg/m^3\")",
            ))
        }
        (true, Some(d)) if d.si <= 0.0 => return Err(field_err("gas.density", "must be positive")),
        (false, Some(_)) => {
            return Err(field_err(
                "gas.density",
                "the darcy gas has no inertia and takes no density (model = \"simple\" does)",
            ))
        }
        _ => {}
    }
    match (simple, g.equation_of_state.as_deref()) {
        (true, None | Some("constant" | "ideal_gas")) | (false, None) => {}
        (true, Some(other)) => {
            return Err(field_err(
                "gas.equation_of_state",
                format!("unknown `{other}` (this build has: constant, ideal_gas)"),
            ))
        }
        (false, Some(_)) => {
            return Err(field_err(
                "gas.equation_of_state",
                "the darcy gas is an ideal gas by construction (McNamara–Flekkøy) and takes no \
                 choice (model = \"simple\" does)",
            ))
        }
    }
    if let Some(c) = g.controlled_velocity.as_deref() {
        let periodic = f.tube.as_ref().is_some_and(|t| t.periodic)
            || f.domain
                .as_ref()
                .is_some_and(|d| d.periodic.iter().any(|&p| p));
        if !matches!(c, "superficial" | "interstitial") {
            return Err(field_err(
                "gas.controlled_velocity",
                format!("unknown `{c}` (superficial, interstitial)"),
            ));
        }
        if !(simple && periodic) {
            return Err(field_err(
                "gas.controlled_velocity",
                "only a periodic section's flow controller with the `simple` gas holds a chosen \
                 velocity (an open tube's inlet fixes the superficial velocity)",
            ));
        }
    }
    if g.viscosity.si <= 0.0 {
        return Err(field_err("gas.viscosity", "must be positive"));
    }
    if g.pressure.si <= 0.0 {
        return Err(field_err(
            "gas.pressure",
            "must be positive (absolute pressure P0)",
        ));
    }
    match (g.superficial_velocity, g.flow) {
        (Some(v), None) if v.si < 0.0 => {
            return Err(field_err("gas.superficial_velocity", "must be ≥ 0"))
        }
        (None, Some(q)) if q.si < 0.0 => return Err(field_err("gas.flow", "must be ≥ 0")),
        (Some(_), Some(_)) => {
            return Err(field_err(
                "gas.flow",
                "give `superficial_velocity` or `flow`, not both",
            ))
        }
        (None, None) => return Err(field_err(
            "gas.superficial_velocity",
            "missing: give `superficial_velocity` (e.g. \"1 m/s\") or `flow` (e.g. \"2.3 l/min\")",
        )),
        _ => {}
    }
    let [nz, nx, ny] = g.grid;
    if nx == 0 || ny == 0 {
        return Err(field_err(
            "gas.grid",
            "needs at least 1 node in each cross direction",
        ));
    }
    let nodes = nz.saturating_mul(nx).saturating_mul(ny);
    if nodes > MAX_GAS_NODES {
        return Err(field_err(
            "gas.grid",
            format!(
                "{nz} × {nx} × {ny} = {nodes} nodes is over the limit of {MAX_GAS_NODES} (the \
                 gas keeps ~40 fields and a factorised matrix per node)"
            ),
        ));
    }
    if nz < 2 {
        return Err(field_err(
            "gas.grid",
            "needs at least 2 nodes along the axis",
        ));
    }
    if simple && nx == 1 && !(1..=8).contains(&ny) {
        return Err(field_err(
            "gas.grid",
            "the 2D simple gas (one node across e1: the plane of the axis and e2) takes \
             1 ≤ ny ≤ 8 rows",
        ));
    }
    if simple && nx > 1 && (ny < 2 || nx > 64 || ny > 64) {
        return Err(field_err(
            "gas.grid",
            "the 3D simple gas (cut-cell tube) takes 2 to 64 nodes in each cross direction",
        ));
    }
    let slab = f.tube.as_ref().is_some_and(|t| t.slab.is_some());
    if simple && nx > 1 && slab {
        return Err(field_err(
            "gas.grid",
            "a quasi-2D slab (tube.slab) takes the 2D simple gas, one node across e1: \
             [nz, 1, ny]",
        ));
    }
    if !simple && (!(1..=2).contains(&nx) || !(1..=2).contains(&ny)) {
        return Err(field_err(
            "gas.grid",
            "across the tube 1 or 2 nodes per direction (finer cross-sections would need \
             wall-cut cells with vanishing volume, not supported)",
        ));
    }
    match (g.scheme, g.theta) {
        (GasScheme::Theta, None) => {
            return Err(field_err("gas.theta", "missing: the theta scheme needs it"))
        }
        (GasScheme::Theta, Some(t)) if !(0.5..=1.0).contains(&t.0) => {
            return Err(field_err(
                "gas.theta",
                "must lie in [0.5, 1] (below ½ the scheme is unstable for stiff diffusion)",
            ))
        }
        (s, Some(_)) if s != GasScheme::Theta => {
            return Err(field_err("gas.theta", "only the theta scheme takes it"))
        }
        _ => {}
    }
    if g.scheme == GasScheme::CrankNicolson && g.solver == GasSolverPath::Splitting {
        return Err(field_err(
            "gas.solver",
            "`splitting` with the `crank_nicolson` scheme is unstable (Crank–Nicolson does not \
             damp the splitting's error: the vertical case blew up at 0.35 s); use \
             `monolithic`, or the `bdf2` or `backward_euler` scheme",
        ));
    }
    let (lo, hi) = (g.porosity_min.0, g.porosity_max.0);
    if !(lo > 0.0 && lo < hi && hi < 1.0) {
        return Err(field_err(
            "gas.porosity_min",
            "the clamp needs 0 < porosity_min < porosity_max < 1",
        ));
    }
    check_coupling(f, simple)
}

/// `coupling.fluid_forces`: registered names, each once, each fed by the scene's gas; the
/// `simple` gas's momentum balance needs `pressure_gradient`.
fn check_fluid_forces(f: &SceneFile, simple: bool) -> Result<(), SceneError> {
    const FIELD: &str = "coupling.fluid_forces";
    let names = f.fluid_forces();
    for (k, name) in names.iter().enumerate() {
        let entry = fluid_force(name).ok_or_else(|| {
            field_err(
                FIELD,
                format!("unknown fluid force `{name}` ({})", fluid_force_names(", ")),
            )
        })?;
        if names[..k].contains(name) {
            return Err(field_err(FIELD, format!("`{name}` is listed twice")));
        }
        if !simple && name == "pressure_gradient" {
            return Err(field_err(
                FIELD,
                "`pressure_gradient` with the darcy gas: the d'Arcy volume force is the whole \
                 fluid force, its pressure gradient included (it would count twice)",
            ));
        }
        if entry.needs_gas_velocity && !simple {
            return Err(field_err(
                FIELD,
                format!(
                    "`{name}` needs the gas velocity and density, which only the simple gas \
                     carries"
                ),
            ));
        }
    }
    if simple && !names.iter().any(|n| n == "pressure_gradient") {
        return Err(field_err(
            FIELD,
            "the simple gas needs `pressure_gradient`: its momentum equation carries −ε∇p and \
             leaves (1 − ε)∇p to the grains; without it gas and grains do not conserve momentum",
        ));
    }
    Ok(())
}

/// `[coupling]`: the drag law from the registry, paired with the gas model, and its settings.
fn check_coupling(f: &SceneFile, simple: bool) -> Result<(), SceneError> {
    let drag = f.coupling.as_ref().map_or("darcy", |c| c.drag.as_str());
    // The drag registry says what each law needs (coupling/src/drag/mod.rs).
    let law = drag_law(drag).ok_or_else(|| {
        field_err(
            "coupling.drag",
            format!(
                "unknown drag law `{drag}` ({})",
                drag_law_names(|_| true, ", ")
            ),
        )
    })?;
    if law.needs_gas_velocity != simple {
        return Err(field_err(
            "coupling.drag",
            if simple {
                format!(
                    "the simple gas needs a drag law of the gas velocity: {} (set [coupling] \
                     drag = …)",
                    drag_law_names(|l| l.needs_gas_velocity, " or ")
                )
            } else {
                format!("`{drag}` needs the gas velocity, which only the simple gas carries")
            },
        ));
    }
    check_fluid_forces(f, simple)?;
    if let Some(c) = &f.coupling {
        if let Some(i) = c.interval {
            if i.si <= 0.0 {
                return Err(field_err("coupling.interval", "must be positive"));
            }
        }
        if let Some(cv) = c.voidage_factor {
            if !law.takes_voidage_factor {
                return Err(field_err(
                    "coupling.voidage_factor",
                    format!(
                        "seed 004 eq. 11 scales the voidage of the {} drag; the `{drag}` drag \
                         does not take it",
                        drag_law_names(|l| l.takes_voidage_factor, " or ")
                    ),
                ));
            }
            if !(cv.0 > 0.0 && cv.0 <= 1.0) {
                return Err(field_err(
                    "coupling.voidage_factor",
                    format!(
                        "must lie in (0, 1] (it brings a 2D model's larger voidage down \
                         to the bed's), got {}",
                        cv.0
                    ),
                ));
            }
        }
        if c.porosity_volume == PorosityVolume::WholeCell {
            let why = if simple {
                Some("the simple gas's cut cells need the open volume (its momentum balance is per open volume)")
            } else if f.tube.as_ref().is_some_and(|t| t.slab.is_some()) {
                Some("a quasi-2D slab's cells hold only the slab's volume by design")
            } else if c.smoothing_length.is_some() {
                Some("the smoothing conserves the solid over the open volumes")
            } else {
                None
            };
            if let Some(why) = why {
                return Err(field_err(
                    "coupling.porosity_volume",
                    format!("`whole_cell` is a reading of the d'Arcy model on a full tube: {why}"),
                ));
            }
        }
        if let (Some(l), Some(t)) = (c.smoothing_length, &f.tube) {
            let d = t.diameter.si;
            if !(l.si > 0.0 && l.si <= d) {
                return Err(field_err(
                    "coupling.smoothing_length",
                    format!(
                        "must lie in (0, {d} m] (the tube's diameter: it spreads a deposit \
                         over grains, not across the pipe), got {} m",
                        l.si
                    ),
                ));
            }
        }
    }
    Ok(())
}
