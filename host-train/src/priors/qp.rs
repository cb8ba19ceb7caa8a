//! A small builder for convex quadratic programs with second-order cones, solved by clarabel.
//!
//! The objective is a weighted sum of squared affine terms `w (a'x - c)^2` (plus an optional
//! linear term); constraints are equalities `a'x = b`, inequalities `a'x <= b` and
//! 3-dimensional second-order cones `u0 >= |(u1, u2)|` with each `u` an affine expression.
//! This is the shape of every problem in trajectory optimization we need, and it keeps the
//! clarabel plumbing (CSC assembly, cone ordering, slack signs) in one place.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};

/// A linear expression: (variable index, coefficient) pairs.
pub type Lin = Vec<(usize, f64)>;

/// An affine expression `a'x + c`.
#[derive(Clone, Debug, Default)]
pub struct Affine {
    /// Linear part.
    pub lin: Lin,
    /// Constant.
    pub constant: f64,
}

impl Affine {
    /// `coef * x[var]`.
    pub fn var(var: usize, coef: f64) -> Self {
        Self {
            lin: vec![(var, coef)],
            constant: 0.0,
        }
    }

    fn eval(&self, x: &[f64]) -> f64 {
        self.constant + self.lin.iter().map(|&(i, a)| a * x[i]).sum::<f64>()
    }
}

/// Why a QP could not be solved.
#[derive(Debug, thiserror::Error)]
pub enum QpError {
    /// Clarabel refused the problem data.
    #[error("solver setup failed: {0}")]
    Setup(String),
    /// A term refers to a variable that does not exist.
    #[error("variable index {index} out of range (problem has {num_vars} variables)")]
    VariableIndex {
        /// Offending index.
        index: usize,
        /// Number of variables.
        num_vars: usize,
    },
}

/// A QP under construction.
#[derive(Clone, Debug, Default)]
pub struct QpBuilder {
    num_vars: usize,
    squares: Vec<(f64, Affine)>,
    linear_cost: Vec<(usize, f64)>,
    equalities: Vec<(Lin, f64)>,
    inequalities: Vec<(Lin, f64)>,
    cones: Vec<[Affine; 3]>,
}

/// The solution of a QP and how well it satisfies its constraints.
#[derive(Clone, Debug)]
pub struct QpSolution {
    /// Primal solution.
    pub x: Vec<f64>,
    /// Solver status.
    pub status: SolverStatus,
    /// Objective value, constant terms included.
    pub objective: f64,
    /// Interior-point iterations.
    pub iterations: u32,
    /// Largest `|a'x - b|` over the equalities.
    pub max_equality_residual: f64,
    /// Largest `max(0, a'x - b)` over the inequalities.
    pub max_inequality_violation: f64,
    /// Largest `max(0, |(u1, u2)| - u0)` over the cones.
    pub max_cone_violation: f64,
}

impl QpSolution {
    /// True when the solver reports a (possibly reduced-accuracy) optimum.
    pub fn is_solved(&self) -> bool {
        matches!(
            self.status,
            SolverStatus::Solved | SolverStatus::AlmostSolved
        )
    }

    /// The worst of the three constraint violations.
    pub fn max_violation(&self) -> f64 {
        self.max_equality_residual
            .max(self.max_inequality_violation)
            .max(self.max_cone_violation)
    }
}

impl QpBuilder {
    /// An empty problem.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds `n` variables and returns the index of the first.
    pub fn add_vars(&mut self, n: usize) -> usize {
        let first = self.num_vars;
        self.num_vars += n;
        first
    }

    /// Number of variables.
    pub fn num_vars(&self) -> usize {
        self.num_vars
    }

    /// Adds `weight * (a'x + c)^2` to the objective.
    pub fn add_square(&mut self, weight: f64, term: Affine) {
        if weight > 0.0 && !term.lin.is_empty() {
            self.squares.push((weight, term));
        }
    }

    /// Adds `coef * x[var]` to the objective.
    pub fn add_linear_cost(&mut self, var: usize, coef: f64) {
        self.linear_cost.push((var, coef));
    }

    /// Adds `a'x = b`.
    pub fn add_equality(&mut self, a: Lin, b: f64) {
        self.equalities.push((a, b));
    }

    /// Adds `a'x <= b`.
    pub fn add_inequality(&mut self, a: Lin, b: f64) {
        self.inequalities.push((a, b));
    }

    /// Adds `lo <= x[var] <= hi`.
    pub fn add_bounds(&mut self, var: usize, lo: f64, hi: f64) {
        self.add_inequality(vec![(var, 1.0)], hi);
        self.add_inequality(vec![(var, -1.0)], -lo);
    }

    /// Adds the second-order cone `u[0] >= |(u[1], u[2])|`.
    pub fn add_cone(&mut self, u: [Affine; 3]) {
        self.cones.push(u);
    }

    fn check_indices(&self) -> Result<(), QpError> {
        let lins = self
            .squares
            .iter()
            .map(|(_, t)| &t.lin)
            .chain(self.equalities.iter().map(|(a, _)| a))
            .chain(self.inequalities.iter().map(|(a, _)| a))
            .chain(self.cones.iter().flat_map(|u| u.iter().map(|t| &t.lin)));
        for lin in lins {
            for &(index, _) in lin {
                if index >= self.num_vars {
                    return Err(QpError::VariableIndex {
                        index,
                        num_vars: self.num_vars,
                    });
                }
            }
        }
        Ok(())
    }

    /// Solves the problem with clarabel's interior-point method.
    pub fn solve(&self) -> Result<QpSolution, QpError> {
        self.check_indices()?;
        let n = self.num_vars;
        // Objective: sum w (a'x + c)^2 = x'(w a a')x + 2 w c a'x + w c^2 = 1/2 x'Px + q'x + k.
        let (mut pi, mut pj, mut pv) = (Vec::new(), Vec::new(), Vec::new());
        let mut q = vec![0.0; n];
        for (w, term) in &self.squares {
            for &(i, ai) in &term.lin {
                for &(j, aj) in &term.lin {
                    if i <= j {
                        // P = 2 w a a'; only the upper triangle is passed.
                        pi.push(i);
                        pj.push(j);
                        pv.push(2.0 * w * ai * aj);
                    }
                }
                q[i] += 2.0 * w * term.constant * ai;
            }
        }
        for &(i, c) in &self.linear_cost {
            q[i] += c;
        }
        let p = upper_triangle(n, pi, pj, pv);

        let (mut ai, mut aj, mut av, mut b) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let mut row = 0;
        let mut push_row = |lin: &Lin, sign: f64, rhs: f64, b: &mut Vec<f64>| {
            for &(j, a) in lin {
                ai.push(row);
                aj.push(j);
                av.push(sign * a);
            }
            b.push(rhs);
            row += 1;
        };
        for (a, rhs) in &self.equalities {
            push_row(a, 1.0, *rhs, &mut b);
        }
        for (a, rhs) in &self.inequalities {
            push_row(a, 1.0, *rhs, &mut b);
        }
        for cone in &self.cones {
            // s = b - A x = u  =>  A = -a, b = c.
            for u in cone {
                push_row(&u.lin, -1.0, u.constant, &mut b);
            }
        }
        let m = b.len();
        let a = CscMatrix::new_from_triplets(m, n, ai, aj, av);
        let mut cones = Vec::new();
        if !self.equalities.is_empty() {
            cones.push(SupportedConeT::ZeroConeT(self.equalities.len()));
        }
        if !self.inequalities.is_empty() {
            cones.push(SupportedConeT::NonnegativeConeT(self.inequalities.len()));
        }
        cones.extend(
            self.cones
                .iter()
                .map(|_| SupportedConeT::SecondOrderConeT(3)),
        );

        let settings = DefaultSettings {
            verbose: false,
            ..DefaultSettings::default()
        };
        let mut solver = DefaultSolver::new(&p, &q, &a, &b, &cones, settings)
            .map_err(|e| QpError::Setup(format!("{e:?}")))?;
        solver.solve();
        let sol = &solver.solution;
        let x = sol.x.clone();
        Ok(QpSolution {
            objective: self.objective(&x),
            status: sol.status,
            iterations: sol.iterations,
            max_equality_residual: self
                .equalities
                .iter()
                .map(|(a, rhs)| (eval_lin(a, &x) - rhs).abs())
                .fold(0.0, f64::max),
            max_inequality_violation: self
                .inequalities
                .iter()
                .map(|(a, rhs)| (eval_lin(a, &x) - rhs).max(0.0))
                .fold(0.0, f64::max),
            max_cone_violation: self
                .cones
                .iter()
                .map(|[u0, u1, u2]| (u1.eval(&x).hypot(u2.eval(&x)) - u0.eval(&x)).max(0.0))
                .fold(0.0, f64::max),
            x,
        })
    }

    /// The objective at `x`, constant terms included.
    pub fn objective(&self, x: &[f64]) -> f64 {
        let squares: f64 = self
            .squares
            .iter()
            .map(|(w, t)| w * t.eval(x).powi(2))
            .sum();
        let linear: f64 = self.linear_cost.iter().map(|&(i, c)| c * x[i]).sum();
        squares + linear
    }
}

fn eval_lin(a: &Lin, x: &[f64]) -> f64 {
    a.iter().map(|&(i, c)| c * x[i]).sum()
}

fn upper_triangle(n: usize, i: Vec<usize>, j: Vec<usize>, v: Vec<f64>) -> CscMatrix<f64> {
    // Off-diagonal pairs (i, j) and (j, i) of a term both land on (min, max): summed by
    // the triplet constructor, which is what the symmetric product needs.
    let (i, j): (Vec<usize>, Vec<usize>) = i
        .iter()
        .zip(&j)
        .map(|(&a, &b)| (a.min(b), a.max(b)))
        .unzip();
    CscMatrix::new_from_triplets(n, n, i, j, v)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-6
    }

    #[test]
    fn projection_onto_a_line() {
        // min (x - 1)^2 + (y - 2)^2  s.t.  x + y = 1  ->  (0, 1), objective 2.
        let mut qp = QpBuilder::new();
        let v = qp.add_vars(2);
        qp.add_square(
            1.0,
            Affine {
                lin: vec![(v, 1.0)],
                constant: -1.0,
            },
        );
        qp.add_square(
            1.0,
            Affine {
                lin: vec![(v + 1, 1.0)],
                constant: -2.0,
            },
        );
        qp.add_equality(vec![(v, 1.0), (v + 1, 1.0)], 1.0);
        let s = qp.solve().unwrap();
        assert!(s.is_solved());
        assert!(close(s.x[0], 0.0) && close(s.x[1], 1.0), "{:?}", s.x);
        assert!(close(s.objective, 2.0));
        assert!(s.max_violation() < 1e-7);
    }

    #[test]
    fn coupled_squares_and_bounds() {
        // min (x - y)^2 + (x + y - 4)^2  s.t.  x <= 1: the bound is active, and for x = 1
        // the objective (1 - y)^2 + (y - 3)^2 is minimal at y = 2, objective 2.
        let mut qp = QpBuilder::new();
        let v = qp.add_vars(2);
        qp.add_square(
            1.0,
            Affine {
                lin: vec![(v, 1.0), (v + 1, -1.0)],
                constant: 0.0,
            },
        );
        qp.add_square(
            1.0,
            Affine {
                lin: vec![(v, 1.0), (v + 1, 1.0)],
                constant: -4.0,
            },
        );
        qp.add_bounds(v, -10.0, 1.0);
        let s = qp.solve().unwrap();
        assert!(close(s.x[0], 1.0) && close(s.x[1], 2.0), "{:?}", s.x);
        assert!(close(s.objective, 2.0));
    }

    #[test]
    fn projection_onto_a_friction_cone() {
        // Nearest point to (3, 4) in the unit disc |(x, y)| <= 1: (0.6, 0.8), objective 16.
        let mut qp = QpBuilder::new();
        let v = qp.add_vars(2);
        qp.add_square(
            1.0,
            Affine {
                lin: vec![(v, 1.0)],
                constant: -3.0,
            },
        );
        qp.add_square(
            1.0,
            Affine {
                lin: vec![(v + 1, 1.0)],
                constant: -4.0,
            },
        );
        qp.add_cone([
            Affine {
                lin: vec![],
                constant: 1.0,
            },
            Affine::var(v, 1.0),
            Affine::var(v + 1, 1.0),
        ]);
        let s = qp.solve().unwrap();
        assert!(close(s.x[0], 0.6) && close(s.x[1], 0.8), "{:?}", s.x);
        assert!(close(s.objective, 16.0));
        assert!(s.max_cone_violation < 1e-7);
    }

    #[test]
    fn infeasible_problems_are_reported() {
        let mut qp = QpBuilder::new();
        let v = qp.add_vars(1);
        qp.add_square(1.0, Affine::var(v, 1.0));
        qp.add_bounds(v, 2.0, 1.0);
        let s = qp.solve().unwrap();
        assert!(!s.is_solved());
        assert!(matches!(s.status, SolverStatus::PrimalInfeasible));
    }

    #[test]
    fn bad_indices_are_refused() {
        let mut qp = QpBuilder::new();
        qp.add_vars(1);
        qp.add_equality(vec![(3, 1.0)], 0.0);
        assert!(matches!(
            qp.solve(),
            Err(QpError::VariableIndex {
                index: 3,
                num_vars: 1
            })
        ));
    }
}
