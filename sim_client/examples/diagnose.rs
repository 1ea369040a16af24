//! Where the planner's beta switches and hard brakes come from, over a campaign slice: each
//! is counted by the layer of the decision in force, whether corrective mode was on and
//! whether a lane change was under way.
//!
//! `cargo run --release -p sim_client --example diagnose -- [scale] [seed] [config.toml]`
//!
//! Environment: `CAMPAIGN=FILE` runs the configurations of FILE (as `campaign --config`) instead
//! of Table I; `ONLY_CFG=N` runs one configuration; `SHOW=1` lists every hard-braking onset;
//! `SHOW_FALLBACK=1` every fallback with the SVs near the ego; `SHOW_TRACE=CFG:TRIAL` one
//! trial decision by decision (speed, state, plan, the leader); `NEAR_M` how far along the road
//! `SHOW_FALLBACK` lists SVs (80 m), `DUMP_FALLBACK=DIR` writes their situations as JSON for
//! `cargo run -p decision --example explain_fallback`; `SHOW_COUNTS=1` the beta
//! switches per trial; `SHOW_SAFETY=1` the trials with a DRAC above 3 m/s^2; `SHOW_NEAR=CFG:TRIAL`
//! the steps of one trial with a vehicle close beside (`NEAR_DY`, 3 m) or ahead of the ego; `SHOW_DRAC=CFG:TRIAL`
//! the steps of one trial with a DRAC above 3 m/s^2 or a TTC below 1 s, with the vehicles the
//! measures took for the ego's leader and follower (its lateral offset shows a lane change counted in both lanes);
//! `SHOW_CAUSES=1` what the decisions the nominal MPC could not answer (Layer A or B) were in
//! corrective mode for: an SV that cut in, the ego's own lane change, or an SV it closed in on,
//! and how long since the trigger. `SV_KEEP_LONG=P` and `SV_LANE_CHANGE=P` set the SVs' random
//! maneuver switches (as `campaign --sv-keep-long`, `--sv-lane-change`), `SV_SLOWDOWN=M/S2` their
//! slowdown's braking (as `--sv-slowdown-decel`).
use sim_client::campaign::{load_entries, paper_entries, scale_trials, trial_spec, CampaignSettings};
use sim_client::diagnosis::infeasibility_cause;
use sim_client::episode::{run_episode, run_episode_observed, Driver, StepObserver};
use sim_client::link::InProcess;
use sim_client::safety::{measure, Body};
use std::collections::BTreeMap;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let scale: f64 = args.get(1).map_or(Ok(0.03), |s| s.parse())?;
    let seed: u64 = args.get(2).map_or(Ok(2026), |s| s.parse())?;
    let entries = match std::env::var("CAMPAIGN") {
        Ok(path) => load_entries(std::path::Path::new(&path))?,
        Err(_) => paper_entries(),
    };
    let mut settings = CampaignSettings::new(scale_trials(&entries, scale)?, seed, 1);
    if let Some(path) = args.get(3) {
        settings.planner = decision::PlannerConfig::from_toml_str(&std::fs::read_to_string(path)?)?;
    }
    if let Ok(p) = std::env::var("SV_KEEP_LONG") {
        settings.params.sv.p_keep_long = p.parse()?;
    }
    if let Ok(p) = std::env::var("SV_LANE_CHANGE") {
        settings.params.sv.p_random_lane_change = p.parse()?;
    }
    if let Ok(d) = std::env::var("SV_SLOWDOWN") {
        settings.params.sv.gentle_decel = d.parse()?;
    }
    settings.params.validate()?;
    let mut switches: BTreeMap<String, u64> = BTreeMap::new();
    let mut brakes: BTreeMap<String, u64> = BTreeMap::new();
    let mut minutes = 0.0;
    let mut dwell: BTreeMap<String, u64> = BTreeMap::new();
    let mut causes: BTreeMap<String, u64> = BTreeMap::new();
    let show_causes = std::env::var("SHOW_CAUSES").is_ok();
    // How far along the road `SHOW_FALLBACK` lists SVs (`NEAR_M`, default 80 m).
    let near_m: f64 = std::env::var("NEAR_M").map_or(Ok(80.0), |v| v.parse())?;
    for e in &settings.entries {
        if std::env::var("ONLY_CFG").is_ok_and(|c| c != e.id.to_string()) {
            continue;
        }
        for trial in 0..e.trials {
            let mut spec = trial_spec(e, trial, &settings)?;
            spec.record_trajectory = true;
            let mut link = InProcess::new(settings.planner.clone())?;
            let ep = run_episode(&spec, Driver::Planner(&mut link))?;
            minutes += ep.simulated_s / 60.0;
            let d = &ep.decisions;
            if std::env::var("SHOW_SAFETY").is_ok() && ep.safety.max_drac_mps2 > 3.0 {
                println!(
                    "trial {}:{} min TTC {:?} max DRAC {:.2}",
                    e.id, trial, ep.safety.min_ttc_s, ep.safety.max_drac_mps2
                );
            }
            if std::env::var("SHOW_COUNTS").is_ok() {
                println!("trial {}:{} switches {}", e.id, trial, ep.metrics().beta_switches);
            }
            if show_causes {
                for k in (0..d.len()).filter(|&k| d[k].layer.is_some_and(|l| l != protocol::Layer::Nominal)) {
                    let cause = infeasibility_cause(d, k).map_or("no request".to_string(), |c| c.to_string());
                    *causes.entry(format!("{:?}: {cause}", d[k].layer.unwrap())).or_default() += 1;
                }
            }
            let mut last_switch: Option<usize> = None;
            for (k, w) in d.windows(2).enumerate() {
                if w[0].beta != w[1].beta {
                    if let Some(prev) = last_switch {
                        let key = format!("{}{}", if k - prev < 10 { " " } else { "" }, (k - prev).min(10));
                        *dwell.entry(key).or_default() += 1;
                        if k - prev == 1 {
                            let key = format!("pulse {:>2} {:>2} {:>2}", d[k - 1].beta, w[0].beta, w[1].beta);
                            *dwell.entry(key).or_default() += 1;
                        }
                    }
                    last_switch = Some(k);
                    let lc = w[1].target_lane != w[0].target_lane
                        || w[0].plan.iter().any(|p| p.maneuver.lane != w[1].target_lane);
                    let key = format!(
                        "{:>2}->{:>2} {:?} corr={} lc={}",
                        w[0].beta,
                        w[1].beta,
                        w[1].layer,
                        w[1].corrective_svs > 0,
                        lc
                    );
                    *switches.entry(key).or_default() += 1;
                }
            }
            if std::env::var("SHOW_FALLBACK").is_ok() {
                for r in d.iter().filter(|r| r.layer == Some(protocol::Layer::Fallback)) {
                    let Some(s) = r.request.as_ref().map(protocol::PlanRequest::to_situation) else {
                        continue;
                    };
                    if let Ok(dir) = std::env::var("DUMP_FALLBACK") {
                        let path = format!("{dir}/cfg{}-trial{}-t{:.1}.json", e.id, trial, r.time_s);
                        std::fs::write(path, serde_json::to_string(&s)?)?;
                    }
                    let ego = &s.ego;
                    let mut near: Vec<_> = s
                        .svs
                        .iter()
                        .filter(|sv| (sv.y_m - ego.y_m).abs() < 5.0 && (sv.x_m - ego.x_m).abs() < near_m)
                        .map(|sv| {
                            format!(
                                "[dx {:.1} dy {:.1} v {:.1} a {:.1} vy {:.2}]",
                                sv.x_m - ego.x_m,
                                sv.y_m - ego.y_m,
                                sv.v_mps,
                                sv.a_mps2,
                                sv.vy_mps
                            )
                        })
                        .collect();
                    near.sort();
                    println!(
                        "fallback cfg {} trial {} t={:.1} v={:.1} y={:.1} man {:?} -> lane {} beta {} near {}",
                        e.id,
                        trial,
                        r.time_s,
                        ego.v_mps,
                        ego.y_m,
                        ego.maneuver,
                        r.target_lane,
                        r.beta,
                        near.join(" ")
                    );
                }
            }
            if std::env::var("SHOW_DRAC").is_ok_and(|t| t == format!("{}:{}", e.id, trial)) {
                let mut link = InProcess::new(settings.planner.clone())?;
                run_episode_observed(&spec, Driver::Planner(&mut link), &mut DracSteps)?;
            }
            if std::env::var("SHOW_NEAR").is_ok_and(|t| t == format!("{}:{}", e.id, trial)) {
                show_near(&ep.trajectory);
            }
            if std::env::var("SHOW_TRACE").is_ok_and(|t| t == format!("{}:{}", e.id, trial)) {
                for r in d {
                    let Some(s) = r.request.as_ref().map(protocol::PlanRequest::to_situation) else {
                        continue;
                    };
                    let ego = &s.ego;
                    let lead = s
                        .svs
                        .iter()
                        .filter(|sv| (sv.y_m - ego.y_m).abs() < 1.5 && sv.x_m > ego.x_m)
                        .min_by(|a, b| a.x_m.total_cmp(&b.x_m));
                    let lead = lead.map_or("-".into(), |l| {
                        format!("gap {:.1} v {:.1} a {:.1}", l.x_m - ego.x_m - 5.0, l.v_mps, l.a_mps2)
                    });
                    let corr: Vec<String> = r
                        .corrective_sv_ids
                        .iter()
                        .filter_map(|id| s.svs.iter().find(|sv| sv.id == *id))
                        .map(|sv| {
                            format!(
                                "#{} dx {:.0} dy {:.1} v {:.1}",
                                sv.id,
                                sv.x_m - ego.x_m,
                                sv.y_m - ego.y_m,
                                sv.v_mps
                            )
                        })
                        .collect();
                    let lead = format!("{lead} | corr [{}]", corr.join(", "));
                    let a0 = ep
                        .trajectory
                        .iter()
                        .find(|t| t.id == 0 && (t.time_s - r.time_s - 0.4).abs() < 1e-6)
                        .map_or(0.0, |t| t.a_mps2);
                    println!(
                        "t={:5.1} v={:5.2} beta {:>2} lane {} corr {} layer {:?} a_end {:5.2} plan {:?} | {}",
                        r.time_s,
                        ego.v_mps,
                        r.beta,
                        r.target_lane,
                        r.corrective_svs,
                        r.layer,
                        a0,
                        r.plan
                            .iter()
                            .map(|p| (p.maneuver.beta, (p.v_mps * 10.0).round() / 10.0))
                            .collect::<Vec<_>>(),
                        lead
                    );
                }
            }
            let ego: Vec<_> = ep.trajectory.iter().filter(|s| s.id == 0).collect();
            let mut braking = false;
            for s in &ego {
                let b = s.a_mps2 <= -2.5;
                if b && !braking {
                    let k = d.iter().rposition(|r| r.time_s <= s.time_s + 1e-9).unwrap_or(0);
                    let r = &d[k];
                    let key = format!(
                        "{:?} corr={} lc={}",
                        r.layer,
                        r.corrective_svs > 0,
                        s.lane != s.target_lane
                    );
                    *brakes.entry(key).or_default() += 1;
                    if std::env::var("SHOW").is_ok() {
                        println!(
                            "brake cfg {} trial {} t={:.1} a={:.2} v={:.1} lane {}->{} layer {:?} corr {}",
                            e.id, trial, s.time_s, s.a_mps2, s.v_mps, s.lane, s.target_lane, r.layer, r.corrective_svs
                        );
                    }
                }
                braking = b;
            }
        }
    }
    println!("minutes {minutes:.1}");
    println!("decisions between switches: {dwell:?}");
    println!(
        "beta switches ({:.2}/min):",
        switches.values().sum::<u64>() as f64 / minutes
    );
    for (k, v) in &switches {
        println!("  {k}: {v}");
    }
    println!(
        "hard brake onsets ({:.1}/h):",
        brakes.values().sum::<u64>() as f64 / minutes * 60.0
    );
    for (k, v) in &brakes {
        println!("  {k}: {v}");
    }
    if show_causes {
        let total = causes.values().sum::<u64>().max(1) as f64;
        println!("decisions not answered by the nominal MPC, by what they were corrective for:");
        for (k, v) in &causes {
            println!("  {k}: {v} ({:.1} %)", 100.0 * *v as f64 / total);
        }
    }
    Ok(())
}

/// Every recorded step with a vehicle within 8 m of the ego and less than 3 m beside it: the
/// ego and the vehicles within 40 m.
fn show_near(trajectory: &[sim_client::episode::VehicleState]) {
    // How far to the side a vehicle counts as close (`NEAR_DY`, default 3 m).
    let near_dy: f64 = std::env::var("NEAR_DY")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3.0);
    let mut steps: BTreeMap<u64, Vec<&sim_client::episode::VehicleState>> = BTreeMap::new();
    for v in trajectory {
        steps.entry(v.step).or_default().push(v);
    }
    for vs in steps.values() {
        let Some(ego) = vs.iter().find(|v| v.id == 0) else {
            continue;
        };
        if !vs
            .iter()
            .any(|v| v.id != 0 && (v.x_m - ego.x_m).abs() < 8.0 && (v.y_m - ego.y_m).abs() < near_dy)
        {
            continue;
        }
        print!(
            "t {:5.1} ego x {:7.1} y {:5.2} v {:5.2} a {:5.2} lane {}->{} b {:2} |",
            ego.time_s, ego.x_m, ego.y_m, ego.v_mps, ego.a_mps2, ego.lane, ego.target_lane, ego.beta
        );
        for v in vs.iter().filter(|v| v.id != 0 && (v.x_m - ego.x_m).abs() < 40.0) {
            print!(
                " #{} dx {:6.1} y {:5.2} v {:5.2} {}->{};",
                v.id,
                v.x_m - ego.x_m,
                v.y_m,
                v.v_mps,
                v.lane,
                v.target_lane
            );
        }
        println!();
    }
}

/// Prints every step with a DRAC above 3 m/s^2 or a TTC below 1 s, and the vehicles within
/// 12 m along the road.
struct DracSteps;

impl StepObserver for DracSteps {
    fn after_step(&mut self, world: &mut traffic::World) -> sim_client::Result<()> {
        let bodies = Body::all(world);
        let m = measure(&bodies);
        let (drac, ttc) = (m.drac_mps2.unwrap_or(0.0), m.ttc_s().unwrap_or(f64::INFINITY));
        if drac <= 3.0 && ttc >= 1.0 {
            return Ok(());
        }
        let (ego, ego_y) = (&bodies[0], world.vehicles()[0].y);
        print!(
            "t {:5.1} DRAC {drac:6.1} TTC {ttc:5.2} ego v {:5.2} lanes {:?} changing {} |",
            world.time(),
            ego.v,
            ego.lanes,
            ego.changing_lanes
        );
        for (b, v) in bodies.iter().zip(world.vehicles()).skip(1) {
            if (b.x - ego.x).abs() < 12.0 {
                print!(
                    " #{} dx {:.1} dy {:.2} v {:.2} lanes {:?} changing {};",
                    b.id,
                    b.x - ego.x,
                    v.y - ego_y,
                    b.v,
                    b.lanes,
                    b.changing_lanes
                );
            }
        }
        println!();
        Ok(())
    }
}
