//! The branch and bound against brute force on random 0/1 programs.

use crate::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// `min cost . x` over `x in {0, 1}^n` with `A x >= b`, searched with a dense relaxation.
struct Binary {
    lp: DenseLp,
    scored: Vec<Vec<bool>>,
    lps: usize,
}

impl Binary {
    fn random(rng: &mut ChaCha8Rng) -> Self {
        let mut lp = DenseLp::default();
        let n = rng.random_range(3..=9);
        for _ in 0..n {
            lp.add_col(rng.random_range(-2.0..3.0), 0.0, 1.0);
        }
        for _ in 0..rng.random_range(1..=5) {
            let terms: Vec<(usize, f64)> = (0..n).map(|c| (c, rng.random_range(-3.0..3.0))).collect();
            lp.add_row(rng.random_range(-2.0..2.0), f64::INFINITY, &terms);
        }
        Self {
            lp,
            scored: Vec::new(),
            lps: 0,
        }
    }

    /// The cost of a 0/1 point, `None` if it misses a row.
    fn score(&self, x: &[bool]) -> Option<f64> {
        let x: Vec<f64> = x.iter().map(|&b| f64::from(u8::from(b))).collect();
        let feasible = (0..self.lp.num_rows()).all(|r| self.lp.activity(r, &x) >= self.lp.row_bounds(r).0 - 1e-6);
        feasible.then(|| self.lp.objective(&x))
    }

    fn brute_force(&self) -> Option<f64> {
        let n = self.lp.num_cols();
        (0..1u32 << n)
            .filter_map(|bits| self.score(&(0..n).map(|c| bits >> c & 1 == 1).collect::<Vec<_>>()))
            .min_by(f64::total_cmp)
    }
}

impl Search for Binary {
    type Plan = f64;
    type Error = Error;

    fn cost(plan: &f64) -> f64 {
        *plan
    }

    fn relax(
        &mut self,
        bounds: Bounds<'_>,
        start: Option<FinalTableau>,
        _objective_bound: Option<f64>,
    ) -> Result<(Relaxed, Option<FinalTableau>), Error> {
        self.lps += 1;
        for (c, (&lo, &hi)) in bounds.lower.iter().zip(bounds.upper).enumerate() {
            self.lp.set_bounds(c, lo, hi);
        }
        Ok(match self.lp.solve_from(Pricing::SteepestEdge, start)? {
            (LpOutcome::Optimal { x, objective }, tableau) => (Relaxed::Optimal { objective, x }, tableau),
            (LpOutcome::Infeasible, _) => (Relaxed::Infeasible, None),
        })
    }

    fn integral(&mut self, x: &[f64]) -> Option<f64> {
        self.score(&x.iter().map(|&v| v > 0.5).collect::<Vec<_>>())
    }

    fn rounding(&mut self, x: &[f64]) -> Option<f64> {
        let rounded: Vec<bool> = x.iter().map(|&v| v > 0.5).collect();
        if self.scored.contains(&rounded) {
            return None;
        }
        let cost = self.score(&rounded);
        self.scored.push(rounded);
        cost
    }
}

#[test]
fn best_first_finds_the_brute_force_optimum() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let (mut optimal, mut infeasible, mut open_at_root) = (0, 0, 0);
    for _ in 0..400 {
        let mut problem = Binary::random(&mut rng);
        let expected = problem.brute_force();
        let n = problem.lp.num_cols();
        let (integer, lower, upper) = (vec![true; n], vec![0.0; n], vec![1.0; n]);
        let tree = |max_lps| Tree {
            integer: &integer,
            lower: &lower,
            upper: &upper,
            max_lps,
        };
        let settled = best_first(&mut problem, tree(10_000), None).unwrap();
        let Settled::Optimal(found) = settled else {
            panic!("the budget ran out: {settled:?}");
        };
        match (found, expected) {
            (Some(f), Some(e)) => assert!((f - e).abs() <= 1e-9, "{f} vs brute force {e}"),
            (None, None) => infeasible += 1,
            (f, e) => panic!("{f:?} vs brute force {e:?}"),
        }
        optimal += 1;
        problem.scored.clear();
        open_at_root += usize::from(matches!(
            best_first(&mut problem, tree(1), None).unwrap(),
            Settled::Open(_)
        ));
    }
    assert!(
        infeasible > 20 && infeasible < optimal && open_at_root > 20,
        "{infeasible} infeasible, {open_at_root} open at the root"
    );
}
