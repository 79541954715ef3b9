//! Small dense linear algebra for least-squares fits: symmetric normal
//! matrices (row-major `Vec<f64>`), their Cholesky solve, and the pivoted
//! Cholesky that picks a set of linearly independent columns.
//!
//! The fits here (a robot's base inertial parameters and joint friction)
//! have at most a few hundred unknowns and are solved once per recording;
//! these two routines are all they need, so no linear-algebra crate is
//! pulled in for them.

/// Why a linear system could not be solved.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LinalgError {
    /// The matrix is not square of the right size.
    #[error("a {rows}×{rows} system was given {values} values")]
    Shape {
        /// Unknowns.
        rows: usize,
        /// Values given for the matrix.
        values: usize,
    },
    /// A pivot is not positive: the matrix is not positive definite.
    #[error("the normal matrix is not positive definite (pivot {pivot} is {value})")]
    NotPositiveDefinite {
        /// Which pivot.
        pivot: usize,
        /// Its value.
        value: f64,
    },
}

/// Solves `A x = b` for a symmetric positive definite `A` (`n × n`, row-major).
pub fn solve_spd(a: &[f64], b: &[f64]) -> Result<Vec<f64>, LinalgError> {
    let n = b.len();
    if a.len() != n * n {
        return Err(LinalgError::Shape {
            rows: n,
            values: a.len(),
        });
    }
    // Lower factor L with A = L Lᵀ.
    let mut l = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..=i {
            let mut sum = a[i * n + j];
            for k in 0..j {
                sum -= l[i * n + k] * l[j * n + k];
            }
            if i == j {
                if sum <= 0.0 || !sum.is_finite() {
                    return Err(LinalgError::NotPositiveDefinite { pivot: i, value: sum });
                }
                l[i * n + i] = sum.sqrt();
            } else {
                l[i * n + j] = sum / l[j * n + j];
            }
        }
    }
    let mut y = vec![0.0; n];
    for i in 0..n {
        let sum: f64 = (0..i).map(|k| l[i * n + k] * y[k]).sum();
        y[i] = (b[i] - sum) / l[i * n + i];
    }
    let mut x = vec![0.0; n];
    for i in (0..n).rev() {
        let sum: f64 = (i + 1..n).map(|k| l[k * n + i] * x[k]).sum();
        x[i] = (y[i] - sum) / l[i * n + i];
    }
    Ok(x)
}

/// The columns of a Gram matrix `G = Aᵀ A` (`n × n`, row-major) that are
/// linearly independent, chosen greedily by the largest remaining pivot
/// (a pivoted Cholesky): a column whose remaining pivot is below
/// `relative_tolerance` times its own diagonal entry is a combination of
/// those already chosen. Sorted.
#[must_use]
pub fn independent_columns(gram: &[f64], n: usize, relative_tolerance: f64) -> Vec<usize> {
    if gram.len() != n * n {
        return Vec::new();
    }
    let diagonal: Vec<f64> = (0..n).map(|i| gram[i * n + i]).collect();
    let scale = diagonal.iter().fold(0.0_f64, |m, &d| m.max(d));
    if scale <= 0.0 || !scale.is_finite() {
        return Vec::new();
    }
    let mut remaining = diagonal.clone();
    let mut chosen: Vec<usize> = Vec::new();
    // Rows of the factor for the chosen pivots, over every column.
    let mut factor: Vec<Vec<f64>> = Vec::new();
    loop {
        let best = (0..n)
            .filter(|c| !chosen.contains(c))
            .filter(|&c| remaining[c] > relative_tolerance * diagonal[c] && remaining[c] > 1e-14 * scale)
            .max_by(|&a, &b| (remaining[a] / diagonal[a]).total_cmp(&(remaining[b] / diagonal[b])));
        let Some(p) = best else { break };
        let pivot = remaining[p].sqrt();
        let row: Vec<f64> = (0..n)
            .map(|c| {
                let earlier: f64 = factor.iter().map(|f| f[p] * f[c]).sum();
                (gram[p * n + c] - earlier) / pivot
            })
            .collect();
        for c in 0..n {
            remaining[c] -= row[c] * row[c];
        }
        factor.push(row);
        chosen.push(p);
    }
    chosen.sort_unstable();
    chosen
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_positive_definite_system_is_solved() {
        let a = [4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0];
        let x_true = [1.0, -2.0, 0.5];
        let b: Vec<f64> = (0..3).map(|i| (0..3).map(|j| a[i * 3 + j] * x_true[j]).sum()).collect();
        let x = solve_spd(&a, &b).unwrap();
        for (got, want) in x.iter().zip(x_true) {
            assert!((got - want).abs() < 1e-12, "{x:?}");
        }
        assert!(solve_spd(&[1.0, 2.0, 2.0, 1.0], &[1.0, 1.0]).is_err());
        assert!(solve_spd(&[1.0], &[1.0, 1.0]).is_err());
    }

    /// Columns 0, 1, a copy of 0 scaled, a sum of 0 and 1, and 4: three
    /// are independent, the first of each dependent group kept.
    #[test]
    fn dependent_columns_are_left_out() {
        let rows = [
            [1.0, 0.0, 2.0, 1.0, 0.3],
            [0.0, 1.0, 0.0, 1.0, -0.7],
            [1.0, 2.0, 2.0, 3.0, 0.1],
            [3.0, -1.0, 6.0, 2.0, 0.9],
        ];
        let mut gram = vec![0.0; 25];
        for r in rows {
            for i in 0..5 {
                for j in 0..5 {
                    gram[i * 5 + j] += r[i] * r[j];
                }
            }
        }
        let chosen = independent_columns(&gram, 5, 1e-9);
        assert_eq!(chosen.len(), 3, "{chosen:?}");
        assert!(chosen.contains(&4));
        assert!(!(chosen.contains(&0) && chosen.contains(&2)), "{chosen:?}");
    }
}
