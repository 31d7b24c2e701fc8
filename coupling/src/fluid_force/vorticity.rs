//! The gas vorticity ω = ∇ × u on the grid's nodes, for forces that read it (the
//! Saffman–Mei lift). Central differences along the axis and the two cross directions
//! (e1, e2), one-sided where a neighbour is missing or in a closed column (a wall sliver
//! carries no gas), zero along a direction of one node (a 2D grid has no gradient across
//! it); then ω = Σ_a e_a × ∂u/∂s_a over the grid's frame. Exact for a linear field.

use crate::grid::TubeGrid;
use crate::Vec3;

/// ∇ × u on every node of `grid` from the node velocities `u` (zero on closed nodes).
pub fn vorticity(grid: &TubeGrid, u: &[Vec3]) -> Vec<Vec3> {
    let (nz, nx, ny) = (grid.nz, grid.nx, grid.ny);
    let mut out = vec![[0.0; 3]; grid.len()];
    // ∂u/∂s along one direction at a node: (u[plus] − u[minus]) / (h × steps apart).
    let derivative = |minus: usize, plus: usize, span: f64| -> Vec3 {
        let (a, b) = (u[minus], u[plus]);
        [
            (b[0] - a[0]) / span,
            (b[1] - a[1]) / span,
            (b[2] - a[2]) / span,
        ]
    };
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let n = grid.node(k, i, j);
                if !grid.is_open(n) {
                    continue;
                }
                // Neighbours along a direction: the open ones of (index − 1, index + 1).
                let along = |lo: Option<usize>, hi: Option<usize>, h: f64| -> Vec3 {
                    let lo = lo.filter(|&m| grid.is_open(m));
                    let hi = hi.filter(|&m| grid.is_open(m));
                    match (lo, hi) {
                        (Some(a), Some(b)) => derivative(a, b, 2.0 * h),
                        (Some(a), None) => derivative(a, n, h),
                        (None, Some(b)) => derivative(n, b, h),
                        (None, None) => [0.0; 3],
                    }
                };
                let d_axis = along(
                    k.checked_sub(1).map(|k| grid.node(k, i, j)),
                    (k + 1 < nz).then(|| grid.node(k + 1, i, j)),
                    grid.dz,
                );
                let d_e1 = along(
                    i.checked_sub(1).map(|i| grid.node(k, i, j)),
                    (i + 1 < nx).then(|| grid.node(k, i + 1, j)),
                    grid.dx,
                );
                let d_e2 = along(
                    j.checked_sub(1).map(|j| grid.node(k, i, j)),
                    (j + 1 < ny).then(|| grid.node(k, i, j + 1)),
                    grid.dy,
                );
                let mut w = [0.0; 3];
                for (e, d) in [(grid.axis, d_axis), (grid.e1, d_e1), (grid.e2, d_e2)] {
                    w[0] += e[1] * d[2] - e[2] * d[1];
                    w[1] += e[2] * d[0] - e[0] * d[2];
                    w[2] += e[0] * d[1] - e[1] * d[0];
                }
                out[n] = w;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Node centre in global coordinates.
    fn centre(g: &TubeGrid, k: usize, i: usize, j: usize) -> Vec3 {
        let s = (k as f64 + 0.5) * g.dz;
        let a = -g.radius + (i as f64 + 0.5) * g.dx;
        let b = -g.radius + (j as f64 + 0.5) * g.dy;
        std::array::from_fn(|c| g.origin[c] + s * g.axis[c] + a * g.e1[c] + b * g.e2[c])
    }

    #[test]
    fn a_linear_field_has_its_exact_curl_on_every_open_node() {
        // u = A x + c with a general A: its curl is (A32 − A23, A13 − A31, A21 − A12), the
        // same everywhere; central and one-sided differences are exact for it (to rounding).
        let g = TubeGrid::new([0.1, -0.2, 0.3], [0.0, 0.6, 0.8], 0.01, 0.05, 10, 6, 6);
        let a = [[0.3, -1.2, 2.0], [0.7, 0.1, -0.4], [-1.5, 2.5, 0.2]];
        let u: Vec<Vec3> = (0..g.len())
            .map(|n| {
                let (k, rest) = (n / (g.nx * g.ny), n % (g.nx * g.ny));
                let (j, i) = (rest / g.nx, rest % g.nx);
                let x = centre(&g, k, i, j);
                std::array::from_fn(|r| 1.0 + (0..3).map(|c| a[r][c] * x[c]).sum::<f64>())
            })
            .collect();
        let curl = [a[2][1] - a[1][2], a[0][2] - a[2][0], a[1][0] - a[0][1]];
        let w = vorticity(&g, &u);
        let mut open = 0;
        for (n, w) in w.iter().enumerate() {
            if !g.is_open(n) {
                assert_eq!(*w, [0.0; 3]);
                continue;
            }
            open += 1;
            for c in 0..3 {
                assert!((w[c] - curl[c]).abs() < 1e-9, "node {n}: {w:?} vs {curl:?}");
            }
        }
        assert!(open > g.nz * 20, "{open} open nodes");
    }
}
