//! SVG figures in the style of the paper's Figs. 2-6 (plotters, SVG backend, no fonts needed).
//! Speed and beta figures here; the road snapshots in [`snapshots`], the load tool's in
//! [`load`].

mod load;
mod snapshots;

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::episode::{DecisionRecord, Episode, VehicleState};
use crate::error::{Result, SimClientError};

pub use load::{latency_plot, load_timeline_plot};
pub use snapshots::{snapshot_instants, snapshots_plot};

const EGO: RGBColor = RGBColor(220, 30, 30);
const SV_COLOURS: [RGBColor; 8] = [
    RGBColor(40, 90, 200),
    RGBColor(30, 150, 60),
    RGBColor(230, 160, 20),
    RGBColor(130, 60, 170),
    RGBColor(240, 90, 40),
    RGBColor(20, 160, 170),
    RGBColor(120, 120, 120),
    RGBColor(180, 60, 120),
];
/// Corrective-phase shading, one colour per reference SV in order of appearance (the
/// paper's yellow, then blue).
const CORRECTIVE: [RGBColor; 4] = [
    RGBColor(255, 220, 90),
    RGBColor(110, 170, 255),
    RGBColor(140, 220, 140),
    RGBColor(240, 150, 200),
];
const SNAPSHOT_MARKER: RGBColor = RGBColor(240, 200, 0);
const BETA_DECEL: RGBColor = RGBColor(40, 170, 60);
const BETA_CRUISE: RGBColor = RGBColor(140, 70, 190);
const BETA_ACCEL: RGBColor = RGBColor(220, 40, 40);

fn sv_colour(id: u32) -> RGBColor {
    SV_COLOURS[(id as usize + SV_COLOURS.len() - 1) % SV_COLOURS.len()]
}

fn beta_colour(beta: i8) -> RGBColor {
    match beta {
        b if b < 0 => BETA_DECEL,
        0 => BETA_CRUISE,
        _ => BETA_ACCEL,
    }
}

fn err<E: std::fmt::Display>(path: &Path) -> impl Fn(E) -> SimClientError + '_ {
    move |e| SimClientError::Plot {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

/// The series labels, in the one style every figure uses.
fn draw_legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
}

fn ids(trajectory: &[VehicleState]) -> Vec<u32> {
    let mut ids: Vec<u32> = trajectory.iter().map(|s| s.id).collect();
    ids.sort_unstable();
    ids.dedup();
    ids
}

/// Adds `[a, b)` to merged intervals (contiguous decisions join).
fn extend_intervals(out: &mut Vec<(f64, f64)>, a: f64, b: f64) {
    match out.last_mut() {
        Some(last) if (last.1 - a).abs() < 1e-6 => last.1 = b,
        _ => out.push((a, b)),
    }
}

/// Time intervals with at least one SV in corrective mode, merged.
pub fn corrective_intervals(decisions: &[DecisionRecord], period: f64) -> Vec<(f64, f64)> {
    let mut out: Vec<(f64, f64)> = Vec::new();
    for d in decisions.iter().filter(|d| d.corrective_svs > 0) {
        extend_intervals(&mut out, d.time_s, d.time_s + period);
    }
    out
}

/// Per reference SV (in order of first appearance), the merged intervals in which it was in
/// corrective mode.
pub fn corrective_intervals_by_sv(decisions: &[DecisionRecord], period: f64) -> Vec<(u32, Vec<(f64, f64)>)> {
    let mut out: Vec<(u32, Vec<(f64, f64)>)> = Vec::new();
    for d in decisions {
        for &id in &d.corrective_sv_ids {
            let k = match out.iter().position(|(i, _)| *i == id) {
                Some(k) => k,
                None => {
                    out.push((id, Vec::new()));
                    out.len() - 1
                }
            };
            extend_intervals(&mut out[k].1, d.time_s, d.time_s + period);
        }
    }
    out
}

fn end_time(e: &Episode) -> f64 {
    e.simulated_s.max(e.decision_period_s)
}

/// Ego and SV speeds over time (the paper's Figs. 3 and 5): the corrective phase shaded per
/// reference SV, and circles on the ego's curve at the decision instants `markers` (the
/// snapshots).
pub fn speed_plot(path: &Path, e: &Episode, title: &str, markers: &[usize]) -> Result<()> {
    let err = err(path);
    let root = SVGBackend::new(path, (1000, 480)).into_drawing_area();
    root.fill(&WHITE).map_err(&err)?;
    let vmax = e.trajectory.iter().map(|s| s.v_mps).fold(1.0, f64::max) * 1.1;
    let t_end = end_time(e);
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..t_end, 0.0..vmax)
        .map_err(&err)?;
    chart
        .configure_mesh()
        .x_desc("time (s)")
        .y_desc("speed (m/s)")
        .draw()
        .map_err(&err)?;
    for (k, (id, intervals)) in corrective_intervals_by_sv(&e.decisions, e.decision_period_s)
        .into_iter()
        .enumerate()
    {
        let colour = CORRECTIVE[k % CORRECTIVE.len()];
        chart
            .draw_series(
                intervals
                    .into_iter()
                    .map(|(a, b)| Rectangle::new([(a, 0.0), (b.min(t_end), vmax)], colour.mix(0.35).filled())),
            )
            .map_err(&err)?
            .label(format!("corrective: SV{id}"))
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], colour.mix(0.6).filled()));
    }
    for id in ids(&e.trajectory).into_iter().rev() {
        let colour = if id == 0 { EGO } else { sv_colour(id) };
        let width = if id == 0 { 3 } else { 1 };
        let points = e.trajectory.iter().filter(|s| s.id == id).map(|s| (s.time_s, s.v_mps));
        let name = if id == 0 { "ego".to_string() } else { format!("SV{id}") };
        chart
            .draw_series(LineSeries::new(points, colour.stroke_width(width)))
            .map_err(&err)?
            .label(name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2)));
    }
    chart
        .draw_series(
            markers
                .iter()
                .filter_map(|&k| e.decisions.get(k))
                .map(|d| Circle::new((d.time_s, d.ego_speed_mps), 7, SNAPSHOT_MARKER.stroke_width(3))),
        )
        .map_err(&err)?;
    draw_legend(&mut chart, SeriesLabelPosition::LowerRight).map_err(&err)?;
    root.present().map_err(&err)?;
    Ok(())
}

/// Step line of a run's commanded beta over time, shifted vertically by `offset`.
fn beta_steps(e: &Episode, offset: f64) -> Vec<(f64, f64)> {
    let mut pts = Vec::with_capacity(2 * e.decisions.len());
    for (k, d) in e.decisions.iter().enumerate() {
        let t1 = e
            .decisions
            .get(k + 1)
            .map_or(end_time(e).max(d.time_s + e.decision_period_s), |n| n.time_s);
        let b = f64::from(d.beta) + offset;
        pts.push((d.time_s, b));
        pts.push((t1, b));
    }
    pts
}

fn beta_chart(
    area: &DrawingArea<SVGBackend<'_>, Shift>,
    caption: &str,
    runs: &[(&Episode, &str, RGBColor, f64)],
    path: &Path,
) -> Result<()> {
    let err = err(path);
    let t_end = runs.iter().map(|r| end_time(r.0)).fold(0.4, f64::max);
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..t_end, -2.0..1.4)
        .map_err(&err)?;
    chart
        .configure_mesh()
        .x_desc("time (s)")
        .y_desc("beta")
        .y_labels(4)
        .y_label_formatter(&|v| format!("{:+.0}", v))
        .draw()
        .map_err(&err)?;
    for &(e, label, colour, offset) in runs {
        chart
            .draw_series(LineSeries::new(beta_steps(e, offset), colour.stroke_width(2)))
            .map_err(&err)?
            .label(label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2)));
    }
    draw_legend(&mut chart, SeriesLabelPosition::LowerRight).map_err(&err)?;
    Ok(())
}

/// The ego's commanded beta over time.
pub fn beta_plot(path: &Path, e: &Episode) -> Result<()> {
    let root = SVGBackend::new(path, (1000, 360)).into_drawing_area();
    root.fill(&WHITE).map_err(err(path))?;
    beta_chart(
        &root,
        "Ego longitudinal maneuver beta (-1 decel, 0 cruise, +1 accel)",
        &[(e, "ego beta", EGO, 0.0)],
        path,
    )?;
    root.present().map_err(err(path))?;
    Ok(())
}

/// Case 2: beta over time with and without hysteresis.
pub fn ablation_plot(path: &Path, with: &Episode, without: &Episode) -> Result<()> {
    let root = SVGBackend::new(path, (1000, 420)).into_drawing_area();
    root.fill(&WHITE).map_err(err(path))?;
    let sw = crate::metrics::EpisodeMetrics::from_episode(with).beta_switches;
    let so = crate::metrics::EpisodeMetrics::from_episode(without).beta_switches;
    let l_with = format!("with hysteresis ({sw} switches)");
    let l_without = format!("without hysteresis ({so} switches)");
    beta_chart(
        &root,
        "Ablation: ego beta with vs. without hysteresis",
        &[
            (without, &l_without, RGBColor(200, 60, 60), -0.05),
            (with, &l_with, RGBColor(40, 90, 200), 0.05),
        ],
        path,
    )?;
    root.present().map_err(err(path))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(index: u64, ids: &[u32]) -> DecisionRecord {
        DecisionRecord {
            index,
            time_s: 0.4 * index as f64,
            layer: None,
            target_lane: 1,
            beta: 0,
            corrective_svs: ids.len(),
            corrective_sv_ids: ids.to_vec(),
            svs_sent: 0,
            ego_x_m: 0.0,
            ego_y_m: 0.0,
            ego_speed_mps: 0.0,
            plan: Vec::new(),
            solve_us: 0,
            request: None,
            nominal_class: None,
        }
    }

    #[test]
    fn corrective_phases_are_merged_per_reference_sv() {
        let d = [
            at(0, &[]),
            at(1, &[2]),
            at(2, &[2]),
            at(3, &[2, 5]),
            at(4, &[5]),
            at(5, &[]),
            at(6, &[2]),
        ];
        let by_sv = corrective_intervals_by_sv(&d, 0.4);
        let close = |a: &[(f64, f64)], b: &[(f64, f64)]| {
            a.len() == b.len()
                && a.iter()
                    .zip(b)
                    .all(|(x, y)| (x.0 - y.0).abs() < 1e-9 && (x.1 - y.1).abs() < 1e-9)
        };
        assert_eq!(by_sv.iter().map(|(id, _)| *id).collect::<Vec<_>>(), vec![2, 5]);
        assert!(close(&by_sv[0].1, &[(0.4, 1.6), (2.4, 2.8)]), "{:?}", by_sv[0].1);
        assert!(close(&by_sv[1].1, &[(1.2, 2.0)]), "{:?}", by_sv[1].1);
        assert!(close(&corrective_intervals(&d, 0.4), &[(0.4, 2.0), (2.4, 2.8)]));
    }
}
