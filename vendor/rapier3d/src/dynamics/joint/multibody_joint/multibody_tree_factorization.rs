//! Factorization of a multibody's joint-space matrices along its kinematic tree.
//!
//! In a tree, `M[i][j]` can only be non-zero when DoF `i` is an ancestor of DoF `j` or
//! the opposite (branch-induced sparsity, Featherstone, *Rigid Body Dynamics Algorithms*,
//! §6.5). Eliminating the DoFs from the leaves to the root then creates no fill-in, so the
//! factorization costs `O(n d²)` and a solve `O(n d)` for a tree of depth `d`, instead of
//! `O(n³)` and `O(n²)` for a dense LU. For a symmetric matrix this is Featherstone's
//! `LᵀDL` factorization; the non-symmetric matrices rapier also factors (the mass matrix
//! with the implicit gyroscopic and Coriolis terms) have the same sparsity pattern, and get
//! the non-symmetric counterpart `A = U·D·L` (`U` unit upper and `L` unit lower
//! triangular, both with the tree's sparsity).
//!
//! The elimination does not pivot. The matrices factored here are a positive-definite
//! mass matrix plus `dt`-sized terms, for which it is stable; when a pivot is nevertheless
//! not usable (zero, tiny against the diagonal, or non-finite), the factorization falls
//! back to nalgebra's dense LU with partial pivoting.

use crate::alloc_prelude::*;
use crate::math::Real;
use na::constraint::{SameNumberOfRows, ShapeConstraint};
use na::{DMatrix, Dim, Dyn, LU, Matrix, StorageMut};

/// Marks a DoF without a parent DoF (a root DoF).
pub(crate) const NO_PARENT: usize = usize::MAX;

/// A square matrix with branch-induced sparsity, factored along its DoF tree (see the module
/// documentation), or by a dense LU when the tree elimination could not be used.
#[cfg_attr(feature = "serde-serialize", derive(Serialize, Deserialize))]
#[derive(Clone, Debug, Default)]
pub struct MultibodyTreeFactorization {
    /// The DoF tree the ancestor lists below were made from.
    parents: Vec<usize>,
    /// The ancestors of DoF `k`, nearest first: `ancestors[ancestor_starts[k]..ancestor_starts[k + 1]]`.
    ancestors: Vec<usize>,
    ancestor_starts: Vec<usize>,
    /// `U[i][k]` and `L[k][i]` for the ancestors `i` of `k`, in the order of `ancestors`.
    upper: Vec<Real>,
    lower: Vec<Real>,
    inv_diagonal: Vec<Real>,
    /// Elimination workspace (column-major, `n x n`).
    work: Vec<Real>,
    /// The dense fallback, when the tree elimination met an unusable pivot.
    dense: Option<LU<Real, Dyn, Dyn>>,
}

impl MultibodyTreeFactorization {
    /// The dimension of the factored matrix.
    pub fn dim(&self) -> usize {
        self.inv_diagonal.len()
    }

    /// Whether the tree elimination was used (`false`: the dense LU fallback).
    pub fn is_tree_sparse(&self) -> bool {
        self.dense.is_none()
    }

    /// Factors the leading `n x n` block of `matrix` (`n = parents.len()`), whose entries
    /// `(i, j)` are zero unless `i` is an ancestor of `j` or `j` an ancestor of `i` in the DoF
    /// tree given by `parents` (`parents[k] < k`, or `NO_PARENT`). Entries outside that
    /// pattern are ignored. Reuses this value's storage.
    pub(crate) fn factor(&mut self, matrix: &DMatrix<Real>, parents: &[usize]) {
        let n = parents.len();
        assert!(
            matrix.nrows() >= n && matrix.ncols() >= n,
            "Internal error: tree factorization dimension."
        );
        assert!(
            parents
                .iter()
                .enumerate()
                .all(|(k, &p)| p == NO_PARENT || p < k),
            "Internal error: DoF parents must precede their children."
        );
        if self.parents != parents {
            self.parents.clear();
            self.parents.extend_from_slice(parents);
            self.ancestors.clear();
            self.ancestor_starts.clear();
            for k in 0..n {
                self.ancestor_starts.push(self.ancestors.len());
                let mut i = parents[k];
                while i != NO_PARENT {
                    self.ancestors.push(i);
                    i = parents[i];
                }
            }
            self.ancestor_starts.push(self.ancestors.len());
            self.upper.resize(self.ancestors.len(), 0.0);
            self.lower.resize(self.ancestors.len(), 0.0);
            self.inv_diagonal.resize(n, 0.0);
            self.work.resize(n * n, 0.0);
        }
        // The leading block, column by column (column-major storage).
        let ld = matrix.nrows();
        let data = matrix.as_slice();
        for j in 0..n {
            self.work[j * n..(j + 1) * n].copy_from_slice(&data[j * ld..j * ld + n]);
        }
        self.dense = None;

        let max_diag = (0..n).fold(0.0, |m: Real, k| m.max(self.work[k * n + k].abs()));
        let tiny = max_diag * Real::EPSILON * 16.0;
        let a = &mut self.work[..];

        for k in (0..n).rev() {
            let d = a[k * n + k];
            if !(d.abs() > tiny) || !d.is_finite() {
                self.dense = Some(LU::new(matrix.view((0, 0), (n, n)).into_owned()));
                return;
            }
            let inv_d = 1.0 / d;
            let range = self.ancestor_starts[k]..self.ancestor_starts[k + 1];
            let ancestors = &self.ancestors[range.clone()];
            let upper = &mut self.upper[range.clone()];
            let lower = &mut self.lower[range];
            // U[i][k] = A[i][k] / d; A[k][j] (scaled into L[k][j] below).
            for ((u, l), &i) in upper.iter_mut().zip(lower.iter_mut()).zip(ancestors) {
                *u = a[k * n + i] * inv_d;
                *l = a[i * n + k];
            }
            // Schur complement on the ancestors of `k`: A[i][j] -= U[i][k]·A[k][j].
            for (&u_ik, &i) in upper.iter().zip(ancestors) {
                for (&a_kj, &j) in lower.iter().zip(ancestors) {
                    // SAFETY: `i, j < k < n`, and `a` has `n * n` entries.
                    unsafe { *a.get_unchecked_mut(j * n + i) -= u_ik * a_kj };
                }
            }
            for l in lower.iter_mut() {
                *l *= inv_d;
            }
            self.inv_diagonal[k] = inv_d;
        }
    }

    /// Solves `A·x = b` in place, column by column. Returns `false` when the matrix was
    /// found singular (as nalgebra's `LU::solve_mut`).
    pub fn solve_mut<R2: Dim, C2: Dim, S2: StorageMut<Real, R2, C2>>(
        &self,
        b: &mut Matrix<Real, R2, C2, S2>,
    ) -> bool
    where
        ShapeConstraint: SameNumberOfRows<R2, Dyn>,
    {
        if let Some(lu) = &self.dense {
            return lu.solve_mut(b);
        }
        let n = self.inv_diagonal.len();
        assert_eq!(
            b.nrows(),
            n,
            "Tree factorization solve: dimension mismatch."
        );
        if b.strides().0 == 1 {
            for mut col in b.column_iter_mut() {
                // SAFETY: a column with a unit row stride is `n` contiguous entries, borrowed
                // mutably through `col` for this scope.
                let x = unsafe { core::slice::from_raw_parts_mut(col.as_mut_ptr(), n) };
                self.solve_slice(x);
            }
            return true;
        }
        const STACK_DIM: usize = 64;
        let mut stack = [0.0; STACK_DIM];
        let mut heap = Vec::new();
        let x: &mut [Real] = if n <= STACK_DIM {
            &mut stack[..n]
        } else {
            heap.resize(n, 0.0);
            &mut heap[..]
        };
        for mut col in b.column_iter_mut() {
            for (r, x) in x.iter_mut().enumerate() {
                // SAFETY: `r < n`, the column's length (checked above).
                *x = unsafe { *col.get_unchecked(r) };
            }
            self.solve_slice(x);
            for (r, x) in x.iter().enumerate() {
                // SAFETY: as above.
                unsafe { *col.get_unchecked_mut(r) = *x };
            }
        }
        true
    }

    fn solve_slice(&self, x: &mut [Real]) {
        let n = x.len();
        let (starts, ancestors) = (&self.ancestor_starts[..], &self.ancestors[..]);
        let (upper, lower) = (&self.upper[..], &self.lower[..]);
        assert!(n == self.inv_diagonal.len() && starts.len() == n + 1);
        assert!(upper.len() == ancestors.len() && lower.len() == ancestors.len());
        assert!(starts[n] == ancestors.len());
        // SAFETY (all the unchecked accesses below): `starts` is non-decreasing up to
        // `ancestors.len()`, so every slot is in bounds of `ancestors`, `upper` and `lower`;
        // every ancestor of `k` is a DoF index below `k < n` (see `factor`).
        unsafe {
            // U·y = b, from the leaves to the root. A constraint's right-hand side is non-zero
            // only on the chain of the link it acts on, and a zero spreads nothing upwards.
            for k in (0..n).rev() {
                let y_k = *x.get_unchecked(k);
                if y_k == 0.0 {
                    continue;
                }
                for slot in *starts.get_unchecked(k)..*starts.get_unchecked(k + 1) {
                    let i = *ancestors.get_unchecked(slot);
                    *x.get_unchecked_mut(i) -= *upper.get_unchecked(slot) * y_k;
                }
            }
            // D·z = y, then L·x = z, from the root to the leaves.
            for k in 0..n {
                let mut acc = *x.get_unchecked(k) * *self.inv_diagonal.get_unchecked(k);
                for slot in *starts.get_unchecked(k)..*starts.get_unchecked(k + 1) {
                    let j = *ancestors.get_unchecked(slot);
                    acc -= *lower.get_unchecked(slot) * *x.get_unchecked(j);
                }
                *x.get_unchecked_mut(k) = acc;
            }
        }
    }
}

#[cfg_attr(feature = "serde-serialize", derive(Serialize, Deserialize))]
#[derive(Clone, Debug, Default)]
pub(crate) struct MultibodyDofTree {
    chain_dofs: Vec<usize>,
    chain_starts: Vec<usize>,
    /// Parent of each kept DoF, in the reduced ordering.
    pub parents: Vec<usize>,
    full_parents: Vec<usize>,
    reduced_ids: Vec<usize>,
    /// The links the tree was built from, and the links of the latest call (compared with
    /// them: the tree is rebuilt only when they differ).
    links: Vec<(usize, usize, usize, bool)>,
    new_links: Vec<(usize, usize, usize, bool)>,
}

impl MultibodyDofTree {
    /// Rebuilds the tree from the links, given in an order where every parent precedes its
    /// children, each as `(parent_link, first_dof, ndofs, kinematic)`; the root's parent is
    /// ignored. DoFs must be numbered contiguously in link order. Nothing is done when the
    /// links are those of the previous call.
    pub fn rebuild(&mut self, links: impl Iterator<Item = (usize, usize, usize, bool)>) {
        self.new_links.clear();
        self.new_links.extend(links);
        if self.new_links == self.links && !self.chain_starts.is_empty() {
            return;
        }
        core::mem::swap(&mut self.links, &mut self.new_links);
        self.chain_dofs.clear();
        self.chain_starts.clear();
        self.parents.clear();
        self.full_parents.clear();
        self.reduced_ids.clear();
        for (i, &(parent, first_dof, ndofs, kinematic)) in self.links.iter().enumerate() {
            debug_assert_eq!(first_dof, self.full_parents.len());
            self.chain_starts.push(self.chain_dofs.len());
            let mut full_parent = NO_PARENT;
            if i != 0 {
                let (start, end) = (self.chain_starts[parent], self.chain_starts[parent + 1]);
                self.chain_dofs.extend_from_within(start..end);
                if end > start {
                    full_parent = self.chain_dofs[end - 1];
                }
            }
            for dof in first_dof..first_dof + ndofs {
                self.chain_dofs.push(dof);
                self.full_parents.push(full_parent);
                if kinematic {
                    self.reduced_ids.push(NO_PARENT);
                } else {
                    // The nearest kept ancestor DoF.
                    let mut p = full_parent;
                    while p != NO_PARENT && self.reduced_ids[p] == NO_PARENT {
                        p = self.full_parents[p];
                    }
                    self.reduced_ids.push(self.parents.len());
                    self.parents.push(if p == NO_PARENT {
                        NO_PARENT
                    } else {
                        self.reduced_ids[p]
                    });
                }
                full_parent = dof;
            }
        }
        self.chain_starts.push(self.chain_dofs.len());
    }

    /// The DoFs of link `i`'s chain, in increasing order; its parent's chain is a prefix.
    pub fn chain(&self, i: usize) -> &[usize] {
        &self.chain_dofs[self.chain_starts[i]..self.chain_starts[i + 1]]
    }
}

#[cfg(test)]
mod test {
    use super::{MultibodyDofTree, MultibodyTreeFactorization, NO_PARENT};
    use crate::alloc_prelude::*;
    use crate::math::Real;
    use na::{DMatrix, DVector};

    /// The DoF tree of a trunk with a 2-DoF root and two 2-DoF legs.
    fn tree() -> Vec<usize> {
        vec![NO_PARENT, 0, 1, 2, 1, 4]
    }

    fn is_ancestor(parents: &[usize], a: usize, mut b: usize) -> bool {
        while b != NO_PARENT {
            if a == b {
                return true;
            }
            b = parents[b];
        }
        false
    }

    /// A matrix with the tree's sparsity: `J^T J` over per-DoF "links", plus `skew` times a
    /// non-symmetric term with the same pattern.
    fn tree_matrix(parents: &[usize], skew: Real) -> DMatrix<Real> {
        let n = parents.len();
        let mut m = DMatrix::zeros(n, n);
        let mut seed = 7u32;
        let mut next = || {
            seed = seed.wrapping_mul(1664525).wrapping_add(1013904223);
            (seed >> 8) as Real / (1u32 << 24) as Real - 0.5
        };
        for i in 0..n {
            for j in 0..n {
                if is_ancestor(parents, i, j) || is_ancestor(parents, j, i) {
                    let v = next();
                    m[(i, j)] += v;
                    m[(j, i)] += v;
                    m[(i, j)] += skew * next();
                }
            }
            m[(i, i)] += 4.0;
        }
        m
    }

    #[test]
    fn tree_solve_matches_dense_lu() {
        let parents = tree();
        for skew in [0.0, 0.3] {
            let m = tree_matrix(&parents, skew);
            let mut f = MultibodyTreeFactorization::default();
            f.factor(&m, &parents);
            assert!(f.is_tree_sparse());
            let b = DMatrix::from_fn(6, 2, |i, j| (i as Real + 1.0) * (j as Real - 0.5));
            let mut x = b.clone();
            assert!(f.solve_mut(&mut x));
            let mut x_lu = b.clone();
            m.clone().lu().solve_mut(&mut x_lu);
            assert!((&x - &x_lu).amax() < 1.0e-5, "{x} vs {x_lu}");
            assert!((&m * &x - &b).amax() < 1.0e-5);
        }
    }

    #[test]
    fn unusable_pivot_falls_back_to_dense_lu() {
        // A zero on a leaf's diagonal: the tree elimination cannot start, pivoting LU can.
        let parents = vec![NO_PARENT, 0];
        let m = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 0.0]);
        let mut f = MultibodyTreeFactorization::default();
        f.factor(&m, &parents);
        assert!(!f.is_tree_sparse());
        let mut x = DVector::from_vec(vec![3.0, 2.0]);
        assert!(f.solve_mut(&mut x));
        assert!((&m * &x - DVector::from_vec(vec![3.0, 2.0])).amax() < 1.0e-6);
    }

    #[test]
    fn dof_tree_skips_kinematic_links() {
        // Root with 2 DoFs; link 1 (1 DoF) on the root; link 2 (kinematic, 1 DoF) on link 1;
        // link 3 (2 DoFs) on link 2; link 4 (1 DoF) on the root.
        let links = [
            (0, 0, 2, false),
            (0, 2, 1, false),
            (1, 3, 1, true),
            (2, 4, 2, false),
            (0, 6, 1, false),
        ];
        let mut tree = MultibodyDofTree::default();
        tree.rebuild(links.into_iter());
        assert_eq!(tree.chain(3), &[0, 1, 2, 3, 4, 5]);
        assert_eq!(tree.chain(4), &[0, 1, 6]);
        // Reduced ordering: full DoFs 0, 1, 2, 4, 5, 6 (3 is kinematic).
        assert_eq!(tree.parents, vec![NO_PARENT, 0, 1, 2, 3, 1]);

        // The same links again keep the tree; a link turned kinematic rebuilds it.
        tree.rebuild(links.into_iter());
        assert_eq!(tree.parents, vec![NO_PARENT, 0, 1, 2, 3, 1]);
        let mut changed = links;
        changed[4].3 = true;
        tree.rebuild(changed.into_iter());
        assert_eq!(tree.chain(4), &[0, 1, 6]);
        assert_eq!(tree.parents, vec![NO_PARENT, 0, 1, 2, 3]);
    }

    #[test]
    fn refactoring_another_tree_and_strided_right_hand_sides_solve_as_dense_lu() {
        // One factorization value reused on two trees (its ancestor lists rebuilt), solving a
        // contiguous column and one read with a row stride of 2.
        let mut f = MultibodyTreeFactorization::default();
        for parents in [tree(), vec![NO_PARENT, 0, 0, 2, NO_PARENT, 4, 5]] {
            let n = parents.len();
            let m = tree_matrix(&parents, 0.3);
            f.factor(&m, &parents);
            assert!(f.is_tree_sparse());
            let b = DVector::from_fn(n, |i, _| i as Real - 1.5);
            let mut x_lu = b.clone();
            m.clone().lu().solve_mut(&mut x_lu);

            let mut x = b.clone();
            assert!(f.solve_mut(&mut x));
            assert!((&x - &x_lu).amax() < 1.0e-5, "{x} vs {x_lu}");

            let mut interleaved =
                DVector::from_fn(2 * n, |i, _| if i % 2 == 0 { b[i / 2] } else { 9.0 });
            let mut strided = interleaved.rows_with_step_mut(0, n, 1);
            assert!(f.solve_mut(&mut strided));
            for i in 0..n {
                assert!((interleaved[2 * i] - x_lu[i]).abs() < 1.0e-5);
                assert_eq!(interleaved[2 * i + 1], 9.0);
            }
        }
    }
}
