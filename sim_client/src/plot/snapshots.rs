//! The road at representative instants (the paper's Figs. 2 and 4): vehicles, the ego's plan
//! and the SVs' predicted branches as semi-transparent strips coloured by beta.

use std::path::Path;

use plotters::prelude::*;
use traffic::Scenario;

use super::{beta_colour, err, sv_colour, EGO};
use crate::episode::{Episode, VehicleState};
use crate::error::Result;
use crate::prediction::SvPrediction;

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

/// The road at the decision instants `picks`: vehicles as rectangles, the ego's planned
/// maneuvers over the horizon as strips coloured by beta (green decel, purple cruise, red
/// accel), and every kept branch of the SVs' predictions as one thin row each
/// (`predictions[i]` for `picks[i]`; opacity grows with the branch probability).
pub fn snapshots_plot(
    path: &Path,
    scenario: &Scenario,
    e: &Episode,
    picks: &[usize],
    predictions: &[Vec<SvPrediction>],
) -> Result<()> {
    let err = err(path);
    let picks: Vec<usize> = picks.iter().copied().filter(|&k| k < e.decisions.len()).collect();
    let root = SVGBackend::new(path, (1100, 220 * picks.len().max(1) as u32)).into_drawing_area();
    root.fill(&WHITE).map_err(&err)?;
    let lanes = scenario.road.lanes;
    let w = scenario.road.lane_width;
    let y_lo = -w / 2.0;
    let y_hi = (f64::from(lanes) - 0.5) * w;
    let lane_y = |lane: u8| f64::from(lanes - lane.min(lanes)) * w;
    let steps_per_decision = (e.decision_period_s / 0.1).round() as u64;
    let areas = root.split_evenly((picks.len().max(1), 1));
    for (slot, (area, &k)) in areas.iter().zip(&picks).enumerate() {
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
        // SV predictions: one thin row per branch inside the lane band (most probable at the
        // bottom), so that overlapping branches keep their colours.
        let clip = |x: f64| x.clamp(x0, x1);
        for prediction in predictions.get(slot).into_iter().flatten() {
            let rows = prediction.branches.len().max(1) as f64;
            let row = 1.8 / rows;
            for (i, branch) in prediction.branches.iter().enumerate() {
                let alpha = 0.25 + 0.6 * branch.probability;
                let lo = -0.9 + i as f64 * row;
                chart
                    .draw_series(branch.steps.iter().map(|s| {
                        let yc = lane_y(s.lane);
                        Rectangle::new(
                            [
                                (clip(s.x_from_m), yc + lo),
                                (clip(s.x_to_m.max(s.x_from_m + 0.5)), yc + lo + 0.85 * row),
                            ],
                            beta_colour(s.beta).mix(alpha).filled(),
                        )
                    }))
                    .map_err(&err)?;
            }
        }
        // The ego's planned maneuvers over the horizon.
        let mut from = d.ego_x_m;
        for p in &d.plan {
            let yc = lane_y(p.maneuver.lane);
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
