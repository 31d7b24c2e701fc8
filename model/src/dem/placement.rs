//! Placing grains without overlap: random sequential addition inside a stretch of the tube
//! (or a box). Used by the mass-flow inlet (one slab per batch) and the initial fill.
//!
//! Random sequential addition saturates near 38 % solids in bulk (less against walls), so a
//! request denser than that places fewer grains; callers see how many were placed.

use super::vec3::{add, dot, norm2, scale, sub};
use crate::rng::Rng;
use crate::{Real, Vec3};
use std::collections::HashMap;

/// Where grains may go: the part of a tube between two axial positions, or a box.
#[derive(Debug, Clone)]
pub enum Region {
    /// Tube stretch s ∈ [from, to] along `axis` from `origin`, inner radius `radius`
    /// (within |u| ≤ `slab_half` along the first cross direction, for a quasi-2D slab).
    TubeStretch {
        origin: Vec3,
        axis: Vec3,
        radius: Real,
        slab_half: Option<Real>,
        from: Real,
        to: Real,
    },
    /// Axis-aligned box.
    Box { lo: Vec3, hi: Vec3 },
    /// A shaped fill of a tube of `length`: a plug over s ∈ [from, to] whose end faces lean
    /// at `end_angle` to the axis (the plug is shorter by h cot θ at each end at height h
    /// above the tube's lowest line), and/or a resting layer of `layer` height along the
    /// whole tube; heights measured along `up` (against gravity, across the axis).
    TubeShape {
        origin: Vec3,
        axis: Vec3,
        radius: Real,
        slab_half: Option<Real>,
        length: Real,
        up: Vec3,
        /// (from, to, cot θ) of the plug, m, m, 1.
        plug: Option<(Real, Real, Real)>,
        /// Layer height, m.
        layer: Option<Real>,
    },
}

/// Two unit vectors perpendicular to `axis` and to each other (the gas grid's frame: the
/// slab's walls and the grid's first cross direction must agree).
pub use plugflow_coupling::grid::perpendicular_basis;

impl Region {
    /// A uniformly random centre for a grain of radius `r` that keeps it inside.
    fn sample(&self, r: Real, rng: &mut Rng) -> Option<Vec3> {
        match self {
            Region::TubeStretch {
                origin,
                axis,
                radius,
                slab_half,
                from,
                to,
            } => {
                let rr = radius - r;
                let ru = slab_half.map_or(rr, |h| (h - r).min(rr));
                if rr <= 0.0 || ru < 0.0 || to - from < 2.0 * r {
                    return None;
                }
                let (e1, e2) = perpendicular_basis(*axis);
                let (u, v) = loop {
                    let u = rng.range(-ru, ru);
                    let v = rng.range(-rr, rr);
                    if u * u + v * v <= rr * rr {
                        break (u, v);
                    }
                };
                let s = rng.range(from + r, to - r);
                Some(add(
                    add(add(*origin, scale(*axis, s)), scale(e1, u)),
                    scale(e2, v),
                ))
            }
            Region::TubeShape {
                origin,
                axis,
                radius,
                slab_half,
                length,
                up,
                plug,
                layer,
            } => {
                // Uniform over the tube, kept where the grain lies wholly in the plug or
                // the layer (rejection: the shape is a good share of the tube in practice).
                let whole = Region::TubeStretch {
                    origin: *origin,
                    axis: *axis,
                    radius: *radius,
                    slab_half: *slab_half,
                    from: 0.0,
                    to: *length,
                };
                for _ in 0..10_000 {
                    let x = whole.sample(r, rng)?;
                    let rel = sub(x, *origin);
                    let s = dot(rel, *axis);
                    // Height of the centre above the tube's lowest line.
                    let h = radius + dot(rel, *up);
                    let in_layer = layer.is_some_and(|top| h + r <= top);
                    let in_plug = plug.is_some_and(|(from, to, cot)| {
                        // The faces lean in towards the top: at height H the plug spans
                        // [from + H cot θ, to − H cot θ]; the grain is held to the span at
                        // its top (h + r), the narrowest it reaches.
                        let lean = (h + r) * cot;
                        s - r >= from + lean && s + r <= to - lean
                    });
                    if in_layer || in_plug {
                        return Some(x);
                    }
                }
                None
            }
            Region::Box { lo, hi } => {
                let mut x = [0.0; 3];
                for k in 0..3 {
                    if hi[k] - lo[k] < 2.0 * r {
                        return None;
                    }
                    x[k] = rng.range(lo[k] + r, hi[k] - r);
                }
                Some(x)
            }
        }
    }
}

/// Place up to `radii.len()` grains (radii in order) in `region` without overlapping each
/// other or the `existing` grains (centre, radius). Gives up on a grain after `attempts`
/// misses in a row and returns the centres placed so far.
pub fn place(
    region: &Region,
    radii: &[Real],
    existing: &[(Vec3, Real)],
    rng: &mut Rng,
    attempts: usize,
) -> Vec<Vec3> {
    let rmax = radii
        .iter()
        .chain(existing.iter().map(|e| &e.1))
        .fold(0.0_f64, |a, &b| a.max(b));
    if rmax <= 0.0 {
        return Vec::new();
    }
    let cell = 2.0 * rmax;
    let key = |x: Vec3| -> (i64, i64, i64) {
        (
            (x[0] / cell).floor() as i64,
            (x[1] / cell).floor() as i64,
            (x[2] / cell).floor() as i64,
        )
    };
    let mut grid: HashMap<(i64, i64, i64), Vec<(Vec3, Real)>> = HashMap::new();
    for &(x, r) in existing {
        grid.entry(key(x)).or_default().push((x, r));
    }
    let mut placed = Vec::with_capacity(radii.len());
    for &r in radii {
        let mut done = false;
        for _ in 0..attempts {
            let Some(x) = region.sample(r, rng) else {
                return placed;
            };
            let (cx, cy, cz) = key(x);
            let mut free = true;
            'search: for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        if let Some(list) = grid.get(&(cx + dx, cy + dy, cz + dz)) {
                            for &(y, ry) in list {
                                let reach = r + ry;
                                if norm2(sub(x, y)) < reach * reach {
                                    free = false;
                                    break 'search;
                                }
                            }
                        }
                    }
                }
            }
            if free {
                grid.entry((cx, cy, cz)).or_default().push((x, r));
                placed.push(x);
                done = true;
                break;
            }
        }
        if !done {
            break;
        }
    }
    placed
}
