//! Why a situation ends in the fallback: an emergency (an SV ahead that only braking beyond
//! the MPC's range keeps the ego behind, docs/emergency-braking.md), or which SVs make the
//! nominal problem and Layer A infeasible on their own (the exact oracle solved with one SV
//! at a time).
//!
//! `cargo run --release -p decision --example explain_fallback -- SITUATION.json... [--config F]`
//! (situations as `sim_client/examples/diagnose.rs` writes them with `DUMP_FALLBACK`).
use decision::prepare;
use decision::Mode;
use decision::{Planner, PlannerConfig, Situation};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let mut config = PlannerConfig::default();
    if let Some(i) = args.iter().position(|a| a == "--config") {
        let path = args.remove(i + 1);
        args.remove(i);
        config = PlannerConfig::from_toml_str(&std::fs::read_to_string(path)?)?;
    }
    for path in &args {
        let situation: Situation = serde_json::from_str(&std::fs::read_to_string(path)?)?;
        let problem = prepare(&config, &situation).problem;
        let ego = &situation.ego;
        println!(
            "{path}: ego x {:.1} y {:.1} v {:.2} {:?}, occupancy {:?}",
            ego.x_m, ego.y_m, ego.v_mps, ego.maneuver, problem.ego.occupancy
        );
        // Emergencies are answered before the MPC is asked: the layers' costs do not apply.
        // A situation the planner refuses is said so, and the others still explained.
        match Planner::new(config.clone())?.decide(&situation) {
            Ok(d) if d.stats.emergency => {
                let threat = d
                    .stats
                    .fallback_threat
                    .map_or_else(|| "no".to_string(), |t| format!("{t:?}").to_lowercase());
                println!(
                    "  emergency: Layer B brakes at {:.2} m/s^2 without asking the MPC ({threat} threat)",
                    -d.setpoint.accel_mps2
                );
                continue;
            }
            Ok(_) => {}
            Err(e) => {
                println!("  refused: {e}");
                continue;
            }
        }
        for mode in [Mode::Nominal, Mode::Relaxed] {
            let (best, count) = decision::solve_by_enumeration(&problem, mode);
            println!(
                "  {mode:?}: {} ({count} sequences)",
                best.map_or("infeasible".into(), |e| format!("cost {:.2}", e.cost))
            );
        }
        for (i, c) in problem.svs.iter().enumerate() {
            let mut alone = problem.clone();
            alone.svs = vec![problem.svs[i].clone()];
            let feasible = |mode| decision::solve_by_enumeration(&alone, mode).0.is_some();
            if feasible(Mode::Nominal) {
                continue;
            }
            let sv = situation
                .svs
                .iter()
                .find(|s| s.id == c.id)
                .expect("the problem's SVs come from the situation");
            println!(
                "  SV {} alone infeasible (Layer A {}): dx {:.1} y {:.1} v {:.2} a {:.2} vy {:.2} ahead {} d_idm {:.1} hard {:?} allowance {:?} floor_allowance {:?} corrective {:?}",
                c.id,
                if feasible(Mode::Relaxed) { "feasible" } else { "infeasible" },
                sv.x_m - ego.x_m,
                sv.y_m,
                sv.v_mps,
                sv.a_mps2,
                sv.vy_mps,
                c.ahead,
                c.d_idm,
                round(&c.hard),
                round(&c.allowance),
                round(&c.floor_allowance),
                c.corrective
            );
            for b in &c.branches {
                println!(
                    "    branch p {:.2} x {:?} v {:?} lanes {:?}",
                    b.probability,
                    round(&b.x.iter().map(|x| x - ego.x_m).collect::<Vec<_>>()),
                    round(&b.v),
                    b.occupancy
                );
            }
        }
    }
    Ok(())
}

fn round(v: &[f64]) -> Vec<f64> {
    v.iter().map(|x| (x * 10.0).round() / 10.0).collect()
}
