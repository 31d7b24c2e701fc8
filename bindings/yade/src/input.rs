//! Scene → YADE setup (the JSON `driver.py` builds the simulation from). Everything is
//! checked here; what YADE's laws cannot express is refused with the field and the reason.
//!
//! Contact laws, so that YADE computes the built-in engine's forces:
//! - Hooke → `ViscElMat` + `Law2_ScGeom_ViscElPhys_Basic` with absolute k_n, k_t, c_n, c_t.
//!   YADE combines two materials' constants in series, 1/(1/a + 1/b), a zero counting as
//!   absent: grains carry twice the grain–grain constants; walls carry the value that
//!   gives the grain–wall constant in series (zero when it is exactly twice the
//!   grain–grain one, as for a Hooke law from a contact time: m* = m against a wall).
//!   Friction is tan(min of the two friction angles).
//!   YADE's ViscEl law clamps the normal force at zero (the dashpot never pulls), which
//!   ends a contact before the overlap closes and raises the restitution (e = 0.5 becomes
//!   0.545 with the same damping). The restitution is the scene's parameter, so YADE gets
//!   the normal damping that yields the scene's e with that cutoff
//!   ([`linear_cutoff_damping_ratio`]); stiffness, tangential damping and friction are the
//!   built-in engine's.
//! - Hertz → `FrictMat` + `Law2_ScGeom_MindlinPhys_Mindlin` with `en` from
//!   [`beta_form_restitution`] (YADE's Mindlin damping has LIGGGHTS's β form). YADE takes
//!   R* = r/2 against a `Wall` or a `Box` (the built-in engine: r), and mixes
//!   moduli as (G₁+G₂)/2, (ν₁+ν₂)/2 for the shear stiffness: the wall and tube materials get
//!   the (E, ν) that make YADE's k_n = 4/3 E*√(R*δ)·δ and k_t = 4√R* G/(2−ν)·√δ equal the
//!   built-in ones. They are fitted constants, not the wall's physical modulus.
//! - YADE has no cylindrical container. The tube is a regular polygon of 96 fixed thin
//!   boxes (not facets: YADE's facet contacts count a grain twice where it straddles the
//!   diagonal of two coplanar triangles, measured), its radius chosen so that the wall lies
//!   within ±R(1 − cos π/N)/2 (±0.47 µm in the 7 mm tube) of the true cylinder.
//!
//! Known differences, all second order for the comparison tests: YADE adds the tangential
//! damping only while a contact sticks (the built-in engine caps spring + damper
//! together); YADE's Mindlin law integrates the shear force incrementally and damps shear
//! with the normal coefficient.

use plugflow_model::dem::config::{InitialConfig, LawSet, RollingSet, TangentialSet};
use plugflow_model::dem::external::{
    beta_form_restitution, linear_cutoff_damping_ratio, linear_pairs, single_grain_mass, LinearPair,
};
use plugflow_model::dem::walls::WallShape;
use plugflow_model::dem::DemConfig;
use plugflow_model::scene::Scene;
use serde::Serialize;

/// Sides of the tube's polygon.
pub const TUBE_SEGMENTS: usize = 96;

/// A refused scene: field and reason.
#[derive(Debug)]
pub struct Refusal {
    pub field: String,
    pub reason: String,
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "field `{}`: {} (YADE backend)", self.field, self.reason)
    }
}

fn refuse(field: &str, reason: impl Into<String>) -> Refusal {
    Refusal {
        field: field.into(),
        reason: reason.into(),
    }
}

/// One YADE material (the fields of its law; the others are left out of the JSON).
#[derive(Debug, Clone, Serialize, Default)]
pub struct Material {
    pub density: f64,
    pub friction_angle: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub kn: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ks: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cn: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cs: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub young: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub poisson: Option<f64>,
}

/// A closed end or a plane: YADE's infinite `Wall`, normal to coordinate `axis`.
#[derive(Debug, Clone, Serialize)]
pub struct Cap {
    pub name: String,
    pub axis: usize,
    pub position: f64,
}

/// The tube along coordinate `axis`: a regular polygon of `segments` boxes whose inner
/// faces have their vertices at angles 2πk/N on `vertex_radius`.
#[derive(Debug, Clone, Serialize)]
pub struct Tube {
    pub name: String,
    pub axis: usize,
    pub centre: [f64; 3],
    pub start: f64,
    pub end: f64,
    pub vertex_radius: f64,
    pub segments: usize,
    /// Radial thickness of the boxes, m.
    pub thickness: f64,
}

/// Everything driver.py needs.
#[derive(Debug, Clone, Serialize)]
pub struct Setup {
    pub dt: f64,
    pub gravity: [f64; 3],
    pub skin: f64,
    pub rotation: bool,
    /// "viscel" or "mindlin".
    pub law: String,
    pub grain: Material,
    pub cap: Material,
    pub tube_wall: Material,
    /// Mindlin: restitution handed to YADE, grain–grain and grain–wall.
    pub en_pp: f64,
    pub en_pw: f64,
    pub caps: Vec<Cap>,
    pub tube: Option<Tube>,
}

fn axis_index(axis: [f64; 3]) -> Option<usize> {
    (0..3).find(|&k| {
        (0..3).filter(|&j| j != k).all(|j| axis[j].abs() < 1e-12)
            && (axis[k].abs() - 1.0).abs() < 1e-12
    })
}

/// The wall value that gives the pair value `pw` in series with the grain value `2 pp`
/// (zero = absent in YADE: the pair then takes the grain's value).
fn series_partner(pp: f64, pw: f64, what: &str) -> Result<f64, Refusal> {
    let grain = 2.0 * pp;
    if (pw - grain).abs() <= 1e-12 * grain.abs() {
        return Ok(0.0);
    }
    if pw < grain && pw > 0.0 {
        return Ok(1.0 / (1.0 / pw - 1.0 / grain));
    }
    Err(refuse(
        "contact",
        format!(
            "YADE combines the grain and wall {what} in series, so a grain–wall value ({pw:e}) \
             above twice the grain–grain one ({pp:e}) cannot be expressed"
        ),
    ))
}

/// Friction angle of the wall material: YADE takes the smaller of the two angles.
fn wall_friction_angle(mu_pp: f64, mu_pw: f64) -> Result<f64, Refusal> {
    if mu_pw > mu_pp {
        return Err(refuse(
            "contact.wall_friction",
            "YADE's contact friction is the smaller of the two materials' angles, so the \
             wall friction cannot exceed the grain friction",
        ));
    }
    Ok(mu_pw.atan())
}

/// (E, ν) of a wall material that makes YADE's Mindlin stiffnesses for a grain of modulus
/// `e`, ratio `nu` against it, with YADE's effective radius c²·r, equal the built-in
/// engine's (wall as a body of the grains' material, R* = r):
///   normal:  E*(E, E_w, ν, ν_w)·c = Y*,  Y* = E/(2(1−ν²)), E* = E E_w/((1−ν²)E_w + (1−ν_w²)E),
///   shear:   c·(G + G_w)/2 / (2 − (ν + ν_w)/2) = G/(2−ν).
/// The normal condition gives E_w = Y*(1−ν_w²)/(c − ½) for each ν_w; the shear one is
/// solved for ν_w in (−0.99, 0.99) by bisection.
pub fn wall_modulus(e: f64, nu: f64, c: f64) -> Option<(f64, f64)> {
    let y = e / (2.0 * (1.0 - nu * nu));
    let g = e / (2.0 * (1.0 + nu));
    let ew = |nw: f64| y * (1.0 - nw * nw) / (c - 0.5);
    let f = |nw: f64| {
        let gw = ew(nw) / (2.0 * (1.0 + nw));
        c * 0.5 * (g + gw) / (2.0 - 0.5 * (nu + nw)) - g / (2.0 - nu)
    };
    let (mut lo, mut hi) = (-0.99, 0.99);
    if f(lo) * f(hi) > 0.0 {
        return None;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if f(lo) * f(mid) <= 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let nw = 0.5 * (lo + hi);
    Some((ew(nw), nw))
}

/// Map a checked scene.
pub fn map(scene: &Scene, cfg: &DemConfig) -> Result<Setup, Refusal> {
    if cfg.tube.is_some_and(|t| t.slab_half.is_some()) {
        return Err(refuse(
            "tube.slab",
            "quasi-2D slabs are not mapped to YADE (not cross-checked); use dem.engine = \
             \"native\"",
        ));
    }
    if scene.file.dem.liggghts_input.is_some() {
        return Err(refuse(
            "dem.liggghts_input",
            "a LIGGGHTS input file is for the LIGGGHTS engine",
        ));
    }
    if let Some(InitialConfig::Given(grains)) = &cfg.initial {
        if grains.iter().any(|g| g.frozen) {
            return Err(refuse(
                "initial.file",
                "frozen grains are not mapped to YADE (not cross-checked); use dem.engine = \
                 \"native\"",
            ));
        }
    }
    if cfg.periodic.iter().any(|&p| p) {
        let field = if cfg.tube.is_some() {
            "tube.periodic"
        } else {
            "domain.periodic"
        };
        return Err(refuse(
            field,
            "periodic boxes are not mapped to YADE (its periodic cell wraps all three \
             directions; not cross-checked); use dem.engine = \"native\" or \"liggghts\"",
        ));
    }
    if !matches!(cfg.rolling, RollingSet::None) {
        return Err(refuse(
            "contact.rolling",
            "not mapped to YADE: its rolling resistance (ViscElMat's `mR`, after Zhou et al. \
             1999) is not shown to equal the constant directional torque term for term (normal \
             force, lever arm R*, the twist removed); use dem.engine = \"native\" or \
             \"liggghts\"",
        ));
    }
    let Some(_) = single_grain_mass(cfg) else {
        return Err(refuse(
            "particles.diameter_min",
            "grains of several sizes are not mapped (the damping per material pair is exact \
             for one size only); give `particles.diameter`",
        ));
    };
    let rho = cfg.density;
    let (law, grain, cap, tube_wall, en_pp, en_pw) = match &cfg.laws {
        LawSet::Hooke(TangentialSet::LiggghtsHistory(_))
        | LawSet::Hertz(TangentialSet::LiggghtsHistory(_)) => {
            return Err(refuse(
                "contact.tangential",
                "`liggghts_history` is LIGGGHTS's shear spring for cross-checks against \
                 LIGGGHTS; YADE's Cundall–Strack spring is not shown to keep its conventions \
                 (the cap on the spring alone, no dashpot while sliding); use `history`",
            ))
        }
        LawSet::Hooke(TangentialSet::CoulombViscous(_))
        | LawSet::Hertz(TangentialSet::CoulombViscous(_)) => {
            return Err(refuse(
                "contact.tangential",
                "YADE has no regularised Coulomb law: its viscous shear force is never capped \
                 by μ|F_n| (Law2_ScGeom_ViscElPhys_Basic adds it whenever the elastic part \
                 sticks); use `history`",
            ))
        }
        LawSet::Hooke(TangentialSet::History(l)) => {
            let (mut pp, mut pw): (LinearPair, LinearPair) =
                linear_pairs(cfg).expect("one grain size, Hooke");
            // YADE clamps F_n ≥ 0, ending the contact before the overlap closes: the
            // normal damping that gives the scene's restitution with that cutoff.
            let m = single_grain_mass(cfg).expect("one grain size");
            let cutoff = |zeta: f64, k: f64, m_eff: f64, field: &str| {
                let e = (-zeta * std::f64::consts::PI / (1.0 - zeta * zeta).sqrt()).exp();
                linear_cutoff_damping_ratio(e)
                    .map(|z| 2.0 * z * (k * m_eff).sqrt())
                    .ok_or_else(|| {
                        refuse(
                            field,
                            "YADE's clamped spring–dashpot cannot reach this restitution",
                        )
                    })
            };
            pp.gamma_n = cutoff(l.pp_normal.zeta, pp.kn, 0.5 * m, "contact.restitution")?;
            pw.gamma_n = cutoff(l.pw_normal.zeta, pw.kn, m, "contact.wall_restitution")?;
            let grain = Material {
                density: rho,
                friction_angle: pp.mu.atan(),
                kn: Some(2.0 * pp.kn),
                ks: Some(2.0 * pp.kt),
                cn: Some(2.0 * pp.gamma_n),
                cs: Some(2.0 * pp.gamma_t),
                ..Default::default()
            };
            let wall = Material {
                density: rho,
                friction_angle: wall_friction_angle(pp.mu, pw.mu)?,
                kn: Some(series_partner(pp.kn, pw.kn, "normal stiffnesses")?),
                ks: Some(series_partner(pp.kt, pw.kt, "tangential stiffnesses")?),
                cn: Some(series_partner(pp.gamma_n, pw.gamma_n, "normal damping")?),
                cs: Some(series_partner(
                    pp.gamma_t,
                    pw.gamma_t,
                    "tangential damping",
                )?),
                ..Default::default()
            };
            ("viscel", grain, wall.clone(), wall, 0.0, 0.0)
        }
        LawSet::Hertz(TangentialSet::History(l)) if l.pp_tangential.gamma_t.is_some() => {
            return Err(refuse(
                "contact.tangential_damping",
                "YADE's Mindlin law damps the shear with its own β; not mapped with the \
                 scene's γ_t",
            ))
        }
        LawSet::Hertz(TangentialSet::History(l)) => {
            let c = &scene.file.contact;
            let e = c.youngs_modulus.map(|q| q.si).unwrap_or(0.0);
            let nu = c.poisson_ratio.map(|q| q.0).unwrap_or(0.0);
            // YADE's Mindlin law damps in LIGGGHTS's β form (its restitution equals `en`
            // to 1e-4, measured: the F_n ≥ 0 clamp hardly acts under Tsuji damping).
            let e_of = |alpha: f64, field: &str| {
                beta_form_restitution(alpha).ok_or_else(|| {
                    refuse(
                        field,
                        "this restitution needs more damping than YADE's Mindlin law can \
                         express (|β| ≥ 1)",
                    )
                })
            };
            let grain = Material {
                density: rho,
                friction_angle: l.pp_tangential.mu.atan(),
                young: Some(e),
                poisson: Some(nu),
                ..Default::default()
            };
            let fitted = |c_radius: f64, what: &str| -> Result<Material, Refusal> {
                let (ew, nw) = wall_modulus(e, nu, c_radius).ok_or_else(|| {
                    refuse(
                        "contact.poisson_ratio",
                        format!(
                            "no {what} material makes YADE's Mindlin stiffnesses equal the \
                             built-in engine's for this Poisson ratio"
                        ),
                    )
                })?;
                Ok(Material {
                    density: rho,
                    friction_angle: wall_friction_angle(l.pp_tangential.mu, l.pw_tangential.mu)?,
                    young: Some(ew),
                    poisson: Some(nw),
                    ..Default::default()
                })
            };
            (
                "mindlin",
                grain,
                // YADE's R*: r/2 against a Wall and against a Box.
                fitted(0.5f64.sqrt(), "wall")?,
                fitted(0.5f64.sqrt(), "tube")?,
                e_of(l.pp_normal.alpha, "contact.restitution")?,
                e_of(l.pw_normal.alpha, "contact.wall_restitution")?,
            )
        }
    };
    let mut caps = Vec::new();
    let mut tube = None;
    for w in &cfg.walls {
        match &w.shape {
            WallShape::Cylinder {
                point,
                axis,
                radius,
            } => {
                let a = axis_index(*axis).ok_or_else(|| {
                    refuse("tube.axis", "YADE's polygon tube is built along x, y or z")
                })?;
                let t = cfg.tube.expect("a cylinder wall comes from [tube]");
                let (s0, s1) = (t.origin[a], t.origin[a] + axis[a] * t.length);
                // Extend past open ends by a grain so grains leaving still feel the wall.
                let pad = 2.0 * cfg.radius_max;
                let (start, end) = (s0.min(s1) - pad, s0.max(s1) + pad);
                let n = TUBE_SEGMENTS as f64;
                tube = Some(Tube {
                    name: w.name.clone(),
                    axis: a,
                    centre: *point,
                    start,
                    end,
                    vertex_radius: 2.0 * radius / (1.0 + (std::f64::consts::PI / n).cos()),
                    segments: TUBE_SEGMENTS,
                    thickness: *radius,
                });
            }
            WallShape::Plane { point, normal } => {
                let a = axis_index(*normal).ok_or_else(|| {
                    refuse(
                        &format!("walls ({})", w.name),
                        "YADE's plane walls are normal to x, y or z",
                    )
                })?;
                caps.push(Cap {
                    name: w.name.clone(),
                    axis: a,
                    position: point[a],
                });
            }
        }
    }
    if cfg.inlet.is_some() && cfg.tube.is_none() {
        return Err(refuse("inlet", "an inlet needs a [tube]"));
    }
    Ok(Setup {
        dt: cfg.dt,
        gravity: cfg.gravity,
        skin: cfg.skin,
        rotation: cfg.rotation,
        law: law.into(),
        grain,
        cap,
        tube_wall,
        en_pp,
        en_pw,
        caps,
        tube,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fitted wall material reproduces the built-in engine's wall stiffnesses in
    /// YADE's formulas (checked by evaluating those formulas, not the solver's own).
    #[test]
    fn wall_modulus_reproduces_built_in_stiffness() {
        for (e, nu) in [(5e6, 0.45), (1e9, 0.3), (7e10, 0.2)] {
            for c in [0.5f64.sqrt(), (2.0f64 / 3.0).sqrt()] {
                let (ew, nw) = wall_modulus(e, nu, c).expect("solvable");
                let y = e / (2.0 * (1.0 - nu * nu));
                let estar = e * ew / ((1.0 - nu * nu) * ew + (1.0 - nw * nw) * e);
                assert!((estar * c / y - 1.0).abs() < 1e-9);
                let (g, gw) = (e / (2.0 * (1.0 + nu)), ew / (2.0 * (1.0 + nw)));
                let kt_yade = c * 0.5 * (g + gw) / (2.0 - 0.5 * (nu + nw));
                assert!((kt_yade / (g / (2.0 - nu)) - 1.0).abs() < 1e-9);
            }
        }
    }

    /// Two materials in series give the pair value back; twice the grain value is "absent".
    #[test]
    fn series_partner_gives_the_pair_value() {
        let w = series_partner(1.0, 1.5, "k").unwrap();
        assert!((1.0 / (1.0 / 2.0 + 1.0 / w) - 1.5).abs() < 1e-12);
        assert_eq!(series_partner(1.0, 2.0, "k").unwrap(), 0.0);
        assert!(series_partner(1.0, 2.5, "k").is_err());
    }
}
