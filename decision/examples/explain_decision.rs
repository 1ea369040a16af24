//! Which SV (or the hysteresis memory) drives a decision: each situation is decided again
//! without one SV at a time, and without the corrective memory; every change of the first
//! step's acceleration by more than 0.5 m/s^2 is printed.
//!
//! `cargo run --release -p decision --example explain_decision -- SITUATIONS.jsonl [CONFIG.toml]`
//! with one JSON object per line: `{"where": "...", "accel": <the answer then>, "situation":
//! <a Situation>}` (`clients/sumo/trace_situations.py` writes them from SUMO's traces,
//! `sim_client campaign --trace-hard-braking` from a campaign's).
use decision::{Planner, PlannerConfig, Situation};

/// The least change of the first step's acceleration that is reported, m/s^2.
const CHANGE_MPS2: f64 = 0.5;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(input) = args.first() else {
        return Err("usage: explain_decision SITUATIONS.jsonl [CONFIG.toml]".into());
    };
    let config = match args.get(1) {
        Some(p) => PlannerConfig::from_toml_str(&std::fs::read_to_string(p)?)?,
        None => PlannerConfig::default(),
    };
    let mut planner = Planner::new(config)?;
    for line in std::fs::read_to_string(input)?.lines() {
        let v: serde_json::Value = serde_json::from_str(line)?;
        let s: Situation = serde_json::from_value(v["situation"].clone())?;
        let d = planner.decide(&s)?;
        let ego = &s.ego;
        let memory: Vec<_> = s
            .memory
            .corrective
            .iter()
            .map(|c| (c.sv_id, c.trigger_m.round(), c.release_m.round()))
            .collect();
        println!(
            "{}: then {:.2}, now {:.2} m/s^2 ({:?}); ego v {:.1} {:?}; corrective (sv, trigger, release) {memory:?}",
            v["where"].as_str().unwrap_or("?"),
            v["accel"].as_f64().unwrap_or(f64::NAN),
            d.setpoint.accel_mps2,
            d.layer,
            ego.v_mps,
            ego.maneuver,
        );
        for (i, sv) in s.svs.iter().enumerate() {
            let mut without = s.clone();
            without.svs.remove(i);
            without.memory.corrective.retain(|c| c.sv_id != sv.id);
            let changed = planner.decide(&without)?.setpoint.accel_mps2;
            if (changed - d.setpoint.accel_mps2).abs() > CHANGE_MPS2 {
                println!(
                    "  without SV {} (dx {:.1} m, y {:.1} m, v {:.1} m/s, a {:.2}, vy {:.2}): {changed:.2}",
                    sv.id,
                    sv.x_m - ego.x_m,
                    sv.y_m,
                    sv.v_mps,
                    sv.a_mps2,
                    sv.vy_mps
                );
            }
        }
        let mut forgetful = s.clone();
        forgetful.memory.corrective.clear();
        let changed = planner.decide(&forgetful)?.setpoint.accel_mps2;
        if (changed - d.setpoint.accel_mps2).abs() > CHANGE_MPS2 {
            println!("  without the corrective memory: {changed:.2}");
        }
    }
    Ok(())
}
