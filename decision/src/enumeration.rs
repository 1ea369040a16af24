//! The exact oracle: exhaustive enumeration of the ego's action sequences.

use crate::evaluate::{evaluate, Evaluation, Mode};
use crate::problem::Problem;

/// Best sequence and how many were examined. Ties go to the first in enumeration order
/// ("keep" first), so the answer is deterministic.
pub fn solve(problem: &Problem, mode: Mode) -> (Option<Evaluation>, usize) {
    let sequences = problem.admissible_sequences();
    let count = sequences.len();
    let mut best: Option<Evaluation> = None;
    for actions in &sequences {
        if let Some(e) = evaluate(problem, actions, mode) {
            if best.as_ref().is_none_or(|b| e.cost < b.cost) {
                best = Some(e);
            }
        }
    }
    (best, count)
}
