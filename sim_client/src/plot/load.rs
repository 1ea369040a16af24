//! Figures of the load tool: latency distribution and time series.

use std::path::Path;

use plotters::prelude::*;

use super::{draw_legend, err, BETA_DECEL, EGO, SV_COLOURS};
use crate::error::Result;

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
    draw_legend(&mut chart, SeriesLabelPosition::UpperLeft).map_err(&err)?;
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
    draw_legend(&mut chart, SeriesLabelPosition::LowerRight).map_err(&err)?;
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
        draw_legend(&mut chart, SeriesLabelPosition::LowerRight).map_err(&err)?;
    }
    root.present().map_err(&err)?;
    Ok(())
}
