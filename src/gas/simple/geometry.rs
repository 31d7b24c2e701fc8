//! The staggered grid of the SIMPLE gas: cells, faces, open volumes and areas (cut cells
//! where a tube's wall crosses them), wall conductances, and the stencils the momentum
//! equations read.

use super::*;

/// What the walls of a rectangular channel do to the gas.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wall {
    /// u = 0 at the wall.
    NoSlip,
    /// No shear at the wall (a symmetry plane).
    Slip,
}

/// Cell volumes, face areas and wall conductances of a staggered grid of `n[0] × n[1] × n[2]`
/// cells (cell (a, b, c) at index a + n0 (b + n1 c); the faces normal to d over the
/// counts n + e_d, indexed alike).
#[derive(Debug, Clone)]
pub struct Geometry {
    pub n: [usize; 3],
    /// Cell sizes, m.
    pub h: [Real; 3],
    /// Open volume of each cell, m³ (0: outside the flow).
    pub volume: Vec<Real>,
    /// Open area of each face normal to direction d, m².
    pub area: [Vec<Real>; 3],
    /// Distance between the nodes of the two cells beside each face normal to d, m (h_d
    /// but between cut cells, whose nodes sit at their open area's centroid).
    pub spacing: [Vec<Real>; 3],
    /// Walls inside each cell as velocity component d feels them: Σ wall area / distance
    /// from the cell's centre, m (the shear on the component is μ ε × this × its value).
    pub wall: [Vec<Real>; 3],
    /// The cross-section the superficial velocity refers to, m² (the tube's πR², of which
    /// the closed slivers are not open: the inlet's flux makes up for them).
    pub flow_area: Real,
    /// Second-order wall shear on the velocity along the flow (index: column b + n1 c;
    /// empty: none): the column one step towards the axis and the coefficients (m) of the
    /// correction to the first-order shear, μ ε (k_self u + k_partner u_partner), so the
    /// gradient at the wall is the slope of the parabola through the wall, the cell and its
    /// partner at their mean distances from the wall. (Deferred: lagged one iteration.)
    pub wall_partner: Vec<Option<(usize, Real, Real)>>,
    /// Periodic along the flow (direction 0): the last cell's downstream face is the first
    /// cell's upstream face. The faces at x₀ = n₀ carry the seam's velocity; those at
    /// x₀ = 0 are copies ([`Geometry::axial_face`] maps every reference to the former).
    pub periodic: bool,
}

pub(super) fn plus(x: [usize; 3], d: usize) -> [usize; 3] {
    let mut y = x;
    y[d] += 1;
    y
}

pub(super) fn minus(x: [usize; 3], d: usize) -> [usize; 3] {
    let mut y = x;
    y[d] -= 1;
    y
}

impl Geometry {
    /// A rectangular channel `length` long, `width` = [w1, w2] across, `cells` = [n0, n1,
    /// n2], its walls normal to directions 1 and 2 as `walls` say. The 2D channel of seed
    /// 004: n1 = 1, w1 = 1 m (per unit depth), walls [Slip, NoSlip].
    pub fn channel(length: Real, width: [Real; 2], cells: [usize; 3], walls: [Wall; 2]) -> Self {
        let n = cells;
        let h = [
            length / n[0] as Real,
            width[0] / n[1] as Real,
            width[1] / n[2] as Real,
        ];
        let cells_len = n[0] * n[1] * n[2];
        let faces = |d: usize| {
            let m = plus(n, d);
            let a = h[0] * h[1] * h[2] / h[d];
            vec![a; m[0] * m[1] * m[2]]
        };
        let mut wall = [
            vec![0.0; cells_len],
            vec![0.0; cells_len],
            vec![0.0; cells_len],
        ];
        for (t, kind) in [(1, walls[0]), (2, walls[1])] {
            if kind == Wall::Slip {
                continue;
            }
            // The wall at half a cell from the centres of the first and last rows in t, felt
            // by the components along it.
            let conductance = h[0] * h[1] * h[2] / h[t] / (0.5 * h[t]);
            for c in 0..n[2] {
                for b in 0..n[1] {
                    for a in 0..n[0] {
                        let x = [a, b, c];
                        let k = a + n[0] * (b + n[1] * c);
                        let walls_here = usize::from(x[t] == 0) + usize::from(x[t] + 1 == n[t]);
                        for (d, w) in wall.iter_mut().enumerate() {
                            if d != t {
                                w[k] += walls_here as Real * conductance;
                            }
                        }
                    }
                }
            }
        }
        Self {
            n,
            h,
            volume: vec![h[0] * h[1] * h[2]; cells_len],
            area: [faces(0), faces(1), faces(2)],
            spacing: std::array::from_fn(|d| vec![h[d]; faces(d).len()]),
            wall,
            flow_area: width[0] * width[1],
            wall_partner: Vec::new(),
            periodic: false,
        }
    }

    /// The 3D tube of `grid` (nz × nx × ny nodes): direction 0 the axis, 1 and 2 the grid's
    /// e1 and e2. Cells outside the tube, or cut by its wall to a sliver (the grid's closed
    /// columns), are closed; a sliver's wall goes to its open neighbour. Cut cells keep their
    /// open volume and face areas, and their nodes sit at their open area's centroid (the
    /// spacing between nodes across). The wall's conductance in each column: the arc inside
    /// it over the open area's mean distance from the wall, weighted for each component by
    /// how tangential the wall is to it, with a second-order correction for the velocity
    /// along the axis ([`Geometry::wall_partner`]). Sampled on 64 × 64 points per column and
    /// 20 000 on the arc. Hagen–Poiseuille: first order, −2.5 % at 16 × 16 cells.
    pub fn tube(grid: &TubeGrid) -> Self {
        let n = [grid.nz, grid.nx, grid.ny];
        let h = [grid.dz, grid.dx, grid.dy];
        let (nx, ny, r) = (grid.nx, grid.ny, grid.radius);
        let column = |i: usize, j: usize| i + nx * j;
        let open = |i: usize, j: usize| grid.open[column(i, j)];
        let (wall_distance, centroid) = column_samples(grid);
        let arc = wall_arcs(grid);
        let cells_len = n[0] * n[1] * n[2];
        let mut volume = vec![0.0; cells_len];
        let mut wall = [
            vec![0.0; cells_len],
            vec![0.0; cells_len],
            vec![0.0; cells_len],
        ];
        for k in 0..n[0] {
            for j in 0..ny {
                for i in 0..nx {
                    if !open(i, j) {
                        continue;
                    }
                    let cell = k + n[0] * (i + nx * j);
                    volume[cell] = grid.volume[grid.node(k, i, j)];
                    // At least a tenth of a cell: the conductance of a column the wall
                    // barely touches stays finite.
                    let dist = wall_distance[column(i, j)].max(0.1 * h[1].min(h[2]));
                    for (d, w) in wall.iter_mut().enumerate() {
                        w[cell] = arc[column(i, j)][d] * h[0] / dist;
                    }
                }
            }
        }
        let wall_partner = wall_partners(grid, &arc, &wall_distance);
        let mut area: [Vec<Real>; 3] = std::array::from_fn(|d| {
            let m = plus(n, d);
            vec![0.0; m[0] * m[1] * m[2]]
        });
        let mut spacing: [Vec<Real>; 3] = std::array::from_fn(|d| vec![h[d]; area[d].len()]);
        for j in 0..ny {
            for i in 0..nx {
                // Axial faces: the column's open cross-section (a prism along the axis).
                if open(i, j) {
                    for k in 0..=n[0] {
                        area[0][k + (n[0] + 1) * (i + nx * j)] = grid.face_z[column(i, j)];
                    }
                }
                // Faces between columns (i, j) | (i + 1, j) and (i, j) | (i, j + 1); the
                // nodes of cut cells sit at their centroids, nearer each other than a cell
                // (at least a quarter cell apart, so a sliver does not stiffen the sweep).
                for k in 0..n[0] {
                    if i + 1 < nx && open(i, j) && open(i + 1, j) {
                        let f = k + n[0] * ((i + 1) + (nx + 1) * j);
                        area[1][f] = grid.face_x[i + (nx - 1) * j];
                        spacing[1][f] = (centroid[column(i + 1, j)][0] - centroid[column(i, j)][0])
                            .max(0.25 * h[1]);
                    }
                    if j + 1 < ny && open(i, j) && open(i, j + 1) {
                        let f = k + n[0] * (i + nx * (j + 1));
                        area[2][f] = grid.face_y[i + nx * j];
                        spacing[2][f] = (centroid[column(i, j + 1)][1] - centroid[column(i, j)][1])
                            .max(0.25 * h[2]);
                    }
                }
            }
        }
        Self {
            n,
            h,
            volume,
            area,
            spacing,
            wall,
            flow_area: std::f64::consts::PI * r * r,
            wall_partner,
            periodic: grid.periodic,
        }
    }

    /// Number of cells.
    pub fn cells(&self) -> usize {
        self.n[0] * self.n[1] * self.n[2]
    }

    #[inline]
    pub(super) fn cell(&self, x: [usize; 3]) -> usize {
        x[0] + self.n[0] * (x[1] + self.n[1] * x[2])
    }

    /// Face counts of direction d: n + e_d.
    #[inline]
    pub(super) fn face_counts(&self, d: usize) -> [usize; 3] {
        plus(self.n, d)
    }

    /// Index of the face normal to d at face coordinates x.
    #[inline]
    pub(super) fn face(&self, d: usize, x: [usize; 3]) -> usize {
        let m = self.face_counts(d);
        x[0] + m[0] * (x[1] + m[1] * x[2])
    }

    /// The face normal to d at x as the momentum equations see it: on a periodic grid the
    /// axial faces at x₀ = 0 are the seam's faces at x₀ = n₀.
    #[inline]
    pub(super) fn axial_face(&self, d: usize, x: [usize; 3]) -> usize {
        if self.periodic && d == 0 && x[0] == 0 {
            self.face(0, [self.n[0], x[1], x[2]])
        } else {
            self.face(d, x)
        }
    }

    /// The cell one step downstream of x along d (periodic grids wrap along 0); None past
    /// the grid's end.
    #[inline]
    pub(super) fn cell_after(&self, x: [usize; 3], d: usize) -> Option<[usize; 3]> {
        if x[d] + 1 < self.n[d] {
            Some(plus(x, d))
        } else if self.periodic && d == 0 {
            Some([0, x[1], x[2]])
        } else {
            None
        }
    }

    /// The cell one step upstream of x along d (periodic grids wrap along 0).
    #[inline]
    pub(super) fn cell_before(&self, x: [usize; 3], d: usize) -> Option<[usize; 3]> {
        if x[d] > 0 {
            Some(minus(x, d))
        } else if self.periodic && d == 0 {
            Some([self.n[0] - 1, x[1], x[2]])
        } else {
            None
        }
    }

    /// Copy the seam's axial velocities (x₀ = n₀) onto their duplicates at x₀ = 0.
    pub(super) fn sync_seam(&self, axial: &mut [Real]) {
        if !self.periodic {
            return;
        }
        for x in Self::each([1, self.n[1], self.n[2]]) {
            axial[self.face(0, x)] = axial[self.face(0, [self.n[0], x[1], x[2]])];
        }
    }

    /// Faces normal to d.
    pub(super) fn faces(&self, d: usize) -> usize {
        let m = self.face_counts(d);
        m[0] * m[1] * m[2]
    }

    /// Every coordinate triple below `m`, in index order.
    pub(super) fn each(m: [usize; 3]) -> impl Iterator<Item = [usize; 3]> {
        (0..m[2]).flat_map(move |c| (0..m[1]).flat_map(move |b| (0..m[0]).map(move |a| [a, b, c])))
    }

    /// Open area of the inlet, m².
    pub(super) fn inlet_area(&self) -> Real {
        Self::each([1, self.n[1], self.n[2]])
            .map(|x| self.area[0][self.face(0, x)])
            .sum()
    }
}

/// One momentum equation of a face: a_P u_P = Σ a_nb u_nb + b (a_P relaxed).
#[derive(Debug, Clone, Copy)]
pub(super) struct Row {
    pub(super) face: usize,
    pub(super) inv_diag: Real,
    pub(super) b: Real,
    /// Neighbour faces (NONE: no neighbour) and their coefficients.
    pub(super) nb: [usize; 6],
    pub(super) a: [Real; 6],
}

/// Cell-centred fields on the faces (per direction, indexed as the faces).
pub(super) struct FaceFields {
    pub(super) porosity: [Vec<Real>; 3],
    pub(super) density: [Vec<Real>; 3],
}

/// What the momentum equation of one unknown face needs of the grid (built once).
#[derive(Debug, Clone)]
pub(super) struct FaceStencil {
    pub(super) face: usize,
    /// The cells beside the face: upstream along d, and downstream (NONE at the outlet).
    pub(super) lo: usize,
    pub(super) hi: usize,
    /// Control volume (half of each cell), m³; the face's open area, m²; the walls the
    /// control volume holds, Σ ½ W, m.
    pub(super) vol: Real,
    pub(super) area: Real,
    pub(super) wall: Real,
    /// Along d: the next faces downstream and upstream (NONE: none) and the cells'
    /// cross-sections V/h_d, m² (downstream, upstream).
    pub(super) next: [usize; 2],
    pub(super) section: [Real; 2],
    /// Across: the control volume's four sides.
    pub(super) sides: [SideStencil; 4],
    /// Deferred second-order wall shear: the partner face and the coefficients, m.
    pub(super) partner: Option<(usize, Real, Real)>,
}

/// A face stencil's face, the cells beside it (hi NONE at the outlet) and its open area, m².
#[derive(Debug, Clone, Copy)]
pub(super) struct FaceLink {
    pub(super) face: usize,
    pub(super) lo: usize,
    pub(super) hi: usize,
    pub(super) area: Real,
}

/// One side of a face's control volume, across direction t.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct SideStencil {
    pub(super) t: usize,
    /// The side towards +t.
    pub(super) up: bool,
    /// The faces normal to t of the cells beside (count of them: 1 or 2; 0: a side that
    /// does nothing, a boundary whose faces carry no flow and no shear).
    pub(super) faces: [usize; 2],
    pub(super) count: u8,
    /// Σ ½ open area, m², and the distance to the neighbouring node, m.
    pub(super) area: Real,
    pub(super) gap: Real,
    /// The neighbouring face of the same component (NONE: the inlet plane beyond).
    pub(super) neighbour: usize,
}

impl Geometry {
    /// The cells beside every face normal to d (upstream, downstream; NONE: none or closed).
    pub(super) fn face_cells(&self, d: usize) -> Vec<(usize, usize)> {
        Self::each(self.face_counts(d))
            .map(|x| {
                let open = |c: usize| if self.volume[c] > 0.0 { c } else { NONE };
                if self.periodic && d == 0 {
                    // The seam's faces join the last cell to the first; their duplicates at
                    // x₀ = 0 belong to no cell (counted once).
                    if x[0] == 0 {
                        return (NONE, NONE);
                    }
                    let hi = self.cell_after(minus(x, 0), 0).expect("periodic");
                    return (open(self.cell(minus(x, 0))), open(self.cell(hi)));
                }
                let lo = if x[d] > 0 {
                    open(self.cell(minus(x, d)))
                } else {
                    NONE
                };
                let hi = if x[d] < self.n[d] {
                    open(self.cell(x))
                } else {
                    NONE
                };
                (lo, hi)
            })
            .collect()
    }

    /// The momentum stencils of component d: its unknown faces (open faces inside the
    /// walls; along the flow, every open face past the inlet's), in sweep order.
    pub(super) fn stencils(&self, d: usize) -> Vec<FaceStencil> {
        let n = self.n;
        let mut out = Vec::new();
        for x in Self::each(self.face_counts(d)) {
            let inside = if d == 0 {
                x[0] >= 1
            } else {
                x[d] >= 1 && x[d] < n[d]
            };
            let f = self.face(d, x);
            if !inside || self.area[d][f] <= 0.0 {
                continue;
            }
            let lo = minus(x, d);
            let hi = self.cell_after(lo, d);
            let cells = [Some(lo), hi];
            let present = cells.iter().flatten().count();
            let vol = cells
                .iter()
                .flatten()
                .map(|&q| 0.5 * self.volume[self.cell(q)])
                .sum();
            let wall = cells
                .iter()
                .flatten()
                .map(|&q| 0.5 * self.wall[d][self.cell(q)])
                .sum();
            let mut sides = [SideStencil::default(); 4];
            let mut slot = 0;
            for t in (0..3).filter(|&t| t != d) {
                for up in [true, false] {
                    let mut side = SideStencil {
                        t,
                        up,
                        faces: [NONE; 2],
                        count: 0,
                        area: 0.0,
                        gap: 0.0,
                        neighbour: NONE,
                    };
                    for (k, &q) in cells.iter().flatten().enumerate() {
                        let sf = self.axial_face(t, if up { plus(q, t) } else { q });
                        side.faces[k] = sf;
                        side.area += 0.5 * self.area[t][sf];
                        side.gap += self.spacing[t][sf] / present as Real;
                    }
                    // (Across the periodic seam too: the neighbouring face of the same
                    // component is the wrapped one; d ≠ 0 there, so no axial duplicate.)
                    let beside = if up {
                        self.cell_after(x, t)
                    } else {
                        self.cell_before(x, t)
                    };
                    if let Some(y) = beside {
                        side.neighbour = self.face(d, y);
                        side.count = present as u8;
                    } else if t == 0 && !up {
                        side.count = present as u8;
                    }
                    sides[slot] = side;
                    slot += 1;
                }
            }
            let partner = if d == 0 {
                let column = x[1] + n[1] * x[2];
                self.wall_partner
                    .get(column)
                    .copied()
                    .flatten()
                    .map(|(p, ks, kp)| {
                        let share = if hi.is_some() { 1.0 } else { 0.5 };
                        (x[0] + (n[0] + 1) * p, share * ks, share * kp)
                    })
            } else {
                None
            };
            out.push(FaceStencil {
                face: f,
                lo: self.cell(lo),
                hi: hi.map_or(NONE, |q| self.cell(q)),
                vol,
                area: self.area[d][f],
                wall,
                next: [
                    hi.map_or(NONE, |q| self.axial_face(d, plus(q, d))),
                    self.axial_face(d, lo),
                ],
                section: [
                    hi.map_or(0.0, |q| self.volume[self.cell(q)] / self.h[d]),
                    self.volume[self.cell(lo)] / self.h[d],
                ],
                sides,
                partner,
            });
        }
        out
    }
}

/// Per column of a tube grid: the mean distance of its open area from the wall (a cell's
/// mean velocity near a no-slip wall is the wall's shear rate times it), and the centroid of
/// its open area (u, w), m (the gas's node in a cut cell). By sampling.
fn column_samples(grid: &TubeGrid) -> (Vec<Real>, Vec<[Real; 2]>) {
    let h = [grid.dz, grid.dx, grid.dy];
    let (nx, ny, r) = (grid.nx, grid.ny, grid.radius);
    let column = |i: usize, j: usize| i + nx * j;
    const S: usize = 64;
    let mut wall_distance = vec![0.0; nx * ny];
    // Centroid of each column's open area (u, w), m: the gas's node in a cut cell.
    let mut centroid = vec![[0.0; 2]; nx * ny];
    for j in 0..ny {
        for i in 0..nx {
            let (mut sum, mut su, mut sw, mut count) = (0.0, 0.0, 0.0, 0usize);
            for a in 0..S {
                for b in 0..S {
                    let u = -r + (i as Real + (a as Real + 0.5) / S as Real) * h[1];
                    let w = -r + (j as Real + (b as Real + 0.5) / S as Real) * h[2];
                    let rr = (u * u + w * w).sqrt();
                    if rr <= r {
                        sum += r - rr;
                        su += u;
                        sw += w;
                        count += 1;
                    }
                }
            }
            if count > 0 {
                let c = count as Real;
                wall_distance[column(i, j)] = sum / c;
                centroid[column(i, j)] = [su / c, sw / c];
            }
        }
    }
    (wall_distance, centroid)
}

/// Per column: the tube wall's arc in it, per component ∫ (1 − n_d²) dl (n the wall's
/// normal); an arc in a closed column goes to its open neighbour nearest the wall point's
/// column (the sliver's gas belongs to it).
fn wall_arcs(grid: &TubeGrid) -> Vec<[Real; 3]> {
    let h = [grid.dz, grid.dx, grid.dy];
    let (nx, ny, r) = (grid.nx, grid.ny, grid.radius);
    let column = |i: usize, j: usize| i + nx * j;
    let open = |i: usize, j: usize| grid.open[column(i, j)];
    const ARC: usize = 20_000;
    let mut arc = vec![[0.0; 3]; nx * ny];
    let dl = 2.0 * std::f64::consts::PI * r / ARC as Real;
    for k in 0..ARC {
        let theta = (k as Real + 0.5) / ARC as Real * 2.0 * std::f64::consts::PI;
        let (cu, sw) = (theta.cos(), theta.sin());
        let i = (((cu * r + r) / h[1]).floor().max(0.0) as usize).min(nx - 1);
        let j = (((sw * r + r) / h[2]).floor().max(0.0) as usize).min(ny - 1);
        let a = &mut arc[column(i, j)];
        a[0] += dl;
        a[1] += (1.0 - cu * cu) * dl;
        a[2] += (1.0 - sw * sw) * dl;
    }
    // An arc in a closed column goes to its open neighbour nearest the wall point's
    // column (the sliver's gas belongs to it).
    for j in 0..ny {
        for i in 0..nx {
            if open(i, j) || arc[column(i, j)][0] == 0.0 {
                continue;
            }
            let mut best: Option<(usize, Real)> = None;
            for jj in j.saturating_sub(1)..(j + 2).min(ny) {
                for ii in i.saturating_sub(1)..(i + 2).min(nx) {
                    if open(ii, jj) {
                        let dist = (ii as Real - i as Real).abs() + (jj as Real - j as Real).abs();
                        if best.is_none_or(|(_, d)| dist < d) {
                            best = Some((column(ii, jj), dist));
                        }
                    }
                }
            }
            if let Some((to, _)) = best {
                let moved = arc[column(i, j)];
                for d in 0..3 {
                    arc[to][d] += moved[d];
                }
            }
            arc[column(i, j)] = [0.0; 3];
        }
    }
    arc
}

/// Per open column at the wall: the column one step towards the axis and the coefficients
/// of the wall shear's parabola through the wall, the cell and that neighbour.
fn wall_partners(
    grid: &TubeGrid,
    arc: &[[Real; 3]],
    wall_distance: &[Real],
) -> Vec<Option<(usize, Real, Real)>> {
    let h = [grid.dz, grid.dx, grid.dy];
    let (nx, ny, r) = (grid.nx, grid.ny, grid.radius);
    let column = |i: usize, j: usize| i + nx * j;
    let open = |i: usize, j: usize| grid.open[column(i, j)];
    let mut wall_partner = vec![None; nx * ny];
    for j in 0..ny {
        for i in 0..nx {
            let arc0 = arc[column(i, j)][0];
            if !open(i, j) || arc0 == 0.0 {
                continue;
            }
            // One step towards the axis, along the direction the wall's normal leans to.
            let (cu, cw) = (-r + (i as Real + 0.5) * h[1], -r + (j as Real + 0.5) * h[2]);
            let (pi, pj) = if cu.abs() >= cw.abs() {
                (if cu > 0.0 { i.wrapping_sub(1) } else { i + 1 }, j)
            } else {
                (i, if cw > 0.0 { j.wrapping_sub(1) } else { j + 1 })
            };
            if pi >= nx || pj >= ny || !open(pi, pj) {
                continue;
            }
            let (dc, dn) = (
                wall_distance[column(i, j)].max(0.1 * h[1].min(h[2])),
                wall_distance[column(pi, pj)],
            );
            if dn - dc < 0.5 * h[1].min(h[2]) {
                continue;
            }
            // Parabola through (0, 0), (dc, u), (dn, u_n): slope at 0 = A u + B u_n.
            let a = dn / (dc * (dn - dc));
            let b = -dc / (dn * (dn - dc));
            let len = arc0 * h[0];
            wall_partner[column(i, j)] = Some((column(pi, pj), len * (a - 1.0 / dc), len * b));
        }
    }
    wall_partner
}
