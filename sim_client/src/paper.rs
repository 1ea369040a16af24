//! Reference values of the paper's Table I (Case 3), copied row by row.

/// One row of the paper's Table I. Rates are percentages.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PaperRow {
    /// Configuration id, 1..=18.
    pub id: u32,
    /// Lane count.
    pub lanes: u8,
    /// Speed range (m/s).
    pub speed_range: (f64, f64),
    /// SV count.
    pub sv_count: u32,
    /// Trials N.
    pub trials: u32,
    /// Decision steps.
    pub decisions: u64,
    /// Collision rate (%).
    pub collision_pct: f64,
    /// Normal optimization rate (%).
    pub nor_pct: f64,
    /// Global soft relaxation rate (%).
    pub gsrr_pct: f64,
    /// Fallback rate (%).
    pub fbr_pct: f64,
}

const fn row(
    id: u32,
    lanes: u8,
    speed_range: (f64, f64),
    sv_count: u32,
    trials: u32,
    decisions: u64,
    rates: [f64; 4],
) -> PaperRow {
    PaperRow {
        id,
        lanes,
        speed_range,
        sv_count,
        trials,
        decisions,
        collision_pct: rates[0],
        nor_pct: rates[1],
        gsrr_pct: rates[2],
        fbr_pct: rates[3],
    }
}

const U: (f64, f64) = (10.0, 20.0);
const H: (f64, f64) = (25.0, 40.0);

/// The 18 rows of Table I, in id order.
pub const PAPER_TABLE: [PaperRow; 18] = [
    row(1, 2, U, 5, 500, 37500, [0.00, 99.84, 0.13, 0.03]),
    row(2, 2, U, 8, 375, 28125, [0.00, 98.89, 0.87, 0.24]),
    row(3, 2, U, 10, 325, 24375, [0.00, 98.04, 1.28, 0.67]),
    row(4, 2, H, 5, 325, 24375, [0.00, 98.75, 1.05, 0.20]),
    row(5, 2, H, 8, 600, 44964, [0.17, 96.20, 2.75, 1.06]),
    row(6, 2, H, 10, 375, 28094, [0.27, 93.34, 4.39, 2.27]),
    row(7, 3, U, 5, 500, 37500, [0.00, 99.97, 0.01, 0.02]),
    row(8, 3, U, 8, 350, 26202, [0.29, 99.77, 0.15, 0.07]),
    row(9, 3, U, 10, 325, 24375, [0.00, 99.59, 0.36, 0.05]),
    row(10, 3, H, 5, 425, 31875, [0.00, 99.58, 0.38, 0.04]),
    row(11, 3, H, 8, 625, 46875, [0.00, 98.76, 1.04, 0.20]),
    row(12, 3, H, 10, 525, 58125, [0.00, 97.96, 1.67, 0.37]),
    row(13, 4, U, 5, 500, 37500, [0.00, 99.99, 0.01, 0.00]),
    row(14, 4, U, 8, 325, 24375, [0.00, 99.98, 0.02, 0.00]),
    row(15, 4, U, 10, 375, 28116, [0.27, 99.95, 0.04, 0.01]),
    row(16, 4, H, 5, 425, 31875, [0.00, 99.69, 0.26, 0.06]),
    row(17, 4, H, 8, 600, 45000, [0.00, 99.46, 0.53, 0.01]),
    row(18, 4, H, 10, 575, 43125, [0.00, 98.88, 1.01, 0.11]),
];

/// The paper's overall row: trials, decisions, collision %, NOR %, GSRR %, FBR %.
pub const PAPER_OVERALL: PaperRow = row(0, 0, (0.0, 0.0), 0, 8050, 622_376, [0.05, 98.77, 0.93, 0.29]);

/// The paper row with the same lanes, SV count and speed range, if any.
pub fn paper_row_for(lanes: u8, sv_count: u32, speed_range: (f64, f64)) -> Option<&'static PaperRow> {
    PAPER_TABLE
        .iter()
        .find(|r| r.lanes == lanes && r.sv_count == sv_count && r.speed_range == speed_range)
}
