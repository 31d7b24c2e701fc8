//! Drag laws: the force of the gas on one grain from the fields at its position. One file
//! per law behind [`DragLaw`]: `darcy` (the seeds' volume force, 000 and 002),
//! `ergun_wen_yu` (seed 004 eqs. 12–13, the Gidaspow switch) and `di_felice`; the last two
//! need a gas velocity, which the SIMPLE solver (src/gas/simple/) carries.
//!
//! Every law registers itself in [`DRAG_LAWS`] (one `ENTRY` in its own file, one line here):
//! the scene check, the gas and the coupler all read that table, so a new law is one file
//! and one line, and a name the table lacks is refused, never run as another law.

mod darcy;
mod di_felice;
pub mod ergun_wen_yu;

pub use darcy::DarcyVolumeForce;
pub use di_felice::DiFelice;
pub use ergun_wen_yu::ErgunWenYu;

use crate::{Real, Vec3};
use std::sync::Arc;

/// What a drag law is built from: the scene's gas and coupling settings.
#[derive(Debug, Clone, Copy)]
pub struct DragSettings {
    /// Gas viscosity μ, Pa·s.
    pub viscosity: Real,
    /// Seed 004's voidage factor C_V (eq. 11), for laws that take it; 1 when not given.
    pub voidage_factor: Real,
}

/// A drag law in the registry: its name in the scene, what it needs, how to build it.
pub struct DragLawEntry {
    /// `coupling.drag` as the scene writes it.
    pub name: &'static str,
    /// The law is a law of the slip u − v: only a gas that carries its velocity (`simple`)
    /// can feed it; the others (the d'Arcy volume force) pair with the d'Arcy gas.
    pub needs_gas_velocity: bool,
    /// The law takes seed 004's `coupling.voidage_factor`.
    pub takes_voidage_factor: bool,
    /// The law with the scene's settings; one instance serves the grains and the gas.
    pub build: fn(&DragSettings) -> Arc<dyn DragLaw>,
}

/// Every drag law a scene may name, in the order the messages list them.
pub static DRAG_LAWS: &[DragLawEntry] = &[darcy::ENTRY, ergun_wen_yu::ENTRY, di_felice::ENTRY];

/// The registered law called `name`.
pub fn drag_law(name: &str) -> Option<&'static DragLawEntry> {
    DRAG_LAWS.iter().find(|e| e.name == name)
}

/// The names of the registered laws that pass `keep`, joined by `sep`.
pub fn drag_law_names(keep: impl Fn(&DragLawEntry) -> bool, sep: &str) -> String {
    DRAG_LAWS
        .iter()
        .filter(|e| keep(e))
        .map(|e| e.name)
        .collect::<Vec<_>>()
        .join(sep)
}

/// What a drag law knows about a grain and the gas around it.
#[derive(Debug, Clone, Copy)]
pub struct GrainInFluid {
    /// Grain volume, m³.
    pub volume: Real,
    /// Grain diameter, m.
    pub diameter: Real,
    /// Grain velocity, m/s.
    pub velocity: Vec3,
    /// Porosity at the grain (eq. 9), clamped as the gas solver clamps it.
    pub porosity: Real,
    /// Pressure gradient at the grain, Pa/m.
    pub pressure_gradient: Vec3,
    /// Gas velocity at the grain, m/s (solvers that carry one).
    pub gas_velocity: Vec3,
    /// Gas density at the grain, kg/m³ (solvers that carry one; the d'Arcy law needs none).
    pub gas_density: Real,
    /// Gas vorticity ∇ × u at the grain, 1/s (zero unless a fluid force reads it).
    pub vorticity: Vec3,
}

impl GrainInFluid {
    /// Slip w = u − v of the gas past the grain, m/s, and its magnitude.
    pub fn slip(&self) -> (Vec3, Real) {
        let w = [
            self.gas_velocity[0] - self.velocity[0],
            self.gas_velocity[1] - self.velocity[1],
            self.gas_velocity[2] - self.velocity[2],
        ];
        (w, (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt())
    }
}

/// A grain of diameter `d` at rest at porosity `eps` in gas of density `rho` streaming at `w`
/// along x, no pressure gradient: the laws' tests' common case.
#[cfg(test)]
pub(crate) fn grain_at_rest_in_stream(d: Real, eps: Real, w: Real, rho: Real) -> GrainInFluid {
    GrainInFluid {
        volume: std::f64::consts::PI / 6.0 * d * d * d,
        diameter: d,
        velocity: [0.0; 3],
        porosity: eps,
        pressure_gradient: [0.0; 3],
        gas_velocity: [w, 0.0, 0.0],
        gas_density: rho,
        vorticity: [0.0; 3],
    }
}

/// A drag law.
pub trait DragLaw: Send + Sync {
    /// Name as the scene writes it.
    fn name(&self) -> &'static str;
    /// Force of the gas on the grain, N.
    fn force(&self, grain: &GrainInFluid) -> Vec3;
    /// For a law of the slip w = u − v: its coefficient β/(1 − ε), the drag per unit of slip
    /// and per volume of solid, kg/(m³ s), at `porosity` ε, slip speed |w| (m/s), grain
    /// `diameter` (m) and `gas_density` (kg/m³), so that the grain feels V_p β/(1 − ε) w.
    /// A gas that carries its own momentum (SIMPLE) takes −β w per volume of mixture from this
    /// same function, so what the grains gain the gas loses. None: not a law of the slip (the
    /// d'Arcy volume force).
    fn slip_coefficient(
        &self,
        porosity: Real,
        slip_speed: Real,
        diameter: Real,
        gas_density: Real,
    ) -> Option<Real> {
        let _ = (porosity, slip_speed, diameter, gas_density);
        None
    }
}

/// One law shared by the grains' side and a gas that carries its own momentum.
impl<L: DragLaw + ?Sized> DragLaw for std::sync::Arc<L> {
    fn name(&self) -> &'static str {
        (**self).name()
    }
    fn force(&self, grain: &GrainInFluid) -> Vec3 {
        (**self).force(grain)
    }
    fn slip_coefficient(&self, eps: Real, w: Real, d: Real, rho: Real) -> Option<Real> {
        (**self).slip_coefficient(eps, w, d, rho)
    }
}

/// The drag of a law of the slip on a grain: V_p β/(1 − ε) w. (The pressure gradient the
/// grain sits in, its share of the (1 − ε)∇p the gas momentum's −ε∇p leaves to the solids,
/// is the fluid force `pressure_gradient`, `crate::fluid_force`.) `coefficient`: the law's
/// [`DragLaw::slip_coefficient`].
pub(crate) fn slip_force(
    g: &GrainInFluid,
    coefficient: impl Fn(Real, Real, Real, Real) -> Real,
) -> Vec3 {
    let (w, speed) = g.slip();
    let s = g.volume * coefficient(g.porosity, speed, g.diameter, g.gas_density);
    [s * w[0], s * w[1], s * w[2]]
}
