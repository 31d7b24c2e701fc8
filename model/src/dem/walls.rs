//! Walls: planes (end caps, user planes) and the inner surface of a cylinder of any axis.
//! A wall acts on a grain like a partner of infinite mass and radius with the grain law's
//! material, so the grain–grain laws serve unchanged (m* = m, r* = r).

use super::vec3::{dot, norm2, scale, sub};
use crate::{Real, Vec3};

/// Wall geometry.
#[derive(Debug, Clone)]
pub enum WallShape {
    /// Grains live on the side `normal` (unit) points to.
    Plane { point: Vec3, normal: Vec3 },
    /// Grains live inside the cylinder through `point` along unit `axis`.
    Cylinder {
        point: Vec3,
        axis: Vec3,
        radius: Real,
    },
}

/// A named wall.
#[derive(Debug, Clone)]
pub struct Wall {
    /// Name in wall-force reports.
    pub name: String,
    /// Geometry.
    pub shape: WallShape,
    /// Friction coefficient of this wall when it differs from the grain–wall law's
    /// (the quasi-2D slab's planes stand in for the missing third dimension).
    pub friction: Option<Real>,
}

impl Wall {
    /// Overlap δ and unit normal from the grain centre towards the wall, when touching.
    #[inline(always)]
    pub fn contact(&self, x: Vec3, r: Real) -> Option<(Real, Vec3)> {
        match &self.shape {
            WallShape::Plane { point, normal } => {
                let dist = dot(sub(x, *point), *normal);
                let overlap = r - dist;
                (overlap > 0.0).then(|| (overlap, scale(*normal, -1.0)))
            }
            WallShape::Cylinder {
                point,
                axis,
                radius,
            } => {
                let rel = sub(x, *point);
                let radial = sub(rel, scale(*axis, dot(rel, *axis)));
                // Most grains are clear of the wall: decide on squares before the root.
                let reach = radius - r;
                let rho2 = norm2(radial);
                if reach > 0.0 && rho2 <= reach * reach {
                    return None;
                }
                let rho = rho2.sqrt();
                let overlap = r + rho - radius;
                if overlap > 0.0 && rho > 0.0 {
                    Some((overlap, scale(radial, 1.0 / rho)))
                } else {
                    None
                }
            }
        }
    }
}
