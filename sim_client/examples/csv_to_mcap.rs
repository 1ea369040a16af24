//! Converts a CSV of vehicle trajectories into a traffic recording that `sim_client replay`
//! reads: the pattern for turning another simulator's output or a real drive into a test.
//!
//! The CSV has a header and one row per vehicle and step with the columns of
//! `trajectory.csv` (what `sim_client case1` writes): `step,time_s,id,x_m,y_m,v_mps,a_mps2,
//! lane,target_lane,beta`; only `step`, `time_s`, `id`, `x_m`, `y_m` and `v_mps` must have
//! values (the others may be empty). Id 0 is the ego. Rows come at every low-level step.
//!
//! ```text
//! cargo run -p sim_client --example csv_to_mcap -- out/case1/trajectory.csv traffic.mcap \
//!     [lanes lane_width_m speed_limit_mps ego_desired_speed_mps]
//! sim_client replay traffic.mcap
//! ```

use std::collections::BTreeMap;

use anyhow::{Context, Result};
use recording::{McapSink, Rotation};
use sim_client::record::{channels, RecordedVehicle, TrialInfo, VehicleStates};

#[derive(serde::Deserialize)]
struct Row {
    step: u64,
    time_s: f64,
    id: u32,
    x_m: f64,
    y_m: f64,
    v_mps: f64,
    a_mps2: Option<f64>,
    lane: Option<u8>,
    target_lane: Option<u8>,
    beta: Option<i8>,
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [input, output, rest @ ..] = args.as_slice() else {
        anyhow::bail!(
            "usage: csv_to_mcap TRAJECTORY.csv OUT.mcap [lanes lane_width_m speed_limit_mps ego_desired_speed_mps]"
        );
    };
    // Case 1's road (Table II) unless given.
    let number = |i: usize, default: f64| -> Result<f64> {
        rest.get(i)
            .map_or(Ok(default), |s| s.parse().with_context(|| format!("argument {s}")))
    };
    let mut steps: BTreeMap<u64, VehicleStates> = BTreeMap::new();
    let mut reader = csv::Reader::from_path(input).with_context(|| format!("reading {input}"))?;
    for row in reader.deserialize::<Row>() {
        let r = row.with_context(|| format!("a row of {input}"))?;
        steps
            .entry(r.step)
            .or_insert_with(|| VehicleStates {
                step: r.step,
                time_s: r.time_s,
                vehicles: Vec::new(),
            })
            .vehicles
            .push(RecordedVehicle {
                id: r.id,
                x_m: r.x_m,
                y_m: r.y_m,
                v_mps: r.v_mps,
                a_mps2: r.a_mps2.unwrap_or(0.0),
                vy_mps: 0.0,
                lane: r.lane.unwrap_or(0),
                target_lane: r.target_lane.unwrap_or(0),
                beta: r.beta.unwrap_or(0),
            });
    }
    let times: Vec<f64> = steps.values().take(2).map(|s| s.time_s).collect();
    let dt = match times.as_slice() {
        [a, b] => b - a,
        _ => anyhow::bail!("{input}: fewer than two steps"),
    };
    let info = TrialInfo {
        label: format!("converted from {input}"),
        seed: 0,
        lanes: number(0, 2.0)? as u8,
        lane_width_m: number(1, 4.0)?,
        speed_limit_mps: number(2, 40.0)?,
        ego_desired_speed_mps: number(3, 25.0)?,
        low_level_step_s: dt,
        max_svs: 0,
        params: None,
    };
    let mut sink = McapSink::create(output.as_ref(), channels(), Rotation::default())?;
    sink.write_json(0, 0, &info)?;
    for s in steps.values() {
        sink.write_json(1, (s.time_s * 1e9).round() as u64, s)?;
    }
    sink.finish()?;
    println!("wrote {output}: {} steps of {} s", steps.len(), dt);
    Ok(())
}
