//! The pressure-correction system A p' = b of one SIMPLE iteration, solved by conjugate
//! gradients preconditioned with the sparse Cholesky factor of an earlier iteration of the
//! same time step.
//!
//! Why: within a time step the matrix changes only through the momentum diagonals a_P
//! (A's couplings are ρ ε² A² α/a_P, a_P dominated by ρεV/Δt and the drag βV, both nearly
//! fixed over the step), so the step's first factorisation is an almost exact inverse of
//! every later matrix: CG converges in a few iterations, each a pair of triangular solves,
//! a tenth of a factorisation. It is refactorised when CG slows (the matrix moved), and at
//! every step's start, so a step's arithmetic depends only on the state the step starts
//! from (a resumed run repeats an uninterrupted one to the bit).

use super::*;
use faer::MatMut;

/// CG stops when ‖r‖₂ ≤ this × ‖b‖₂: the correction then leaves a millionth of the
/// imbalance it corrects, and the SIMPLE iteration converges as with the exact p'
/// (`gas_bench`, measured with the flow controller of before session 22: the same 16.4
/// SIMPLE iterations per step at 1e-4, 1e-6, 1e-8, 1e-12 and with the direct solve of every
/// iteration).
const CG_RELATIVE_RESIDUAL: Real = 1e-6;
/// Nor need CG go below this share of the SIMPLE iteration's own tolerance on the
/// imbalance (late iterations correct imbalances near it): what is left is a thousandth of
/// what the iteration accepts.
pub(super) const CG_FLOOR_OF_TOLERANCE: Real = 1e-3;
/// CG iterations after which the preconditioner counts as stale: the matrix is factorised
/// anew and solved directly.
const CG_REFACTORISE_AFTER: usize = 12;

/// Working storage of the pressure correction: rebuilt within every time step, never part
/// of the gas's state.
#[derive(Clone, Default)]
pub(super) struct PressureSystem {
    /// The cells (lo, hi) joined by each interior face, stencils' order (built once).
    pairs: Vec<(usize, usize)>,
    /// Each joined face's coefficient a_f (the matrix holds −a_f), this iteration.
    pub(super) coupling: Vec<Real>,
    /// The diagonal and the right-hand side (mass imbalance, kg/s), this iteration.
    pub(super) diag: Vec<Real>,
    pub(super) rhs: Vec<Real>,
    /// The matrix's values in the order of the factorisation's pattern (off-diagonals,
    /// then the diagonal).
    values: Vec<Real>,
    /// The factorisation in use (None at a step's start).
    llt: Option<Llt<usize, Real>>,
    /// The solution p', Pa.
    pub(super) solution: Vec<Real>,
    /// CG's residual, preconditioned residual, search direction and A × direction.
    residual: Vec<Real>,
    preconditioned: Vec<Real>,
    direction: Vec<Real>,
    product: Vec<Real>,
    /// A residual ‖r‖₂ that is small enough whatever ‖b‖, kg/s (0: none).
    pub(super) residual_floor: Real,
    /// Factorisations and CG iterations so far (for tests and the bench).
    pub(super) factorisations: usize,
    pub(super) cg_iterations: usize,
}

impl PressureSystem {
    /// Forget the factorisation: the next solve factorises (a step's start).
    pub(super) fn new_step(&mut self) {
        self.llt = None;
    }

    /// Zeroed diagonal, right-hand side and couplings for `cells` cells and the interior
    /// faces among `links` (their pairs recorded on the first call).
    pub(super) fn reset(&mut self, cells: usize, links: &[Vec<FaceLink>; 3]) {
        if self.pairs.is_empty() {
            self.pairs = links
                .iter()
                .flatten()
                .filter(|l| l.hi != NONE)
                .map(|l| (l.lo, l.hi))
                .collect();
        }
        self.diag.clear();
        self.diag.resize(cells, 0.0);
        self.rhs.clear();
        self.rhs.resize(cells, 0.0);
        self.coupling.clear();
    }

    /// A × x into `out`.
    fn multiply(&self, x: &[Real], out: &mut [Real]) {
        for ((o, d), x) in out.iter_mut().zip(&self.diag).zip(x) {
            *o = d * x;
        }
        for (&(lo, hi), &a) in self.pairs.iter().zip(&self.coupling) {
            out[lo] -= a * x[hi];
            out[hi] -= a * x[lo];
        }
    }

    /// Factorise the present matrix (the pattern and symbolic factorisation kept in
    /// `pattern`, `symbolic`: built on the first call).
    fn factorise(
        &mut self,
        pattern: &mut Option<(SymbolicSparseColMat<usize>, Argsort<usize>)>,
        symbolic: &mut Option<SymbolicLlt<usize>>,
    ) -> Result<(), String> {
        let cells = self.diag.len();
        if pattern.is_none() {
            // Entries (row, column) of the lower triangle in the order `values` fills.
            let pairs: Vec<Pair<usize, usize>> = self
                .pairs
                .iter()
                .map(|&(lo, hi)| Pair {
                    row: hi.max(lo),
                    col: hi.min(lo),
                })
                .chain((0..cells).map(|k| Pair { row: k, col: k }))
                .collect();
            *pattern = Some(
                SymbolicSparseColMat::try_new_from_indices(cells, cells, &pairs)
                    .map_err(|e| format!("pressure-correction pattern: {e:?}"))?,
            );
        }
        self.values.clear();
        self.values.extend(self.coupling.iter().map(|a| -a));
        self.values.extend_from_slice(&self.diag);
        let (pattern, order) = pattern.as_ref().expect("just built");
        let mat =
            SparseColMat::<usize, Real>::new_from_argsort(pattern.clone(), order, &self.values)
                .map_err(|e| format!("pressure-correction assembly: {e:?}"))?;
        if symbolic.is_none() {
            *symbolic = Some(
                SymbolicLlt::try_new(mat.symbolic(), Side::Lower)
                    .map_err(|e| format!("symbolic factorisation: {e:?}"))?,
            );
        }
        self.llt = Some(
            Llt::try_new_with_symbolic(
                symbolic.clone().expect("just built"),
                mat.as_ref(),
                Side::Lower,
            )
            .map_err(|e| format!("pressure-correction factorisation: {e:?}"))?,
        );
        self.factorisations += 1;
        Ok(())
    }

    /// z = M⁻¹ r with the factorisation in use.
    fn precondition(llt: &Llt<usize, Real>, r: &[Real], z: &mut [Real]) {
        z.copy_from_slice(r);
        let n = z.len();
        llt.solve_in_place(MatMut::from_column_major_slice_mut(z, n, 1));
    }

    /// Solve A p' = b into `solution`: directly after a fresh factorisation, by CG on the
    /// one in use otherwise (refactorising when it has gone stale).
    pub(super) fn solve(
        &mut self,
        pattern: &mut Option<(SymbolicSparseColMat<usize>, Argsort<usize>)>,
        symbolic: &mut Option<SymbolicLlt<usize>>,
    ) -> Result<(), String> {
        let n = self.diag.len();
        self.solution.clear();
        self.solution.resize(n, 0.0);
        if self.llt.is_some() && self.conjugate_gradients() {
            return Ok(());
        }
        self.factorise(pattern, symbolic)?;
        let llt = self.llt.as_ref().expect("just factorised");
        Self::precondition(llt, &self.rhs, &mut self.solution);
        Ok(())
    }

    /// Preconditioned CG from p' = 0; true when it met its tolerance within
    /// [`CG_REFACTORISE_AFTER`] iterations (`solution` then holds p').
    fn conjugate_gradients(&mut self) -> bool {
        let n = self.diag.len();
        let dot = |a: &[Real], b: &[Real]| a.iter().zip(b).map(|(x, y)| x * y).sum::<Real>();
        for v in [
            &mut self.residual,
            &mut self.preconditioned,
            &mut self.direction,
            &mut self.product,
        ] {
            v.clear();
            v.resize(n, 0.0);
        }
        self.residual.copy_from_slice(&self.rhs);
        let norm_b = dot(&self.rhs, &self.rhs).sqrt();
        let target = (CG_RELATIVE_RESIDUAL * norm_b).max(self.residual_floor);
        if target == 0.0 || norm_b <= target {
            return true; // b small enough: p' = 0
        }
        let llt = self.llt.take().expect("checked by the caller");
        Self::precondition(&llt, &self.residual, &mut self.preconditioned);
        self.direction.copy_from_slice(&self.preconditioned);
        let mut rz = dot(&self.residual, &self.preconditioned);
        let mut converged = false;
        for _ in 0..CG_REFACTORISE_AFTER {
            self.cg_iterations += 1;
            let mut product = std::mem::take(&mut self.product);
            self.multiply(&self.direction, &mut product);
            self.product = product;
            let curvature = dot(&self.direction, &self.product);
            if curvature.is_nan() || curvature <= 0.0 {
                break; // not positive definite in finite precision: factorise instead
            }
            let step = rz / curvature;
            for k in 0..n {
                self.solution[k] += step * self.direction[k];
                self.residual[k] -= step * self.product[k];
            }
            if dot(&self.residual, &self.residual).sqrt() <= target {
                converged = true;
                break;
            }
            Self::precondition(&llt, &self.residual, &mut self.preconditioned);
            let rz_next = dot(&self.residual, &self.preconditioned);
            let beta = rz_next / rz;
            rz = rz_next;
            for k in 0..n {
                self.direction[k] = self.preconditioned[k] + beta * self.direction[k];
            }
        }
        self.llt = Some(llt);
        converged
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A chain of `n` cells (faces between neighbours) with couplings `a(k)` and a diagonal
    /// Σ a + `own`: symmetric positive definite, as the pressure correction of a transient
    /// step (its ∂ρ/∂p or pinned cell makes `own` > 0 somewhere).
    fn chain(sys: &mut PressureSystem, n: usize, a: impl Fn(usize) -> Real, own: Real) {
        sys.pairs = (0..n - 1).map(|k| (k, k + 1)).collect();
        sys.coupling = (0..n - 1).map(&a).collect();
        sys.diag = vec![own; n];
        for k in 0..n - 1 {
            sys.diag[k] += a(k);
            sys.diag[k + 1] += a(k);
        }
        sys.rhs = (0..n).map(|k| ((k * 7 % 5) as Real - 2.0) * 1e-3).collect();
    }

    /// The solve after a fresh factorisation is exact; a later matrix of the same step
    /// (couplings changed by up to 20 %) is solved by CG on the stale factor to the
    /// tolerance, with no new factorisation: A p' = b holds to ‖r‖ ≤ tol ‖b‖.
    #[test]
    fn stale_factor_preconditions_the_next_matrix_to_its_tolerance() {
        let (mut pattern, mut symbolic) = (None, None);
        let mut sys = PressureSystem::default();
        let n = 200;
        chain(&mut sys, n, |k| 1.0 + (k % 3) as Real, 0.05);
        sys.solve(&mut pattern, &mut symbolic).unwrap();
        let residual = |sys: &PressureSystem| {
            let mut ax = vec![0.0; n];
            sys.multiply(&sys.solution, &mut ax);
            let r: Real = ax.iter().zip(&sys.rhs).map(|(x, b)| (x - b).powi(2)).sum();
            let b: Real = sys.rhs.iter().map(|b| b * b).sum();
            (r / b).sqrt()
        };
        assert!(residual(&sys) < 1e-12, "direct: {:e}", residual(&sys));
        assert_eq!((sys.factorisations, sys.cg_iterations), (1, 0));
        chain(
            &mut sys,
            n,
            |k| (1.0 + (k % 3) as Real) * (1.0 + 0.2 * ((k % 11) as Real / 10.0)),
            0.05,
        );
        sys.solve(&mut pattern, &mut symbolic).unwrap();
        assert_eq!(sys.factorisations, 1, "refactorised");
        assert!(sys.cg_iterations > 0 && sys.cg_iterations <= CG_REFACTORISE_AFTER);
        assert!(
            residual(&sys) <= CG_RELATIVE_RESIDUAL,
            "CG: {:e}",
            residual(&sys)
        );
    }

    /// A matrix far from the factor (couplings spread over six decades) is refactorised
    /// rather than left unconverged, and solved exactly.
    #[test]
    fn a_stale_factor_far_off_is_replaced() {
        let (mut pattern, mut symbolic) = (None, None);
        let mut sys = PressureSystem::default();
        let n = 400;
        chain(&mut sys, n, |_| 1.0, 1e-2);
        sys.solve(&mut pattern, &mut symbolic).unwrap();
        chain(
            &mut sys,
            n,
            |k| (10.0 as Real).powf(3.0 * (0.7 * k as Real).sin()),
            1e-2,
        );
        sys.solve(&mut pattern, &mut symbolic).unwrap();
        let mut ax = vec![0.0; n];
        sys.multiply(&sys.solution, &mut ax);
        let r: Real = ax.iter().zip(&sys.rhs).map(|(x, b)| (x - b).powi(2)).sum();
        let b: Real = sys.rhs.iter().map(|b| b * b).sum();
        assert_eq!(
            (sys.factorisations, sys.cg_iterations),
            (2, CG_REFACTORISE_AFTER),
            "CG did not give up on the stale factor"
        );
        assert!((r / b).sqrt() < 1e-12, "{:e}", (r / b).sqrt());
    }
}
