//! From a checked scene to the built-in engine's configuration ([`DemConfig`]): contact
//! laws, time step and its stability limit, walls, box, inlet. Everything here can fail only
//! with a field error. (The engine itself, `dem/`, reads only this configuration.)

use crate::dem::config::{
    open_cross_section, DemConfig, GivenGrain, InitialConfig, InletConfig, LawSet, RollingSet,
    TangentialChoice, TangentialSet, TimeStepReport, TubeGeometry,
};
use crate::dem::contact::{ConstantTorque, Hertz, Hooke, RollingPair, TorqueReading};
use crate::dem::placement::{perpendicular_basis, Region};
use crate::dem::vec3::{add, dot, norm, normalized, scale, sub};
use crate::dem::walls::{Wall, WallShape};
use crate::scene::{
    InletMode, NormalLawName, RollingLawName, Scene, SceneError, TangentialLawName, TubeEnd,
};
use crate::{Real, Vec3};
use std::f64::consts::PI;
use std::path::Path;

/// Grain sizes and density, as every part of the configuration needs them.
struct Grains {
    dmin: Real,
    dmax: Real,
    rmin: Real,
    rmax: Real,
    rho: Real,
}

impl Grains {
    fn of(scene: &Scene) -> Grains {
        let p = &scene.file.particles;
        let (dmin, dmax) = match p.diameter {
            Some(d) => (d.si, d.si),
            None => (
                p.diameter_min.map(|q| q.si).unwrap_or(0.0),
                p.diameter_max.map(|q| q.si).unwrap_or(0.0),
            ),
        };
        Grains {
            dmin,
            dmax,
            rmin: 0.5 * dmin,
            rmax: 0.5 * dmax,
            rho: p.density.si,
        }
    }

    /// Mass of a grain of radius `r`, kg.
    fn mass(&self, r: Real) -> Real {
        self.rho * 4.0 / 3.0 * PI * r * r * r
    }
}

/// Derive the built-in engine's configuration from a checked scene.
pub fn dem_config(scene: &Scene) -> Result<DemConfig, SceneError> {
    let f = &scene.file;
    let g = Grains::of(scene);
    let mut laws = contact_laws(scene, &g);
    let (dt, dt_report, v_max) = time_step(scene, &g, &laws)?;
    let skin = f.dem.skin.map(|s| s.si).unwrap_or(0.1 * g.dmax);
    let Geometry {
        walls,
        box_lo,
        box_hi,
        tube,
        removes,
        periodic,
    } = geometry(scene, g.dmax, skin)?;
    laws.attach_walls(&walls);
    let inlet = inlet_config(scene, tube.as_ref(), &g)?;
    let initial = initial_config(scene, tube.as_ref(), box_lo, box_hi, &g)?;
    Ok(DemConfig {
        dt,
        dt_report,
        rotation: f.dem.rotation,
        skin,
        threads: f.dem.threads,
        gravity: [f.gravity[0].si, f.gravity[1].si, f.gravity[2].si],
        walls,
        laws,
        rolling: rolling_law(scene),
        box_lo,
        box_hi,
        periodic,
        tube,
        inlet,
        initial,
        radius_min: g.rmin,
        radius_max: g.rmax,
        density: g.rho,
        seed: f.seed,
        removes_grains: removes,
        max_impact_velocity: v_max,
        settle: f.dem.settle.map(|t| t.si),
    })
}

/// `[contact]` → the laws, grain–grain and grain–wall.
fn contact_laws(scene: &Scene, g: &Grains) -> LawSet {
    let (dmin, dmax) = (g.dmin, g.dmax);
    let mass = |r: Real| g.mass(r);
    let c = &scene.file.contact;
    let e_pp = c.restitution.0;
    let e_pw = c.wall_restitution.map(|e| e.0).unwrap_or(e_pp);
    let mu_pp = c.friction.0;
    let mu_pw = c.wall_friction.map(|m| m.0).unwrap_or(mu_pp);
    // One arm per law name: the tangential law is chosen once, for whichever normal law.
    let tangential = match c.tangential {
        TangentialLawName::History => TangentialChoice::History {
            gamma_t: c.tangential_damping.map(|g| g.si),
        },
        TangentialLawName::LiggghtsHistory => TangentialChoice::LiggghtsHistory {
            gamma_t: c.tangential_damping.map(|g| g.si),
        },
        TangentialLawName::CoulombViscous => TangentialChoice::CoulombViscous {
            gamma_t: c.tangential_damping.map(|g| g.si),
        },
    };
    let laws = match c.normal {
        NormalLawName::Hooke => {
            let ratio = c
                .tangential_stiffness_ratio
                .map(|r| r.0)
                .unwrap_or(2.0 / 7.0);
            let kn = match (c.stiffness, c.contact_time) {
                (Some(k), _) => k.si,
                (None, Some(tc)) => {
                    // Contact time given for two grains of the mean size.
                    let m_mean = mass(0.25 * (dmin + dmax));
                    Hooke::stiffness_for_contact_time(tc.si, 0.5 * m_mean, e_pp)
                }
                (None, None) => unreachable!("checked in scene::check"),
            };
            let (pp, pw) = (Hooke::new(kn, e_pp, ratio), Hooke::new(kn, e_pw, ratio));
            LawSet::Hooke(TangentialSet::new(tangential, pp, pw, mu_pp, mu_pw))
        }
        NormalLawName::Hertz => {
            let e_mod = c.youngs_modulus.map(|q| q.si).unwrap_or(0.0);
            let nu = c.poisson_ratio.map(|q| q.0).unwrap_or(0.0);
            let (pp, pw) = (Hertz::new(e_mod, nu, e_pp), Hertz::new(e_mod, nu, e_pw));
            LawSet::Hertz(TangentialSet::new(tangential, pp, pw, mu_pp, mu_pw))
        }
    };
    laws
}

/// `contact.rolling` → the rolling law, grain–grain and grain–wall (values checked in
/// `scene::check`).
fn rolling_law(scene: &Scene) -> RollingSet {
    let c = &scene.file.contact;
    match c.rolling {
        RollingLawName::None => RollingSet::None,
        RollingLawName::ConstantTorque | RollingLawName::ConstantResistance => {
            let reading = if c.rolling == RollingLawName::ConstantTorque {
                TorqueReading::ElasticNoTwist
            } else {
                TorqueReading::WholeForceAndRotation
            };
            let pp = c.rolling_friction.map(|m| m.0).unwrap_or(0.0);
            let pw = c.wall_rolling_friction.map(|m| m.0).unwrap_or(pp);
            RollingSet::ConstantTorque(RollingPair {
                pp: ConstantTorque { mu_r: pp, reading },
                pw: ConstantTorque { mu_r: pw, reading },
            })
        }
    }
}

/// The time step, its stability limit and why, and the largest impact speed (m/s).
fn time_step(
    scene: &Scene,
    g: &Grains,
    laws: &LawSet,
) -> Result<(Real, TimeStepReport, Real), SceneError> {
    let f = &scene.file;
    let c = &f.contact;
    let (rmin, rho) = (g.rmin, g.rho);
    let mass = |r: Real| g.mass(r);
    // Time step: the smallest grain pair collides fastest.
    let v_max = f.dem.max_impact_velocity.si;
    let m_small = mass(rmin);
    let tc = laws.pair_contact_time(0.5 * m_small, 0.5 * rmin, v_max);
    let mut limit = tc / 10.0;
    let mut limit_reason = format!(
        "contact time {tc:.3e} s of the smallest grain pair / 10 (a collision must span ≥ 10 steps)"
    );
    let mut rayleigh = None;
    if c.normal == NormalLawName::Hertz {
        let e_mod = c.youngs_modulus.map(|q| q.si).unwrap_or(0.0);
        let nu = c.poisson_ratio.map(|q| q.0).unwrap_or(0.0);
        let shear = e_mod / (2.0 * (1.0 + nu));
        let t_r = PI * rmin * (rho / shear).sqrt() / (0.1631 * nu + 0.8766);
        rayleigh = Some(t_r);
        if 0.2 * t_r < limit {
            limit = 0.2 * t_r;
            limit_reason = format!("20 % of the Rayleigh time {t_r:.3e} s");
        }
    }
    let (dt, derived) = match f.dem.dt {
        Some(dt) => {
            if dt.si > limit {
                return Err(field_err(
                    "dem.dt",
                    format!(
                        "{:.3e} s is above the stability limit {:.3e} s ({}); use a smaller \
                         dt or leave it out to derive contact time / {}",
                        dt.si, limit, limit_reason, f.dem.dt_fraction.0
                    ),
                ));
            }
            (dt.si, false)
        }
        None => ((tc / f.dem.dt_fraction.0).min(limit), true),
    };
    // A run of more steps than this would not end in a lifetime of a machine (1e10 steps of
    // 1000 grains take ~4 days at 3e7 particle-steps/s); what was meant is surely else.
    const MAX_STEPS: Real = 1e10;
    let steps = f.duration.si / dt;
    if steps.is_nan() || steps > MAX_STEPS {
        let (field, why) = if derived {
            (
                "dem.dt_fraction",
                format!(
                    "the contact time {tc:.3e} s / dt_fraction {:e}; check the contact's \
                     stiffness or contact time too",
                    f.dem.dt_fraction.0
                ),
            )
        } else {
            ("dem.dt", "as given".to_string())
        };
        return Err(field_err(
            field,
            format!(
                "the run would need {steps:.3e} steps of dt = {dt:.3e} s ({why}) for its \
                 duration of {} s, over the limit of {MAX_STEPS:e}",
                f.duration.si
            ),
        ));
    }
    Ok((
        dt,
        TimeStepReport {
            contact_time: tc,
            rayleigh_time: rayleigh,
            limit,
            limit_reason,
            derived,
        },
        v_max,
    ))
}

/// The walls, the simulation box and the tube in engine terms.
struct Geometry {
    walls: Vec<Wall>,
    box_lo: Vec3,
    box_hi: Vec3,
    tube: Option<TubeGeometry>,
    /// Grains can leave (open ends or a box).
    removes: bool,
    /// Periodic lab directions.
    periodic: [bool; 3],
}

/// The lab direction a unit axis lies along, if any.
fn periodic_axis(axis: Vec3) -> Option<usize> {
    (0..3).find(|&k| (axis[k].abs() - 1.0).abs() < 1e-12)
}

/// `[tube]` (its wall, caps and slab planes) or `[domain]`, and `[[walls]]`.
fn geometry(scene: &Scene, dmax: Real, skin: Real) -> Result<Geometry, SceneError> {
    let f = &scene.file;
    let mut walls = Vec::new();
    let (mut box_lo, mut box_hi);
    let mut tube_geom = None;
    let removes;
    let mut periodic = [false; 3];
    if let Some(t) = &f.tube {
        let axis = normalized([t.axis[0].0, t.axis[1].0, t.axis[2].0]);
        let origin = [t.origin[0].si, t.origin[1].si, t.origin[2].si];
        let radius = 0.5 * t.diameter.si;
        let length = t.length.si;
        walls.push(Wall {
            name: "tube".into(),
            shape: WallShape::Cylinder {
                point: origin,
                axis,
                radius,
            },
            friction: None,
        });
        if !t.periodic && t.inlet() == TubeEnd::Closed {
            walls.push(Wall {
                name: "inlet_cap".into(),
                shape: WallShape::Plane {
                    point: origin,
                    normal: axis,
                },
                friction: None,
            });
        }
        if !t.periodic && t.outlet() == TubeEnd::Closed {
            walls.push(Wall {
                name: "outlet_cap".into(),
                shape: WallShape::Plane {
                    point: add(origin, scale(axis, length)),
                    normal: scale(axis, -1.0),
                },
                friction: None,
            });
        }
        let slab_half = match t.slab {
            None => None,
            Some(w) if w.si < dmax || w.si >= 2.0 * radius => {
                return Err(field_err(
                    "tube.slab",
                    format!(
                        "{:.4e} m must lie between the largest grain's diameter {:.4e} m and \
                         the tube's {:.4e} m",
                        w.si,
                        dmax,
                        2.0 * radius
                    ),
                ))
            }
            Some(w) => {
                let (e1, _) = perpendicular_basis(axis);
                let h = 0.5 * w.si;
                let slab_friction = t.slab_friction.map_or(0.0, |m| m.0);
                for (name, sign) in [("slab_front", 1.0), ("slab_back", -1.0)] {
                    walls.push(Wall {
                        name: name.into(),
                        shape: WallShape::Plane {
                            point: add(origin, scale(e1, sign * h)),
                            normal: scale(e1, -sign),
                        },
                        friction: Some(slab_friction),
                    });
                }
                Some(h)
            }
        };
        removes = !t.periodic && (t.inlet() == TubeEnd::Open || t.outlet() == TubeEnd::Open);
        // Box around the tube with one diameter of margin at the ends.
        let end = add(origin, scale(axis, length));
        box_lo = [0.0; 3];
        box_hi = [0.0; 3];
        // (A quasi-2D slab spans at most h |e1_k| + R |e2_k| along k: a box that tight
        // keeps the neighbour grid small.)
        let (e1, e2) = perpendicular_basis(axis);
        for k in 0..3 {
            let mut half = radius * (1.0 - axis[k] * axis[k]).max(0.0).sqrt();
            if let Some(h) = slab_half {
                half = half.min(h * e1[k].abs() + radius * e2[k].abs());
            }
            box_lo[k] = origin[k].min(end[k]) - half - dmax;
            box_hi[k] = origin[k].max(end[k]) + half + dmax;
        }
        if t.periodic {
            // The box spans the section exactly along the axis: its length is the period.
            let k = periodic_axis(axis).ok_or_else(|| {
                field_err(
                    "tube.axis",
                    "a periodic tube lies along x, y or z (the periodic box is axis-aligned)",
                )
            })?;
            box_lo[k] = origin[k].min(end[k]);
            box_hi[k] = origin[k].max(end[k]);
            periodic[k] = true;
        }
        tube_geom = Some(TubeGeometry {
            origin,
            axis,
            radius,
            length,
            inlet_open: !t.periodic && t.inlet() == TubeEnd::Open,
            outlet_open: !t.periodic && t.outlet() == TubeEnd::Open,
            periodic: t.periodic,
            slab_half,
        });
    } else {
        let b = f.domain.as_ref().expect("checked: tube or domain");
        box_lo = b.min.map(|q| q.si);
        box_hi = b.max.map(|q| q.si);
        periodic = b.periodic;
        removes = periodic.iter().any(|p| !p);
    }
    for w in &f.walls {
        walls.push(Wall {
            name: w.name.clone(),
            shape: WallShape::Plane {
                point: w.point.map(|q| q.si),
                normal: normalized(w.normal.map(|q| q.0)),
            },
            friction: None,
        });
    }
    // Three cells of the neighbour grid along each periodic direction (one pair, one image).
    let cell = 2.0 * (0.5 * dmax) + skin;
    for k in 0..3 {
        if periodic[k] && box_hi[k] - box_lo[k] < 3.0 * cell {
            let field = if f.tube.is_some() {
                "tube.length"
            } else {
                "domain.max"
            };
            return Err(field_err(
                field,
                format!(
                    "a periodic length of {:.4e} m is under three neighbour cells (3 × (d_max + \
                     skin) = {:.4e} m): a grain would meet its own image",
                    box_hi[k] - box_lo[k],
                    3.0 * cell
                ),
            ));
        }
    }
    Ok(Geometry {
        walls,
        box_lo,
        box_hi,
        tube: tube_geom,
        removes,
        periodic,
    })
}

/// `[inlet]` in engine terms (None without one).
fn inlet_config(
    scene: &Scene,
    tube: Option<&TubeGeometry>,
    g: &Grains,
) -> Result<Option<InletConfig>, SceneError> {
    let f = &scene.file;
    let (rmin, rmax, rho, dmax) = (g.rmin, g.rmax, g.rho, g.dmax);
    let inlet = match (&f.inlet, tube) {
        (Some(i), Some(t)) => {
            let v_mean = 4.0 / 3.0 * PI * (0.5 * (rmin + rmax)).powi(3);
            let m_mean = rho * v_mean;
            let rate = match (i.mass_flow, i.rate) {
                (Some(m), _) => m.si / m_mean,
                (None, Some(r)) => r.si,
                _ => unreachable!("checked in scene::check"),
            };
            if i.velocity.si <= 0.0 {
                return Err(field_err(
                    "inlet.velocity",
                    "must be > 0: the feed moves along the tube axis, into the tube",
                ));
            }
            let slab = i.slab_length.map(|q| q.si).unwrap_or(3.0 * dmax);
            if slab >= t.length {
                return Err(field_err(
                    "inlet.slab_length",
                    "must be shorter than the tube",
                ));
            }
            let area = open_cross_section(t.radius, t.slab_half);
            let mut porosity = i.porosity.0;
            if i.mode == InletMode::Conveyor {
                // The column's porosity is what carries the rate at the velocity:
                // 1 − rate V̄ / (A v). The scene's `porosity` is read from the seeds'
                // figures (0.51 against the 0.52 their 2.49 kg/h at 0.04 m/s make): it must
                // agree to 0.02, the figure's reading precision.
                let made = 1.0 - rate * v_mean / (area * i.velocity.si);
                if (made - porosity).abs() > 0.02 {
                    return Err(field_err(
                        "inlet.porosity",
                        format!(
                            "{porosity} disagrees with the conveyor's: {made:.4} carries the \
                             {} of `inlet.{}` at {} m/s through the {area:.4e} m² \
                             cross-section (1 − rate × grain volume / (area × velocity)); \
                             the conveyor enforces the flow, so give a porosity within 0.02 \
                             of it or change the flow or the velocity",
                            if i.mass_flow.is_some() {
                                format!("{:.4e} kg/s", rate * m_mean)
                            } else {
                                format!("{rate:.4e} grains/s")
                            },
                            if i.mass_flow.is_some() {
                                "mass_flow"
                            } else {
                                "rate"
                            },
                            i.velocity.si
                        ),
                    ));
                }
                porosity = made;
            }
            let batch_target = ((1.0 - porosity) * area * slab / v_mean).floor().max(1.0) as usize;
            // Densest feed possible: random close packing (64 % solids) moving at the
            // feed velocity fills area × velocity per second.
            let capacity = 0.64 * area * i.velocity.si / v_mean;
            if rate > capacity {
                return Err(field_err(
                    if i.mass_flow.is_some() {
                        "inlet.mass_flow"
                    } else {
                        "inlet.rate"
                    },
                    format!(
                        "{rate:.4e} grains/s cannot fit the tube: at {} m/s even random \
                         close packing carries at most {capacity:.4e} grains/s ({:.4e} kg/h) \
                         through the {:.4e} m² cross-section",
                        i.velocity.si,
                        capacity * m_mean * 3600.0,
                        area
                    ),
                ));
            }
            Some(InletConfig {
                mode: i.mode,
                rate,
                velocity: i.velocity.si,
                slab_length: slab,
                batch_target,
                porosity,
                until: match i.until {
                    Some(u) if u.si < 0.0 => return Err(field_err("inlet.until", "must be ≥ 0 s")),
                    u => u.map(|q| q.si),
                },
            })
        }
        _ => None,
    };
    Ok(inlet)
}

/// `[initial]` in engine terms (None without one): grains from a file, or grains to place
/// in a stretch, a shaped plug and/or a resting layer (or a box's z range).
fn initial_config(
    scene: &Scene,
    tube: Option<&TubeGeometry>,
    box_lo: Vec3,
    box_hi: Vec3,
    g: &Grains,
) -> Result<Option<InitialConfig>, SceneError> {
    let f = &scene.file;
    let Some(ini) = &f.initial else {
        return Ok(None);
    };
    if let Some(path) = &ini.file {
        let grains = read_grain_file(Path::new(path), g, tube, box_lo, box_hi)?;
        return Ok(Some(InitialConfig::Given(grains)));
    }
    let count = ini.count.expect("checked: count or file");
    let stretch = ini.from.zip(ini.to).map(|(a, b)| (a.si, b.si));
    let region = match tube {
        Some(t) => {
            if let Some((from, to)) = stretch {
                if from < 0.0 || to > t.length {
                    return Err(field_err(
                        "initial.to",
                        format!(
                            "the stretch [{from}, {to}] m must lie inside the tube [0, {}] m",
                            t.length
                        ),
                    ));
                }
            }
            if ini.layer_height.is_none() && ini.end_angle.is_none() {
                let (from, to) = stretch.expect("checked: a stretch or a layer");
                Region::TubeStretch {
                    origin: t.origin,
                    axis: t.axis,
                    radius: t.radius,
                    slab_half: t.slab_half,
                    from,
                    to,
                }
            } else {
                // Up: against gravity, across the axis (checked to be non-zero).
                let gv = f.gravity.map(|q| q.si);
                let across = sub(gv, scale(t.axis, dot(gv, t.axis)));
                let up = scale(normalized(across), -1.0);
                let cot = ini
                    .end_angle
                    .map_or(0.0, |a| 1.0 / a.0.to_radians().tan())
                    .max(0.0);
                Region::TubeShape {
                    origin: t.origin,
                    axis: t.axis,
                    radius: t.radius,
                    slab_half: t.slab_half,
                    length: t.length,
                    up,
                    plug: stretch.map(|(from, to)| (from, to, cot)),
                    layer: ini.layer_height.map(|h| h.si),
                }
            }
        }
        None => {
            let (from, to) = stretch.expect("checked: a box fill is a z stretch");
            let mut lo = box_lo;
            let mut hi = box_hi;
            lo[2] = from;
            hi[2] = to;
            Region::Box { lo, hi }
        }
    };
    Ok(Some(InitialConfig::Placed {
        count,
        region,
        velocity: ini
            .velocity
            .map(|v| [v[0].si, v[1].si, v[2].si])
            .unwrap_or([0.0; 3]),
    }))
}

/// The grains of an `initial.file`: CSV, a header naming `x,y,z,radius` and optionally
/// `vx,vy,vz` (SI) and `frozen` (1: held in place, 0: free), one grain per line. Each grain is checked: finite numbers, a radius
/// within the scene's `[particles]` range (1e-9 relative), inside the tube or box, and no
/// overlap deeper than 5 % of the smaller radius with another (a bed settled by another
/// code overlaps by a fraction of a percent; deeper, the first step would blow it apart).
fn read_grain_file(
    path: &Path,
    g: &Grains,
    tube: Option<&TubeGeometry>,
    box_lo: Vec3,
    box_hi: Vec3,
) -> Result<Vec<GivenGrain>, SceneError> {
    const FIELD: &str = "initial.file";
    let text = std::fs::read_to_string(path)
        .map_err(|e| field_err(FIELD, format!("{}: {e}", path.display())))?;
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let (_, header) = lines
        .next()
        .ok_or_else(|| field_err(FIELD, format!("{}: empty", path.display())))?;
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let column = |name: &str| names.iter().position(|n| *n == name);
    let (Some(cx), Some(cy), Some(cz), Some(cr)) =
        (column("x"), column("y"), column("z"), column("radius"))
    else {
        return Err(field_err(
            FIELD,
            format!(
                "{}: the header `{header}` must name the columns x, y, z, radius (and \
                 optionally vx, vy, vz)",
                path.display()
            ),
        ));
    };
    let velocity = match (column("vx"), column("vy"), column("vz")) {
        (Some(a), Some(b), Some(c)) => Some([a, b, c]),
        (None, None, None) => None,
        _ => {
            return Err(field_err(
                FIELD,
                format!("{}: give all of vx, vy, vz or none", path.display()),
            ))
        }
    };
    let frozen_column = column("frozen");
    let mut grains = Vec::new();
    for (k, line) in lines {
        let at =
            |what: String| field_err(FIELD, format!("{} line {}: {what}", path.display(), k + 1));
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        if cells.len() != names.len() {
            return Err(at(format!(
                "{} values for {} columns",
                cells.len(),
                names.len()
            )));
        }
        let num = |c: usize| -> Result<Real, SceneError> {
            cells[c]
                .parse::<Real>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    at(format!(
                        "`{}` ({}) is not a finite number",
                        cells[c], names[c]
                    ))
                })
        };
        let x = [num(cx)?, num(cy)?, num(cz)?];
        let r = num(cr)?;
        if !(r >= g.rmin * (1.0 - 1e-9) && r <= g.rmax * (1.0 + 1e-9)) {
            return Err(at(format!(
                "radius {r} m lies outside the scene's grains [{}, {}] m",
                g.rmin, g.rmax
            )));
        }
        let v = match velocity {
            Some([a, b, c]) => [num(a)?, num(b)?, num(c)?],
            None => [0.0; 3],
        };
        let inside = match tube {
            Some(t) => {
                let rel = sub(x, t.origin);
                let s = dot(rel, t.axis);
                let radial = norm(sub(rel, scale(t.axis, s)));
                radial + r <= t.radius * (1.0 + 1e-9) && s >= 0.0 && s <= t.length
            }
            None => (0..3).all(|c| x[c] >= box_lo[c] && x[c] <= box_hi[c]),
        };
        if !inside {
            return Err(at(format!(
                "the grain at {x:?} m does not lie inside the {}",
                if tube.is_some() { "tube" } else { "box" }
            )));
        }
        let frozen = match frozen_column.map(|c| cells[c]) {
            None | Some("0") => false,
            Some("1") => true,
            Some(other) => {
                return Err(at(format!("`{other}` (frozen) is neither 0 nor 1")));
            }
        };
        grains.push(GivenGrain {
            position: x,
            radius: r,
            velocity: if frozen { [0.0; 3] } else { v },
            line: k + 1,
            frozen,
        });
    }
    if grains.is_empty() {
        return Err(field_err(FIELD, format!("{}: no grains", path.display())));
    }
    // Overlaps, on a hash grid of cells one largest diameter wide.
    let cell = 2.0 * g.rmax;
    let key = |x: Vec3| x.map(|c| (c / cell).floor() as i64);
    let mut grid: std::collections::HashMap<[i64; 3], Vec<usize>> = Default::default();
    for (i, gr) in grains.iter().enumerate() {
        grid.entry(key(gr.position)).or_default().push(i);
    }
    for (i, a) in grains.iter().enumerate() {
        let c = key(a.position);
        for d in 0..27i64 {
            let n = [c[0] + d % 3 - 1, c[1] + (d / 3) % 3 - 1, c[2] + d / 9 - 1];
            for &j in grid.get(&n).map_or(&[][..], |v| &v[..]) {
                if j <= i {
                    continue;
                }
                let b = &grains[j];
                let overlap = a.radius + b.radius - norm(sub(a.position, b.position));
                if overlap > 0.05 * a.radius.min(b.radius) {
                    return Err(field_err(
                        FIELD,
                        format!(
                            "{}: the grains of lines {} and {} overlap by {overlap:.3e} m, over \
                             5 % of a radius",
                            path.display(),
                            a.line,
                            b.line
                        ),
                    ));
                }
            }
        }
    }
    Ok(grains)
}

fn field_err(field: impl Into<String>, reason: impl Into<String>) -> SceneError {
    SceneError::field(field, reason)
}
