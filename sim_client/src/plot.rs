//! SVG figures in the style of the paper's Figs. 2-6 (plotters, SVG backend, no fonts needed).

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use traffic::Scenario;

use crate::episode::{DecisionRecord, Episode, VehicleState};
use crate::error::{Result, SimClientError};

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
const CORRECTIVE: RGBColor = RGBColor(255, 220, 90);
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

fn ids(trajectory: &[VehicleState]) -> Vec<u32> {
    let mut ids: Vec<u32> = trajectory.iter().map(|s| s.id).collect();
    ids.sort_unstable();
    ids.dedup();
    ids
}

/// Time intervals with at least one SV in corrective mode, merged.
pub fn corrective_intervals(decisions: &[DecisionRecord], period: f64) -> Vec<(f64, f64)> {
    let mut out: Vec<(f64, f64)> = Vec::new();
    for d in decisions.iter().filter(|d| d.corrective_svs > 0) {
        let (a, b) = (d.time_s, d.time_s + period);
        match out.last_mut() {
            Some(last) if (last.1 - a).abs() < 1e-6 => last.1 = b,
            _ => out.push((a, b)),
        }
    }
    out
}

fn end_time(e: &Episode) -> f64 {
    e.simulated_s.max(e.decision_period_s)
}

/// Ego and SV speeds over time; corrective-mode intervals shaded yellow.
pub fn speed_plot(path: &Path, e: &Episode) -> Result<()> {
    let err = err(path);
    let root = SVGBackend::new(path, (1000, 480)).into_drawing_area();
    root.fill(&WHITE).map_err(&err)?;
    let vmax = e.trajectory.iter().map(|s| s.v_mps).fold(1.0, f64::max) * 1.1;
    let t_end = end_time(e);
    let mut chart = ChartBuilder::on(&root)
        .caption("Speed: ego vs. SVs (shaded: corrective mode)", ("sans-serif", 20))
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
    chart
        .draw_series(
            corrective_intervals(&e.decisions, e.decision_period_s)
                .into_iter()
                .map(|(a, b)| Rectangle::new([(a, 0.0), (b.min(t_end), vmax)], CORRECTIVE.mix(0.35).filled())),
        )
        .map_err(&err)?
        .label("corrective mode")
        .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], CORRECTIVE.mix(0.6).filled()));
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
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(&err)?;
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
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(&err)?;
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

/// Four decision instants for the snapshots: the start, the first corrective decision, the
/// first lane change and a later instant, filled with evenly spaced ones when missing.
pub fn snapshot_instants(e: &Episode) -> Vec<usize> {
    let n = e.decisions.len();
    if n == 0 {
        return Vec::new();
    }
    let mut picks = vec![0usize];
    if let Some(k) = e.decisions.iter().position(|d| d.corrective_svs > 0) {
        picks.push(k);
    }
    let mut lane = e.initial_lane;
    let first_change = e.decisions.iter().position(|d| {
        let changed = d.target_lane != lane;
        lane = d.target_lane;
        changed
    });
    if let Some(k) = first_change {
        picks.push(k);
        picks.push((k + 10).min(n - 1));
    }
    picks.sort_unstable();
    picks.dedup();
    picks.truncate(4);
    // Fill up with the instants farthest from those already chosen.
    while picks.len() < 4.min(n) {
        let far = (0..n)
            .max_by_key(|c| {
                let d = picks.iter().map(|p| p.abs_diff(*c)).min().unwrap_or(n);
                (d, std::cmp::Reverse(*c))
            })
            .expect("n > 0");
        picks.push(far);
        picks.sort_unstable();
    }
    picks.truncate(4);
    picks
}

/// The road at four instants: vehicles as rectangles and the ego's planned maneuvers over the
/// horizon as semi-transparent strips coloured by beta (green decel, purple cruise, red accel).
pub fn snapshots_plot(path: &Path, scenario: &Scenario, e: &Episode) -> Result<()> {
    let err = err(path);
    let picks = snapshot_instants(e);
    let root = SVGBackend::new(path, (1100, 220 * picks.len().max(1) as u32)).into_drawing_area();
    root.fill(&WHITE).map_err(&err)?;
    let lanes = scenario.road.lanes;
    let w = scenario.road.lane_width;
    let y_lo = -w / 2.0;
    let y_hi = (f64::from(lanes) - 0.5) * w;
    let steps_per_decision = (e.decision_period_s / 0.1).round() as u64;
    let areas = root.split_evenly((picks.len().max(1), 1));
    for (area, &k) in areas.iter().zip(&picks) {
        let d = &e.decisions[k];
        let step = d.index * steps_per_decision;
        let states: Vec<&VehicleState> = e.trajectory.iter().filter(|s| s.step == step).collect();
        let x0 = d.ego_x_m - 80.0;
        let x1 = d.ego_x_m + 170.0;
        let mut chart = ChartBuilder::on(area)
            .caption(format!("t = {:.1} s", d.time_s), ("sans-serif", 16))
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(40)
            .build_cartesian_2d(x0..x1, y_lo..y_hi)
            .map_err(&err)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc("x (m)")
            .y_desc("y (m)")
            .draw()
            .map_err(&err)?;
        // Lane boundaries.
        chart
            .draw_series((0..=lanes).map(|b| {
                let y = (f64::from(b) - 0.5) * w;
                let style = if b == 0 || b == lanes {
                    BLACK.stroke_width(2)
                } else {
                    RGBColor(150, 150, 150).stroke_width(1)
                };
                PathElement::new(vec![(x0, y), (x1, y)], style)
            }))
            .map_err(&err)?;
        // Planned maneuvers over the horizon.
        let mut from = d.ego_x_m;
        for p in &d.plan {
            let yc = f64::from(lanes - p.maneuver.lane.min(lanes)) * w;
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(from, yc - 0.9), (p.x_m.max(from + 0.5), yc + 0.9)],
                    beta_colour(p.maneuver.beta).mix(0.35).filled(),
                )))
                .map_err(&err)?;
            from = p.x_m;
        }
        // Vehicles.
        for s in states.iter().filter(|s| s.x_m - 2.5 >= x0 && s.x_m + 12.0 <= x1) {
            let colour = if s.id == 0 { EGO } else { sv_colour(s.id) };
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(s.x_m - 2.5, s.y_m - 1.0), (s.x_m + 2.5, s.y_m + 1.0)],
                    colour.filled(),
                )))
                .map_err(&err)?;
            let label = if s.id == 0 {
                format!("EV {:.1}", s.v_mps)
            } else {
                format!("SV{} {:.1}", s.id, s.v_mps)
            };
            chart
                .draw_series(std::iter::once(Text::new(
                    label,
                    (s.x_m - 4.0, s.y_m + 1.9),
                    ("sans-serif", 11).into_font(),
                )))
                .map_err(&err)?;
        }
    }
    root.present().map_err(&err)?;
    Ok(())
}

/// The round-trip distribution of a load run: latency against the percentile, on "nines"
/// (1 = p90, 2 = p99, 3 = p99.9), with the deadline for reference.
pub fn latency_plot(path: &Path, report: &crate::load::LoadReport) -> Result<()> {
    let err = err(path);
    let root = SVGBackend::new(path, (900, 480)).into_drawing_area();
    root.fill(&WHITE).map_err(&err)?;
    let deadline_us = report.deadline_ms * 1e3;
    let top = report
        .round_trip_spectrum
        .iter()
        .map(|&(_, v)| v as f64)
        .fold(deadline_us, f64::max)
        * 1.5;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!(
                "Round trip over {}: {} vehicles at {} Hz",
                report.transport, report.clients, report.rate_hz
            ),
            ("sans-serif", 20),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..5.0, (10.0..top).log_scale())
        .map_err(&err)?;
    chart
        .configure_mesh()
        .x_desc("percentile (1 = p90, 2 = p99, 3 = p99.9, 4 = p99.99)")
        .y_desc("round trip (us)")
        .draw()
        .map_err(&err)?;
    chart
        .draw_series(LineSeries::new(
            report
                .round_trip_spectrum
                .iter()
                .map(|&(n, v)| (n, (v as f64).max(10.0))),
            EGO.stroke_width(2),
        ))
        .map_err(&err)?
        .label("round trip")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], EGO.stroke_width(2)));
    chart
        .draw_series(LineSeries::new(
            [(0.0, deadline_us), (5.0, deadline_us)],
            BLACK.stroke_width(1),
        ))
        .map_err(&err)?
        .label("deadline")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(1)));
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(&err)?;
    root.present().map_err(&err)?;
    Ok(())
}

/// The time series of a load run: decisions in time and misses per second; the planner's RSS
/// and CPU when they were sampled.
pub fn load_timeline_plot(path: &Path, report: &crate::load::LoadReport) -> Result<()> {
    let err = err(path);
    let root = SVGBackend::new(path, (1000, 640)).into_drawing_area();
    root.fill(&WHITE).map_err(&err)?;
    let (upper, lower) = root.split_vertically(320);
    let t_end = report.timeline.last().map_or(1.0, |p| p.t_s).max(1.0);
    let period = match report.timeline.as_slice() {
        [first, ..] => first.t_s.max(1e-3),
        [] => 1.0,
    };
    let rate_max = report
        .timeline
        .iter()
        .map(|p| (p.in_time + p.misses) as f64 / period)
        .fold(1.0, f64::max)
        * 1.2;
    let mut chart = ChartBuilder::on(&upper)
        .caption("Decisions per second", ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..t_end, 0.0..rate_max)
        .map_err(&err)?;
    chart
        .configure_mesh()
        .x_desc("time (s)")
        .y_desc("per second")
        .draw()
        .map_err(&err)?;
    for (name, colour, value) in [
        (
            "in time",
            BETA_DECEL,
            (|p: &crate::load::TimelinePoint| p.in_time) as fn(&_) -> u64,
        ),
        ("deadline misses", EGO, |p: &crate::load::TimelinePoint| p.misses),
    ] {
        chart
            .draw_series(LineSeries::new(
                report.timeline.iter().map(|p| (p.t_s, value(p) as f64 / period)),
                colour.stroke_width(2),
            ))
            .map_err(&err)?
            .label(name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2)));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(&err)?;
    if let Some(planner) = &report.planner {
        let rss_max = planner
            .samples
            .iter()
            .map(|s| s.rss_kib as f64 / 1024.0)
            .fold(1.0, f64::max)
            * 1.2;
        let mut chart = ChartBuilder::on(&lower)
            .caption(
                "Planner process: RSS (MiB) and CPU (% of one core / 10)",
                ("sans-serif", 18),
            )
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..t_end, 0.0..rss_max.max(20.0))
            .map_err(&err)?;
        chart.configure_mesh().x_desc("time (s)").draw().map_err(&err)?;
        chart
            .draw_series(LineSeries::new(
                planner.samples.iter().map(|s| (s.t_s, s.rss_kib as f64 / 1024.0)),
                SV_COLOURS[0].stroke_width(2),
            ))
            .map_err(&err)?
            .label("RSS (MiB)")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], SV_COLOURS[0].stroke_width(2)));
        chart
            .draw_series(LineSeries::new(
                planner.samples.iter().map(|s| (s.t_s, s.cpu_percent / 10.0)),
                SV_COLOURS[2].stroke_width(2),
            ))
            .map_err(&err)?
            .label("CPU (% / 10)")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], SV_COLOURS[2].stroke_width(2)));
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(&err)?;
    }
    root.present().map_err(&err)?;
    Ok(())
}
