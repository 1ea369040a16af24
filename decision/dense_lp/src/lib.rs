//! A dense simplex for small linear programs, and a best-first branch and bound over it.
//!
//! # The LP
//!
//! [`DenseLp`] is `min offset + cost . x` subject to `row_lower <= A x <= row_upper` and
//! `lower <= x <= upper`, built column by column and row by row. [`DenseLp::solve`] runs a
//! bounded-variable dual simplex on the condensed tableau, a dense `rows x columns` array
//! updated by exchange pivots. It is meant for LPs of some tens to a few hundred rows and
//! columns, where a general solver's fixed cost per run (model checks, scaling, set-up)
//! outweighs the pivoting itself.
//!
//! Why the dual simplex: when every column is boxed or has a non-negative cost, putting each
//! column at the bound its cost prefers is dual feasible at once, with no phase one; the row
//! logicals start basic. A column whose cost pulls it towards an infinite bound has no such
//! start, and the solve says so ([`Error::NoDualStart`]). A row that stays violated with no
//! column able to move it proves the LP infeasible ([`LpOutcome::Infeasible`]).
//!
//! # Pivot rules
//!
//! [`Pricing::LargestViolation`] lets the most violated row leave and the smallest dual ratio
//! enter; ties are common in degenerate LPs, so after `4 (m + n) + 20` pivots the choice
//! switches to Bland's rule, which cannot cycle. [`Pricing::SteepestEdge`] uses dual
//! steepest-edge pricing (exact weights read off the tableau) and the bound-flipping ratio
//! test, which moves a boxed column whose ratio comes first to its other bound instead of
//! pivoting it in while the leaving row stays violated; on LPs of mostly `[0, 1]` columns it
//! takes several times fewer pivots.
//!
//! A hard pivot limit ([`Error::PivotLimit`]) and a final check of the point against the
//! original rows and bounds ([`Error::Inaccurate`], [`CHECK_TOL`]) turn any numerical failure
//! into an error: the caller can then ask another solver. An error is never a wrong verdict.
//!
//! # Re-solves
//!
//! [`DenseLp::solve_from`] returns, with an optimum, its [`FinalTableau`]. Solving the same LP
//! with other column bounds from that tableau keeps its reduced costs, so they stay dual
//! feasible: each nonbasic column moves to its new bound and the dual simplex repairs the few
//! rows that broke, a handful of pivots where a cold start takes tens.
//!
//! # Branch and bound
//!
//! [`best_first`] searches a relaxation with integer columns: the open node of the lowest
//! bound is solved, its point scored when integral, or rounded and scored, then split on its
//! most fractional integer column, both children starting from its final tableau. The
//! problem-specific parts (solving a node's LP, scoring a point) are the [`Search`] trait's;
//! a budget of LP runs bounds the work, and past it the best plan comes back as
//! [`Settled::Open`].
//!
//! ```
//! use dense_lp::{DenseLp, LpOutcome};
//!
//! // min x + 2y  s.t.  x + y >= 1,  0 <= x, y <= 4
//! let mut lp = DenseLp::default();
//! let x = lp.add_col(1.0, 0.0, 4.0);
//! let y = lp.add_col(2.0, 0.0, 4.0);
//! lp.add_row(1.0, f64::INFINITY, &[(x, 1.0), (y, 1.0)]);
//! let LpOutcome::Optimal { x: point, objective } = lp.solve().unwrap() else { panic!() };
//! assert_eq!((point[x], point[y], objective), (1.0, 0.0, 1.0));
//! ```

mod branch;
mod simplex;
mod tableau;

pub use branch::{best_first, Bounds, Relaxed, Search, Settled, Tree, INTEGRALITY_TOLERANCE, OPTIMALITY_TOLERANCE};
pub use simplex::{DenseLp, Error, FinalTableau, LpOutcome, Pricing, Violated, CHECK_TOL, PRIMAL_TOL};

#[cfg(test)]
mod tests;

#[cfg(test)]
mod branch_tests;
