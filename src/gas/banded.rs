//! Cholesky factorisation A = L Lᵀ of a symmetric positive definite band matrix (the
//! unblocked form of LAPACK's `dpbtrf`). The d'Arcy system of a tube grid couples a node
//! only to nodes at most one cross-section (nx·ny nodes) away in the axis-major numbering
//! of [`plugflow_coupling::TubeGrid::node`], so its half-bandwidth is the cross-section's
//! node count (4 for a 2 × 2 grid): the factorisation costs n b² flops in one pass over
//! contiguous rows, where the general sparse Cholesky spent most of a gas step walking its
//! elimination tree (`cargo bench`-free evidence: 13 % of the horizontal case's wall in
//! faer's numeric factorisation, measured by perf on 2026-12-03).

use crate::Real;

/// The lower band of a symmetric matrix, factorised in place.
#[derive(Debug, Clone)]
pub struct BandCholesky {
    n: usize,
    /// Half-bandwidth: entries (i, j) with i − b ≤ j ≤ i.
    b: usize,
    /// Row i holds columns i − b ..= i at `band[i * (b + 1) + (j + b − i)]` (the diagonal
    /// last); entries left of column 0 stay zero.
    band: Vec<Real>,
    /// 1 / L_ii: the substitutions multiply (a division's latency on every row of the
    /// two serial sweeps was most of a solve).
    inv_diag: Vec<Real>,
}

impl BandCholesky {
    /// An n × n matrix of half-bandwidth `b`, all zero.
    pub fn new(n: usize, b: usize) -> Self {
        Self {
            n,
            b,
            band: vec![0.0; n * (b + 1)],
            inv_diag: vec![0.0; n],
        }
    }

    /// Half-bandwidth.
    pub fn half_bandwidth(&self) -> usize {
        self.b
    }

    #[inline(always)]
    fn at(&self, i: usize, j: usize) -> usize {
        i * (self.b + 1) + (j + self.b - i)
    }

    /// Where entry (i, j) of the lower triangle sits in the band, for [`BandCholesky::set_at`]
    /// (a matrix whose pattern never changes looks its slots up once); entries outside the
    /// band are refused.
    pub fn slot(&self, i: usize, j: usize) -> Result<usize, String> {
        if j > i || i - j > self.b || i >= self.n {
            return Err(format!(
                "entry ({i}, {j}) outside the lower band of half-width {}",
                self.b
            ));
        }
        Ok(self.at(i, j))
    }

    /// Set the matrix from its lower triangle's values at the slots [`BandCholesky::slot`]
    /// gave (each slot at most once; the rest is zero).
    pub fn set_at(&mut self, slots: &[usize], values: &[Real]) {
        self.band.iter_mut().for_each(|v| *v = 0.0);
        for (&k, &v) in slots.iter().zip(values) {
            self.band[k] = v;
        }
    }

    /// Factorise in place; refused when a pivot is not positive (the matrix is not
    /// positive definite), naming the row.
    pub fn factor(&mut self) -> Result<(), String> {
        // The half-bandwidths of tube grids up to 4 × 4 nodes across.
        match self.b {
            1 => self.factor_fixed::<1>(),
            2 => self.factor_fixed::<2>(),
            3 => self.factor_fixed::<3>(),
            4 => self.factor_fixed::<4>(),
            6 => self.factor_fixed::<6>(),
            8 => self.factor_fixed::<8>(),
            9 => self.factor_fixed::<9>(),
            12 => self.factor_fixed::<12>(),
            16 => self.factor_fixed::<16>(),
            _ => self.factor_rows(0, self.n),
        }
    }

    /// [`BandCholesky::factor`] with the half-bandwidth a constant: the first B rows (which
    /// reach left of column 0) by the general loop, the rest with every index fixed at
    /// compile time. The same products summed in the same order: the same bits.
    fn factor_fixed<const B: usize>(&mut self) -> Result<(), String> {
        let n = self.n;
        self.factor_rows(0, n.min(B))?;
        let w = B + 1;
        for i in B..n {
            // Row i holds columns i − B + c at offset c; row j = i − B + c holds column
            // i − B + m at offset B − c + m.
            let (done, row) = self.band.split_at_mut(i * w);
            let row = &mut row[..w];
            for c in 0..B {
                let j = i - B + c;
                let row_j = &done[j * w..j * w + w];
                let mut s = row[c];
                for m in 0..c {
                    s -= row[m] * row_j[B - c + m];
                }
                row[c] = s * self.inv_diag[j];
            }
            let mut s = row[B];
            for m in 0..B {
                s -= row[m] * row[m];
            }
            if s.is_nan() || s <= 0.0 {
                return Err(Self::not_positive(s, i));
            }
            let d = s.sqrt();
            self.inv_diag[i] = 1.0 / d;
            row[B] = d;
        }
        Ok(())
    }

    fn not_positive(pivot: Real, row: usize) -> String {
        format!("band Cholesky: pivot {pivot:e} at row {row} (not positive definite)")
    }

    /// The general factorisation of rows `from..to` (rows before `from` done).
    fn factor_rows(&mut self, from: usize, to: usize) -> Result<(), String> {
        let b = self.b;
        for i in from..to {
            let first = i.saturating_sub(b);
            for j in first..=i {
                // A_ij − Σ_k L_ik L_jk over the columns both rows hold.
                let mut s = self.band[self.at(i, j)];
                for k in first.max(j.saturating_sub(b))..j {
                    s -= self.band[self.at(i, k)] * self.band[self.at(j, k)];
                }
                let v = if j == i {
                    if s.is_nan() || s <= 0.0 {
                        return Err(Self::not_positive(s, i));
                    }
                    let d = s.sqrt();
                    self.inv_diag[i] = 1.0 / d;
                    d
                } else {
                    s * self.inv_diag[j]
                };
                let k = self.at(i, j);
                self.band[k] = v;
            }
        }
        Ok(())
    }

    /// Solve L Lᵀ x = r in place (after [`BandCholesky::factor`]).
    pub fn solve_in_place(&self, x: &mut [Real]) {
        // (Already at the latency of its serial chain, one multiply–subtract and the
        // multiply by 1/L_ii per row: a fixed-width copy ran slower.)
        let (n, b) = (self.n, self.b);
        for i in 0..n {
            let mut s = x[i];
            for k in i.saturating_sub(b)..i {
                s -= self.band[self.at(i, k)] * x[k];
            }
            x[i] = s * self.inv_diag[i];
        }
        for i in (0..n).rev() {
            let mut s = x[i];
            for k in i + 1..n.min(i + b + 1) {
                s -= self.band[self.at(k, i)] * x[k];
            }
            x[i] = s * self.inv_diag[i];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A diffusion-like SPD band matrix (the d'Arcy system's shape: a dominant diagonal,
    /// negative couplings b and 1 apart): A x = r is solved to round-off, and a matrix that
    /// is not positive definite is refused.
    #[test]
    fn solves_a_band_system_and_refuses_an_indefinite_one() {
        let (n, b) = (40, 4);
        let mut entries = Vec::new();
        for i in 0..n {
            entries.push(((i, i), 10.0 + (i % 7) as Real));
            for d in [1, b] {
                if i >= d {
                    entries.push(((i, i - d), -1.0 - 0.1 * (i % 3) as Real));
                }
            }
        }
        let mut m = BandCholesky::new(n, b);
        let slots: Vec<usize> = entries
            .iter()
            .map(|&((i, j), _)| m.slot(i, j).unwrap())
            .collect();
        let values: Vec<Real> = entries.iter().map(|&(_, v)| v).collect();
        m.set_at(&slots, &values);
        m.factor().unwrap();
        let r: Vec<Real> = (0..n).map(|i| (i as Real * 0.37).sin()).collect();
        let mut x = r.clone();
        m.solve_in_place(&mut x);
        // The residual A x − r from the entries themselves (both triangles).
        let mut ax = vec![0.0; n];
        for &((i, j), v) in &entries {
            ax[i] += v * x[j];
            if i != j {
                ax[j] += v * x[i];
            }
        }
        for i in 0..n {
            assert!(
                (ax[i] - r[i]).abs() < 1e-14,
                "row {i}: {} vs {}",
                ax[i],
                r[i]
            );
        }
        let mut bad = BandCholesky::new(2, 1);
        let slots = [(0, 0), (1, 0), (1, 1)].map(|(i, j)| bad.slot(i, j).unwrap());
        bad.set_at(&slots, &[1.0, 2.0, 1.0]);
        assert!(bad.factor().unwrap_err().contains("row 1"));
        assert!(BandCholesky::new(3, 1).slot(2, 0).is_err());
    }

    /// The fixed-width factorisation is the general loop's arithmetic, bit for bit: the same
    /// band matrices (diffusion-like, couplings 1, 2 and b apart) factorised both ways, for
    /// every half-bandwidth a tube grid gives and one it does not.
    #[test]
    fn the_fixed_width_factor_is_the_general_one_bit_for_bit() {
        for b in [1, 2, 3, 4, 5, 6, 8, 9, 12, 16] {
            let n = 7 * b + 5;
            let mut fixed = BandCholesky::new(n, b);
            let (mut slots, mut values) = (Vec::new(), Vec::new());
            for i in 0..n {
                slots.push(fixed.slot(i, i).unwrap());
                values.push(4.0 * b as Real + (i as Real * 0.71).sin());
                let mut reach = vec![1, 2, b];
                reach.sort_unstable();
                reach.dedup();
                for d in reach {
                    if i >= d && d <= b {
                        slots.push(fixed.slot(i, i - d).unwrap());
                        values.push(-1.0 - 0.3 * ((i * d) as Real * 0.37).cos());
                    }
                }
            }
            fixed.set_at(&slots, &values);
            let mut general = fixed.clone();
            fixed.factor().unwrap();
            general.factor_rows(0, n).unwrap();
            let bits = |m: &BandCholesky| -> Vec<u64> {
                m.band
                    .iter()
                    .chain(&m.inv_diag)
                    .map(|v| v.to_bits())
                    .collect()
            };
            assert_eq!(bits(&fixed), bits(&general), "half-bandwidth {b}");
        }
    }
}
