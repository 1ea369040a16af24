//! A long-lived HiGHS instance with an interrupt that another thread can pull.
//!
//! The `highs` crate's `Model` is consumed by each solve, which rules out keeping one
//! configured instance per worker, so this talks to `highs-sys` directly. The instance is
//! created once, configured once (quiet, one thread, no parallelism, fixed seed) and fed a
//! new model per decision with `Highs_passMip`, which keeps the options.

use std::ffi::{c_char, c_int, c_void, CString};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use highs_sys as ffi;

use crate::error::SolverError;

/// A mixed-integer program in row-wise sparse form.
#[derive(Debug, Clone, Default)]
pub struct MipModel {
    pub col_cost: Vec<f64>,
    pub col_lower: Vec<f64>,
    pub col_upper: Vec<f64>,
    /// `true` for integer columns.
    pub integer: Vec<bool>,
    pub row_lower: Vec<f64>,
    pub row_upper: Vec<f64>,
    pub row_start: Vec<c_int>,
    pub row_index: Vec<c_int>,
    pub row_value: Vec<f64>,
}

impl MipModel {
    pub fn add_col(&mut self, cost: f64, lower: f64, upper: f64, integer: bool) -> usize {
        self.col_cost.push(cost);
        self.col_lower.push(lower);
        self.col_upper.push(upper);
        self.integer.push(integer);
        self.col_cost.len() - 1
    }

    /// Add `lower <= sum(coef * col) <= upper`. Repeated columns are merged (HiGHS rejects
    /// a column that appears twice in one row) and zero coefficients dropped.
    pub fn add_row(&mut self, lower: f64, upper: f64, terms: &mut [(usize, f64)]) {
        terms.sort_by_key(|t| t.0);
        self.row_start.push(self.row_index.len() as c_int);
        let mut i = 0;
        while i < terms.len() {
            let col = terms[i].0;
            let mut coef = 0.0;
            while i < terms.len() && terms[i].0 == col {
                coef += terms[i].1;
                i += 1;
            }
            if coef != 0.0 {
                self.row_index.push(col as c_int);
                self.row_value.push(coef);
            }
        }
        self.row_lower.push(lower);
        self.row_upper.push(upper);
    }

    pub fn num_cols(&self) -> usize {
        self.col_cost.len()
    }

    pub fn num_rows(&self) -> usize {
        self.row_lower.len()
    }

    pub fn num_integers(&self) -> usize {
        self.integer.iter().filter(|&&i| i).count()
    }
}

/// Column bounds to solve a model within.
#[derive(Debug, Clone, Copy)]
pub struct Bounds<'a> {
    pub lower: &'a [f64],
    pub upper: &'a [f64],
}

/// How a solve ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MipStatus {
    Optimal,
    Infeasible,
    /// Time limit or interrupt; a feasible incumbent may still exist.
    Stopped,
    /// Anything else HiGHS can report (numerical trouble, unbounded).
    Other(i32),
}

/// Result of one solve.
#[derive(Debug, Clone)]
pub struct MipResult {
    pub status: MipStatus,
    pub objective: f64,
    /// Column values, when HiGHS has a feasible point.
    pub columns: Option<Vec<f64>>,
    pub nodes: u64,
}

impl MipResult {
    /// No solution exists (below the cutoff), known without a MIP run.
    pub fn nothing_found() -> Self {
        Self {
            status: MipStatus::Infeasible,
            objective: f64::INFINITY,
            columns: None,
            nodes: 0,
        }
    }

    /// An optimum of value `objective`, proven at the root without a MIP run.
    pub fn optimal_at_root(objective: f64) -> Self {
        Self {
            status: MipStatus::Optimal,
            objective,
            columns: None,
            nodes: 0,
        }
    }
}

/// Shared between a solver and the threads that may interrupt it.
#[derive(Debug, Default)]
struct InterruptState {
    /// Id of the solve that should stop; solves are numbered from 1.
    stop: AtomicU64,
    /// Id of the solve in progress, 0 when idle.
    running: AtomicU64,
}

/// Cloneable handle that stops a given solve from any thread.
#[derive(Debug, Clone)]
pub struct InterruptHandle(Arc<InterruptState>);

impl InterruptHandle {
    /// Ask the solve numbered `solve_id` to stop. Harmless if it has already finished: ids
    /// are never reused, so a late request cannot stop a later solve.
    pub fn interrupt(&self, solve_id: u64) {
        self.0.stop.store(solve_id, Ordering::SeqCst);
    }

    /// Id of the solve in progress, if any.
    pub fn running(&self) -> Option<u64> {
        match self.0.running.load(Ordering::SeqCst) {
            0 => None,
            id => Some(id),
        }
    }
}

/// Passed to the C callback; lives in a `Box` so its address is stable.
struct CallbackData {
    state: Arc<InterruptState>,
    /// Id of the solve this instance is running; written only between solves.
    solve_id: AtomicU64,
}

unsafe extern "C" fn interrupt_callback(
    callback_type: c_int,
    _message: *const c_char,
    _data_out: *const ffi::HighsCallbackDataOut,
    data_in: *mut ffi::HighsCallbackDataIn,
    user_data: *mut c_void,
) {
    if callback_type != ffi::kHighsCallbackMipInterrupt || data_in.is_null() || user_data.is_null() {
        return;
    }
    // SAFETY: user_data is the boxed CallbackData registered in `HighsSolver::new`, which
    // outlives the HiGHS instance; data_in is valid for the duration of the callback.
    let data = unsafe { &*(user_data as *const CallbackData) };
    let stop = data.state.stop.load(Ordering::Relaxed) == data.solve_id.load(Ordering::Relaxed);
    // Always write the flag: HiGHS keeps this struct across runs, so a 1 left from an
    // interrupted solve would stop the next one too.
    unsafe { (*data_in).user_interrupt = c_int::from(stop) };
}

/// One HiGHS instance, to be kept by one thread for its whole life.
pub struct HighsSolver {
    ptr: *mut c_void,
    callback: Box<CallbackData>,
    next_id: u64,
    /// Columns of the model passed last (what [`HighsSolver::resolve_within`] changes).
    loaded_cols: Option<usize>,
}

fn check(call: &'static str, status: c_int) -> Result<(), SolverError> {
    if status == ffi::kHighsStatusError {
        Err(SolverError::Highs { call, status })
    } else {
        Ok(())
    }
}

impl HighsSolver {
    /// Create and configure an instance.
    pub fn new(time_limit_s: f64) -> Result<Self, SolverError> {
        // SAFETY: Highs_create has no preconditions; the pointer is owned by this struct.
        let ptr = unsafe { ffi::Highs_create() };
        // Boxed so the address handed to HiGHS survives moves of the solver.
        let callback = Box::new(CallbackData {
            state: Arc::new(InterruptState::default()),
            solve_id: AtomicU64::new(0),
        });
        let mut solver = Self {
            ptr,
            callback,
            next_id: 1,
            loaded_cols: None,
        };
        solver.set_bool("output_flag", false)?;
        solver.set_bool("log_to_console", false)?;
        solver.set_int("threads", 1)?;
        solver.set_string("parallel", "off")?;
        solver.set_int("random_seed", 0)?;
        solver.set_double("mip_rel_gap", 0.0)?;
        solver.set_double("mip_abs_gap", 1e-9)?;
        // Costs ~3 ms per solve and never pays on models this small.
        solver.set_bool("mip_heuristic_run_feasibility_jump", false)?;
        // The models have few symmetric columns to find; looking for them cost 8 % of the mean
        // solve time on the 0.03 campaign slice, with identical decisions.
        solver.set_bool("mip_detect_symmetry", false)?;
        solver.set_double("time_limit", time_limit_s)?;
        // HiGHS 1.16's presolve declared feasible models with the continuous input
        // infeasible (the oracle's optimum satisfies every row; with presolve off HiGHS finds
        // it), and on models this small it saves nothing.
        solver.set_string("presolve", "off")?;
        let data = &*solver.callback as *const CallbackData as *mut c_void;
        // SAFETY: ptr is a live instance, the callback has the C signature HiGHS expects and
        // `data` stays valid until Drop destroys the instance.
        unsafe {
            check(
                "Highs_setCallback",
                ffi::Highs_setCallback(solver.ptr, Some(interrupt_callback), data),
            )?;
            check(
                "Highs_startCallback",
                ffi::Highs_startCallback(solver.ptr, ffi::kHighsCallbackMipInterrupt),
            )?;
        }
        Ok(solver)
    }

    /// Handle to interrupt this solver's solves from another thread.
    pub fn interrupt_handle(&self) -> InterruptHandle {
        InterruptHandle(self.callback.state.clone())
    }

    /// Id the next solve will carry.
    pub fn next_solve_id(&self) -> u64 {
        self.next_id
    }

    fn set_bool(&mut self, name: &'static str, value: bool) -> Result<(), SolverError> {
        let key = CString::new(name).expect("option names have no NUL");
        // SAFETY: live instance, NUL-terminated key.
        check(name, unsafe {
            ffi::Highs_setBoolOptionValue(self.ptr, key.as_ptr(), c_int::from(value))
        })
    }

    fn set_int(&mut self, name: &'static str, value: c_int) -> Result<(), SolverError> {
        let key = CString::new(name).expect("option names have no NUL");
        // SAFETY: as above.
        check(name, unsafe {
            ffi::Highs_setIntOptionValue(self.ptr, key.as_ptr(), value)
        })
    }

    fn set_double(&mut self, name: &'static str, value: f64) -> Result<(), SolverError> {
        let key = CString::new(name).expect("option names have no NUL");
        // SAFETY: as above.
        check(name, unsafe {
            ffi::Highs_setDoubleOptionValue(self.ptr, key.as_ptr(), value)
        })
    }

    fn set_string(&mut self, name: &'static str, value: &str) -> Result<(), SolverError> {
        let key = CString::new(name).expect("option names have no NUL");
        let value = CString::new(value).expect("option values have no NUL");
        // SAFETY: as above.
        check(name, unsafe {
            ffi::Highs_setStringOptionValue(self.ptr, key.as_ptr(), value.as_ptr())
        })
    }

    /// Set any option by name from its text form (HiGHS parses it by the option's type).
    pub fn set_option(&mut self, name: &str, value: &str) -> Result<(), SolverError> {
        let rejected = || SolverError::Option {
            name: name.to_owned(),
            value: value.to_owned(),
        };
        let key = CString::new(name).map_err(|_| rejected())?;
        let text = CString::new(value).map_err(|_| rejected())?;
        // SAFETY: live instance, NUL-terminated strings.
        let status = unsafe { ffi::Highs_setOptionValue(self.ptr, key.as_ptr(), text.as_ptr()) };
        if status == ffi::kHighsStatusOk {
            Ok(())
        } else {
            Err(rejected())
        }
    }

    /// Change the per-solve time limit.
    pub fn set_time_limit(&mut self, seconds: f64) -> Result<(), SolverError> {
        self.set_double("time_limit", seconds)
    }

    /// Solve `model` (minimisation). With `cutoff`, only solutions with an objective below it
    /// are sought (nodes whose bound reaches it are pruned); finding none is reported as
    /// `Infeasible`, which then means "nothing beats the cutoff".
    ///
    /// A cutoff is how a known feasible plan warm-starts the search. `Highs_setSolution` would
    /// be the obvious tool, but with HiGHS 1.16 a MIP solved from a user solution can report
    /// the improved objective while `Highs_getSolution` still returns the user's point.
    pub fn solve(&mut self, model: &MipModel, cutoff: Option<f64>) -> Result<MipResult, SolverError> {
        self.solve_as(model, cutoff)
    }

    /// Load the LP relaxation of `model`, to be solved within changing column bounds by
    /// [`Self::resolve_within`]. HiGHS keeps its basis between those runs, so a
    /// branch-and-bound child (one bound changed) starts from its parent's optimum.
    pub fn load_relaxation(&mut self, model: &MipModel) -> Result<(), SolverError> {
        let integrality = vec![ffi::kHighsVarTypeContinuous; model.num_cols()];
        self.pass(model, &integrality)
    }

    /// Solve the loaded relaxation within `bounds` (one entry per column of the model that
    /// [`Self::load_relaxation`] loaded last; this instance must not have solved another
    /// model since). With `objective_bound`, a relaxation whose optimum cannot come below it
    /// may stop early and report `Infeasible`.
    pub fn resolve_within(
        &mut self,
        bounds: Bounds<'_>,
        objective_bound: Option<f64>,
    ) -> Result<MipResult, SolverError> {
        self.set_double("objective_bound", objective_bound.unwrap_or(f64::INFINITY))?;
        let n = bounds.lower.len();
        assert!(
            n == bounds.upper.len() && Some(n) == self.loaded_cols,
            "bounds of the loaded model"
        );
        // SAFETY: the instance is live and holds a model of n columns; both arrays have n entries.
        unsafe {
            check(
                "Highs_changeColsBoundsByRange",
                ffi::Highs_changeColsBoundsByRange(
                    self.ptr,
                    0,
                    n as c_int - 1,
                    bounds.lower.as_ptr(),
                    bounds.upper.as_ptr(),
                ),
            )?;
        }
        self.run_loaded(n)
    }

    fn solve_as(&mut self, model: &MipModel, cutoff: Option<f64>) -> Result<MipResult, SolverError> {
        self.set_double("objective_bound", cutoff.unwrap_or(f64::INFINITY))?;
        let integrality: Vec<c_int> = model
            .integer
            .iter()
            .map(|&i| {
                if i {
                    ffi::kHighsVarTypeInteger
                } else {
                    ffi::kHighsVarTypeContinuous
                }
            })
            .collect();
        self.pass(model, &integrality)?;
        let solve_id = self.next_id;
        self.next_id += 1;
        self.callback.solve_id.store(solve_id, Ordering::SeqCst);
        let state = self.callback.state.clone();
        state.running.store(solve_id, Ordering::SeqCst);
        let result = self.run_loaded(model.num_cols());
        state.running.store(0, Ordering::SeqCst);
        result
    }

    fn pass(&mut self, model: &MipModel, integrality: &[c_int]) -> Result<(), SolverError> {
        self.loaded_cols = Some(model.num_cols());
        // SAFETY: every array has the length HiGHS expects for the given counts and format
        // (checked by MipModel's construction); the instance is live.
        unsafe {
            check(
                "Highs_passMip",
                ffi::Highs_passMip(
                    self.ptr,
                    model.num_cols() as c_int,
                    model.num_rows() as c_int,
                    model.row_value.len() as c_int,
                    ffi::kHighsMatrixFormatRowwise,
                    ffi::kHighsObjSenseMinimize,
                    0.0,
                    model.col_cost.as_ptr(),
                    model.col_lower.as_ptr(),
                    model.col_upper.as_ptr(),
                    model.row_lower.as_ptr(),
                    model.row_upper.as_ptr(),
                    model.row_start.as_ptr(),
                    model.row_index.as_ptr(),
                    model.row_value.as_ptr(),
                    integrality.as_ptr(),
                ),
            )
        }
    }

    /// Run the loaded model and collect its result.
    fn run_loaded(&mut self, num_cols: usize) -> Result<MipResult, SolverError> {
        // SAFETY: the instance is live and holds a model of `num_cols` columns.
        unsafe {
            check("Highs_run", ffi::Highs_run(self.ptr))?;
            let status = match ffi::Highs_getModelStatus(self.ptr) {
                s if s == ffi::kHighsModelStatusOptimal => MipStatus::Optimal,
                // With an objective bound, "nothing below it" (the dual simplex stops once its
                // objective, a lower bound, passes the bound).
                s if s == ffi::kHighsModelStatusInfeasible || s == ffi::kHighsModelStatusObjectiveBound => {
                    MipStatus::Infeasible
                }
                s if s == ffi::kHighsModelStatusTimeLimit
                    || s == ffi::kHighsModelStatusInterrupt
                    || s == ffi::kHighsModelStatusHighsInterrupt =>
                {
                    MipStatus::Stopped
                }
                s => MipStatus::Other(s),
            };
            let mut primal_status: c_int = 0;
            let key = CString::new("primal_solution_status").expect("no NUL");
            ffi::Highs_getIntInfoValue(self.ptr, key.as_ptr(), &mut primal_status);
            let columns = if primal_status == ffi::kHighsSolutionStatusFeasible {
                let mut cols = vec![0.0; num_cols];
                check(
                    "Highs_getSolution",
                    ffi::Highs_getSolution(
                        self.ptr,
                        cols.as_mut_ptr(),
                        std::ptr::null_mut(),
                        std::ptr::null_mut(),
                        std::ptr::null_mut(),
                    ),
                )?;
                Some(cols)
            } else {
                None
            };
            let mut nodes: i64 = 0;
            let key = CString::new("mip_node_count").expect("no NUL");
            ffi::Highs_getInt64InfoValue(self.ptr, key.as_ptr(), &mut nodes);
            Ok(MipResult {
                status,
                objective: ffi::Highs_getObjectiveValue(self.ptr),
                columns,
                nodes: nodes.max(0) as u64,
            })
        }
    }
}

thread_local! {
    /// This thread's LP instance (HiGHS keeps per-thread state) for the exact evaluation's
    /// LPs.
    static LP: std::cell::RefCell<Option<HighsSolver>> = const { std::cell::RefCell::new(None) };
}

/// Run `f` on this thread's LP instance, created on first use. It has no time limit:
/// HiGHS's LP clock runs on across the runs of one instance, so any finite limit would
/// eventually stop every LP of a long-lived thread (these LPs end in microseconds).
pub fn with_thread_lp<R>(f: impl FnOnce(&mut HighsSolver) -> Result<R, SolverError>) -> Result<R, SolverError> {
    LP.with(|cell| {
        let mut slot = cell.borrow_mut();
        if slot.is_none() {
            *slot = Some(HighsSolver::new(f64::INFINITY)?);
        }
        f(slot.as_mut().expect("just created"))
    })
}

impl Drop for HighsSolver {
    fn drop(&mut self) {
        // SAFETY: ptr came from Highs_create and is destroyed exactly once; the callback data
        // is dropped after this.
        unsafe { ffi::Highs_destroy(self.ptr) };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// max x + y s.t. x + 2y <= 4, 3x + y <= 6, x, y integer in [0, 10] -> (2, 0) or (1, 1)... value 2
    /// written as minimisation of -x - y.
    #[test]
    fn solves_a_tiny_integer_program() {
        let mut s = HighsSolver::new(1.0).unwrap();
        let mut m = MipModel::default();
        let x = m.add_col(-1.0, 0.0, 10.0, true);
        let y = m.add_col(-1.0, 0.0, 10.0, true);
        m.add_row(f64::NEG_INFINITY, 4.0, &mut [(x, 1.0), (y, 2.0)]);
        m.add_row(f64::NEG_INFINITY, 6.0, &mut [(x, 3.0), (y, 1.0)]);
        let r = s.solve(&m, None).unwrap();
        assert_eq!(r.status, MipStatus::Optimal);
        assert!((r.objective + 2.0).abs() < 1e-9);
        // Reuse the instance for an infeasible model.
        let mut m2 = MipModel::default();
        let z = m2.add_col(0.0, 0.0, 1.0, true);
        m2.add_row(2.0, f64::INFINITY, &mut [(z, 1.0)]);
        assert_eq!(s.solve(&m2, None).unwrap().status, MipStatus::Infeasible);
    }

    #[test]
    fn merges_repeated_columns() {
        let mut m = MipModel::default();
        let x = m.add_col(0.0, 0.0, 1.0, false);
        let y = m.add_col(0.0, 0.0, 1.0, false);
        m.add_row(0.0, 1.0, &mut [(y, 1.0), (x, 2.0), (y, -1.0), (x, 0.5)]);
        assert_eq!(m.row_index, vec![x as c_int]);
        assert_eq!(m.row_value, vec![2.5]);
    }

    #[test]
    fn solve_ids_increase_and_a_stale_interrupt_is_harmless() {
        let mut s = HighsSolver::new(1.0).unwrap();
        let handle = s.interrupt_handle();
        let mut m = MipModel::default();
        let x = m.add_col(-1.0, 0.0, 3.0, true);
        m.add_row(f64::NEG_INFINITY, 2.5, &mut [(x, 1.0)]);
        let first = s.next_solve_id();
        assert_eq!(s.solve(&m, None).unwrap().status, MipStatus::Optimal);
        handle.interrupt(first);
        assert_eq!(handle.running(), None);
        assert_eq!(s.next_solve_id(), first + 1);
        assert_eq!(s.solve(&m, None).unwrap().status, MipStatus::Optimal);
    }
}
