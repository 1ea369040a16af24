//! The SUMO bridge (`clients/sumo/hmdp_sumo.py`) against the real planner binary, with SUMO
//! as the judge.
//!
//! The bridge runs a small scenario (`clients/sumo/scenarios/test-small.toml`, two seeded
//! 20 s episodes) with the planner and with SUMO's own Krauss ego. What it reports is held to
//! SUMO's own output files, read here without the bridge's code: the collisions SUMO wrote,
//! its SSM log, and the ego's trajectory SUMO recorded (`--device.fcd.explicit ego`). From
//! that trajectory: every set-point the planner gave was applied (the speed one period later
//! is the set-point's target speed), every lane change it decided happened in SUMO and no
//! other did, and the positions sent to the planner are SUMO's (centre = front - length / 2,
//! lane 1 = SUMO's leftmost lane). From the bridge's decision trace: the planner's memory and
//! maneuver are carried from each answer to the next request.
//!
//! Needs python3 with SUMO, traci, sumolib and zenoh (`scripts/install-build-deps` installs
//! clients/sumo/requirements.txt); without them the tests fail. The `planner` binary must be
//! built (`cargo build -p planner`, or run under `cargo test --workspace`).

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use serde_json::Value;
use system_tests::run_to_end;

/// A bridge run that takes longer than this is hung: killed, and the test fails.
const BRIDGE_LIMIT: Duration = Duration::from_secs(240);
/// The planner's period and the lane change duration the bridge gives SUMO.
const PERIOD_S: f64 = 0.4;
const LANE_CHANGE_S: f64 = 3.0;
/// The ego's length (the bridge's ego vType): centre = front - length / 2.
const EGO_LENGTH_M: f64 = 5.0;
/// The SSM figures start this long after the ego's entry (judge.SETTLE_S).
const SETTLE_S: f64 = 5.0;
/// SUMO writes its outputs with 2 decimals.
const SUMO_ROUNDING: f64 = 0.006;
const EPISODES: usize = 2;
/// The bridge's `--speed-split-s` here: within the small scenario's 20 s episodes.
const SPEED_SPLIT_S: f64 = 10.0;
const LANES: u8 = 3;
const LANE_WIDTH_M: f64 = 3.5;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Fails (never skips) when SUMO or the Python modules are missing: CI installs them.
fn require_sumo() {
    if let Err(why) = system_tests::python_can_import("sumo, traci, sumolib, zenoh") {
        panic!(
            "python3 cannot import sumo, traci, sumolib and zenoh: run scripts/install-build-deps (it installs \
             clients/sumo/requirements.txt)\n{why}"
        );
    }
}

/// Runs `python3 args` (in the repository) to its end, its output in `dir`, within
/// BRIDGE_LIMIT; (exit code, stdout, stderr).
fn run_python(dir: &Path, args: &[&str]) -> (i32, String, String) {
    let run = run_to_end(
        Command::new("python3").args(args).current_dir(repo()),
        dir,
        "python",
        BRIDGE_LIMIT,
    );
    (run.code, run.stdout, run.stderr)
}

/// The elements named `tag` of an XML document, as attribute maps. SUMO's outputs are plain
/// XML whose attribute values hold no `<`, `>` or `"`: a scanner is enough.
fn elements(xml: &str, tag: &str) -> Vec<HashMap<String, String>> {
    let open = format!("<{tag}");
    let mut out = Vec::new();
    let mut rest = xml;
    while let Some(start) = rest.find(&open) {
        let after = &rest[start + open.len()..];
        if !after.starts_with([' ', '>', '/', '\n', '\t']) {
            rest = after;
            continue; // a longer tag name
        }
        let end = after.find('>').expect("element closed");
        let mut attrs = HashMap::new();
        let mut body = &after[..end];
        while let Some(eq) = body.find("=\"") {
            let key = body[..eq].trim().to_string();
            let value_end = body[eq + 2..].find('"').expect("attribute closed");
            attrs.insert(key, body[eq + 2..eq + 2 + value_end].to_string());
            body = &body[eq + 2 + value_end + 1..];
        }
        out.push(attrs);
        rest = &after[end..];
    }
    out
}

/// The text between `<tag` (an element with `attr="value"`) and its `</tag>`.
fn element_body<'a>(xml: &'a str, tag: &str, attr: &str) -> Option<&'a str> {
    let start = xml.find(&format!("<{tag} {attr}"))?;
    let end = xml[start..].find(&format!("</{tag}>"))?;
    Some(&xml[start..start + end])
}

fn number(s: &str) -> f64 {
    s.parse().unwrap_or_else(|_| panic!("not a number: {s}"))
}

fn tenth(t: f64) -> i64 {
    (t * 10.0).round() as i64
}

/// One sample of the ego's trajectory as SUMO recorded it.
#[derive(Debug, Clone)]
struct EgoSample {
    sumo_lane: u8,
    front_m: f64,
    y_m: f64,
    speed: f64,
}

/// The ego's trajectory from SUMO's FCD output, by time in tenths of a second, on TraCI's
/// clock: SUMO labels an output step with the time at the step's start, TraCI reports the
/// time at its end (the bridge's times), one step later.
fn ego_trajectory(fcd: &str) -> BTreeMap<i64, EgoSample> {
    let mut samples = BTreeMap::new();
    let mut time = None;
    for chunk in fcd.split('<').skip(1) {
        let element = format!("<{chunk}");
        if element.starts_with("<timestep") {
            time = Some(number(&elements(&element, "timestep")[0]["time"]));
        } else if element.starts_with("<vehicle") {
            let v = &elements(&element, "vehicle")[0];
            if v["id"] != "ego" {
                continue;
            }
            let lane = v["lane"].rsplit('_').next().unwrap().parse().unwrap();
            samples.insert(
                tenth(time.expect("vehicle inside a timestep")) + 1,
                EgoSample {
                    sumo_lane: lane,
                    front_m: number(&v["pos"]),
                    y_m: number(&v["y"]),
                    speed: number(&v["speed"]),
                },
            );
        }
    }
    samples
}

/// Distinct pairs SUMO reported as colliding with the ego in its collision output.
fn sumo_ego_collisions(xml: &str) -> usize {
    let mut pairs: Vec<(String, String)> = elements(xml, "collision")
        .into_iter()
        .filter(|c| c["collider"] == "ego" || c["victim"] == "ego")
        .map(|c| {
            let (a, b) = (c["collider"].clone(), c["victim"].clone());
            if a < b {
                (a, b)
            } else {
                (b, a)
            }
        })
        .collect();
    pairs.sort();
    pairs.dedup();
    pairs.len()
}

/// The smallest time gap to the leader SUMO's SSM device logged from `from_s` on.
fn ssm_min_time_gap(ssm: &str, from_s: f64) -> Option<f64> {
    let global = element_body(ssm, "globalMeasures", "ego=\"ego\"").expect("SSM log has the ego's global measures");
    let times = &elements(global, "timeSpan")[0]["values"];
    let gaps = &elements(global, "TGAPSpan")[0]["values"];
    times
        .split_whitespace()
        .zip(gaps.split_whitespace())
        .filter(|(t, g)| number(t) >= from_s - 1e-6 && *g != "NA")
        .map(|(_, g)| number(g))
        .min_by(f64::total_cmp)
}

/// The y of SUMO's rightmost lane centre in its network file (to put SUMO's y into the
/// protocol's frame, where that lane centre is y = 0).
fn rightmost_lane_y(net: &str) -> f64 {
    let lane = elements(net, "lane")
        .into_iter()
        .find(|l| l["id"] == "highway_0")
        .expect("lane highway_0 in the network");
    let first_point = lane["shape"].split_whitespace().next().unwrap().to_string();
    number(first_point.split(',').nth(1).unwrap())
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn bridge_unit_tests_pass() {
    require_sumo();
    let dir = system_tests::scratch_dir("sumo-unit");
    let (code, stdout, stderr) = run_python(
        &dir,
        &[
            "-m",
            "unittest",
            "discover",
            "-s",
            "clients/sumo",
            "-p",
            "test_*.py",
            "-v",
        ],
    );
    assert_eq!(code, 0, "the bridge's Python unit tests failed\n{stdout}\n{stderr}");
    // Not an empty discovery: the mapping, judge and paired-comparison tests ran.
    for name in [
        "test_lane_centres_agree_with_the_protocol",
        "test_a_rear_end_collision_is_counted_once_everywhere",
        "test_the_interval_covers_the_true_difference_as_often_as_it_says",
    ] {
        assert!(stderr.contains(name), "{name} did not run\n{stderr}");
    }
}

#[test]
fn the_planner_drives_a_sumo_vehicle_and_sumo_judges_it() {
    require_sumo();
    let dir = system_tests::scratch_dir("sumo-bridge");
    let out = dir.join("out");
    let json_path = dir.join("results.json");
    let planner = system_tests::binary("planner");
    let episodes = EPISODES.to_string();
    let (code, stdout, stderr) = run_python(
        &dir,
        &[
            "clients/sumo/hmdp_sumo.py",
            "--spawn-planner",
            "--planner-bin",
            planner.to_str().unwrap(),
            "--scenario",
            "clients/sumo/scenarios/test-small.toml",
            "--episodes",
            &episodes,
            "--drivers",
            "planner,krauss",
            "--json",
            json_path.to_str().unwrap(),
            "--out-dir",
            out.to_str().unwrap(),
            "--speed-split-s",
            &SPEED_SPLIT_S.to_string(),
        ],
    );
    let planner_log = std::fs::read_to_string(out.join("planner.log")).unwrap_or_default();
    assert_eq!(
        code, 0,
        "bridge failed\nstdout:\n{stdout}\nstderr:\n{stderr}\nplanner log:\n{planner_log}"
    );
    let results: Value = serde_json::from_str(&read(&json_path)).unwrap();
    let scenario = &results["scenarios"][0];
    assert!(
        stdout.contains("| planner (HMDP-MPC) | 2 |"),
        "markdown table:\n{stdout}"
    );
    assert!(
        stdout.contains("Mean speed from 10 s after entry on, planner (HMDP-MPC) minus SUMO Krauss + LC2013"),
        "the paired speed after the entry's first seconds:\n{stdout}"
    );
    assert_eq!(scenario["paired_speed"]["split_s"].as_f64(), Some(SPEED_SPLIT_S));
    let scenario_dir = out.join("test-small");
    let rightmost_y = rightmost_lane_y(&read(&scenario_dir.join("highway.net.xml")));

    let mut lateral_decisions = 0;
    let mut corrective_memories = 0;
    for (label, driver) in [("planner (HMDP-MPC)", "planner"), ("SUMO Krauss + LC2013", "krauss")] {
        let metrics = scenario["episode_metrics"][label]
            .as_array()
            .expect("episodes of the driver");
        assert_eq!(metrics.len(), EPISODES, "{label}");
        for (i, m) in metrics.iter().enumerate() {
            let ep = scenario_dir.join(driver).join(format!("episode-{i:03}"));
            let what = format!("{label} episode {i}");
            let entry = m["entry_s"].as_f64().unwrap();
            let simulated = m["simulated_s"].as_f64().unwrap();

            // Collisions: the bridge's count (TraCI) is the one in SUMO's collision output.
            let sumo_collisions = sumo_ego_collisions(&read(&ep.join("collisions.xml")));
            assert_eq!(
                m["collisions"].as_u64().unwrap() as usize,
                sumo_collisions,
                "{what}: collisions"
            );

            // SSM: the log exists and is the one the figures come from.
            let ssm = read(&ep.join("ssm.xml"));
            assert!(ssm.contains("<SSMLog"), "{what}: not an SSM log");
            let min_gap = ssm_min_time_gap(&ssm, entry + SETTLE_S).expect("a leader was in range");
            let reported = m["ssm"]["min_time_headway_s"]
                .as_f64()
                .expect("min time headway reported");
            assert!(
                (min_gap - reported).abs() < 1e-9,
                "{what}: min time gap {reported} vs SSM log {min_gap}"
            );

            // The trajectory SUMO recorded: the reported speed and lane changes are its own.
            let trajectory = ego_trajectory(&read(&ep.join("ego-fcd.xml")));
            let episode: Vec<&EgoSample> = trajectory
                .range(tenth(entry) + 1..=tenth(entry + simulated))
                .map(|(_, s)| s)
                .collect();
            assert_eq!(episode.len() as u64, m["steps"].as_u64().unwrap(), "{what}: steps");
            let mean = episode.iter().map(|s| s.speed).sum::<f64>() / episode.len() as f64;
            let reported = m["mean_speed_mps"].as_f64().unwrap();
            assert!(
                (mean - reported).abs() < SUMO_ROUNDING,
                "{what}: mean speed {reported} vs SUMO's {mean}"
            );
            let late: Vec<f64> = trajectory
                .range(tenth(entry + SPEED_SPLIT_S) + 1..=tenth(entry + simulated))
                .map(|(_, s)| s.speed)
                .collect();
            let late_mean = late.iter().sum::<f64>() / late.len() as f64;
            let reported = m["mean_speed_after_split_mps"].as_f64().unwrap();
            assert!(
                (late_mean - reported).abs() < SUMO_ROUNDING,
                "{what}: mean speed after {SPEED_SPLIT_S} s {reported} vs SUMO's {late_mean} ({} steps)",
                late.len()
            );
            let mut lanes: Vec<u8> = vec![trajectory[&tenth(entry)].sumo_lane];
            lanes.extend(episode.iter().map(|s| s.sumo_lane));
            let changes = lanes.windows(2).filter(|w| w[0] != w[1]).count();
            assert_eq!(
                m["lane_changes"].as_u64().unwrap() as usize,
                changes,
                "{what}: lane changes"
            );

            if driver == "planner" {
                let (lateral, corrective) = check_planner_episode(
                    &what,
                    &read(&ep.join("trace.jsonl")),
                    &trajectory,
                    entry,
                    simulated,
                    rightmost_y,
                );
                lateral_decisions += lateral;
                corrective_memories += corrective;
                assert_eq!(
                    m["decisions"].as_u64().unwrap() as usize,
                    (simulated / PERIOD_S).round() as usize,
                    "{what}"
                );
            }
        }
    }
    // The scenario is one where the planner changes lanes and uses its memory: otherwise the
    // checks above would hold vacuously.
    assert!(
        lateral_decisions > 0,
        "no lane change decided: the test scenario no longer tests lane changes"
    );
    assert!(
        corrective_memories > 0,
        "no SV ever in corrective mode: the memory check is vacuous"
    );
}

/// Checks one planner episode's decisions against SUMO's trajectory; returns the number of
/// lane changes decided and of answers whose memory held a corrective entry.
fn check_planner_episode(
    what: &str,
    trace: &str,
    trajectory: &BTreeMap<i64, EgoSample>,
    entry: f64,
    simulated: f64,
    rightmost_y: f64,
) -> (usize, usize) {
    let decisions: Vec<Value> = trace.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert!(!decisions.is_empty(), "{what}: no decision");
    let end = tenth(entry + simulated);
    let (mut lateral, mut corrective) = (0, 0);
    let mut decided_changes: Vec<(i64, u8)> = Vec::new(); // (time, SUMO target lane)
    for (i, d) in decisions.iter().enumerate() {
        let t = tenth(d["time_s"].as_f64().unwrap());
        assert_eq!(d["sequence"].as_u64().unwrap() as usize, i + 1, "{what}: sequence");
        // The memory and maneuver sent are the previous answer's, unchanged (empty at first).
        if i == 0 {
            assert_eq!(
                d["memory_sent"],
                serde_json::json!({"corrective": [], "previous_plan": []}),
                "{what}"
            );
        } else {
            assert_eq!(
                d["memory_sent"],
                decisions[i - 1]["memory"],
                "{what}: memory of decision {i} not carried"
            );
            assert_eq!(
                d["maneuver_sent"],
                decisions[i - 1]["next_maneuver"],
                "{what}: maneuver {i} not carried"
            );
        }
        if !d["memory"]["corrective"].as_array().unwrap().is_empty() {
            corrective += 1;
        }
        // What was sent is SUMO's state at that instant, mapped: centre = front - length / 2,
        // y in the protocol's frame, protocol lane 1 = SUMO's leftmost lane.
        let now = &trajectory[&t];
        let ego = &d["ego_sent"];
        let sent_x = ego["x_m"].as_f64().unwrap();
        assert!(
            (sent_x - (now.front_m - EGO_LENGTH_M / 2.0)).abs() < SUMO_ROUNDING,
            "{what}: x {sent_x} vs {now:?}"
        );
        let sent_y = ego["y_m"].as_f64().unwrap();
        // SUMO's position is the front's: off the centre's y by up to L/2 sin(angle) in a change.
        assert!(
            (sent_y - (now.y_m - rightmost_y)).abs() < 0.25,
            "{what}: y {sent_y} vs {now:?}"
        );
        // y lies within the lane SUMO has the ego on (SUMO lane k: centre at k * width).
        let lane_centre = f64::from(now.sumo_lane) * LANE_WIDTH_M;
        assert!(
            (sent_y - lane_centre).abs() <= LANE_WIDTH_M / 2.0 + 0.01,
            "{what}: y {sent_y} off SUMO lane {}",
            now.sumo_lane
        );
        // Longitudinal: the set-point's acceleration was held for the period: one period
        // later SUMO's speed is the set-point's target speed.
        if let Some(later) = trajectory
            .get(&(t + tenth(PERIOD_S)))
            .filter(|_| t + tenth(PERIOD_S) <= end)
        {
            let target = d["setpoint"]["target_speed_mps"].as_f64().unwrap().max(0.0);
            assert!(
                (later.speed - target).abs() < SUMO_ROUNDING,
                "{what}: decision {i}: speed {} vs set-point {target}",
                later.speed
            );
        }
        // Lateral: a new target lane is a lane change SUMO must carry out within its duration.
        let target_lane = d["next_maneuver"]["lane"].as_u64().unwrap() as u8;
        if target_lane != d["maneuver_sent"]["lane"].as_u64().unwrap() as u8 {
            lateral += 1;
            let sumo_target = LANES - target_lane;
            decided_changes.push((t, sumo_target));
            let deadline = t + tenth(LANE_CHANGE_S + PERIOD_S);
            if deadline <= end {
                let reached = trajectory
                    .range(t + 1..=deadline)
                    .any(|(_, s)| s.sumo_lane == sumo_target);
                assert!(
                    reached,
                    "{what}: decision {i} (lane {target_lane}) not carried out by SUMO"
                );
            }
        }
    }
    // And SUMO changed lanes only when the planner said so.
    let mut previous = trajectory[&tenth(entry)].sumo_lane;
    for (&t, s) in trajectory.range(tenth(entry) + 1..=end) {
        if s.sumo_lane != previous {
            let decided = decided_changes
                .iter()
                .any(|&(at, lane)| lane == s.sumo_lane && at < t && t <= at + tenth(LANE_CHANGE_S + PERIOD_S));
            assert!(
                decided,
                "{what}: SUMO moved the ego to lane {} at {} s on its own",
                s.sumo_lane,
                t as f64 / 10.0
            );
            previous = s.sumo_lane;
        }
    }
    (lateral, corrective)
}

/// Over the network without the planner's key the bridge refuses to run (a forged planner
/// there would drive the vehicle), and says why; before it starts SUMO or sends anything.
#[test]
fn the_bridge_refuses_an_unverified_planner_beyond_this_host() {
    require_sumo();
    let dir = system_tests::scratch_dir("sumo-refusal");
    let (code, stdout, stderr) = run_python(
        &dir,
        &[
            "clients/sumo/hmdp_sumo.py",
            // A documentation address (RFC 5737): beyond this host, nothing answers there.
            "--zenoh-connect",
            "tcp/198.51.100.7:7447",
            "--scenario",
            "clients/sumo/scenarios/test-small.toml",
            "--drivers",
            "planner",
        ],
    );
    assert!(
        code == 1 && stderr.contains("cannot be verified"),
        "exit {code}\nstdout:\n{stdout}\nstderr:\n{stderr}"
    );
}

/// With `--planner-key` the bridge takes only answers signed by the planner: a forger that
/// answers every plan query first (with a set-point no planner commands) is refused, and the
/// decisions the bridge applied are exactly the planner's.
#[test]
fn the_bridge_verifies_the_planners_answers() {
    require_sumo();
    let dir = system_tests::scratch_dir("sumo-signed");
    let (secret, public) = system_tests::keygen(&dir, "planner.key");
    let planner = system_tests::ZenohPlanner::start("sumo-signed", &["--signing-key", secret.to_str().unwrap()]);
    drop(planner.vehicle(Some(protocol::ResponseVerifier::from_file(&public).unwrap())));
    let forger = system_tests::forger::Forger::start(&planner.endpoint, 0);
    let json_path = dir.join("results.json");
    let (code, stdout, stderr) = run_python(
        &dir,
        &[
            "clients/sumo/hmdp_sumo.py",
            "--zenoh-connect",
            &planner.endpoint,
            "--planner-key",
            public.to_str().unwrap(),
            "--scenario",
            "clients/sumo/scenarios/test-small.toml",
            "--drivers",
            "planner",
            "--json",
            json_path.to_str().unwrap(),
        ],
    );
    assert_eq!(code, 0, "stdout:\n{stdout}\nstderr:\n{stderr}\n{}", planner.log());
    let forgeries = forger.sent.load(std::sync::atomic::Ordering::SeqCst);
    assert!(forgeries > 0, "the forger never answered");
    assert!(stderr.contains("refused"), "no forgery refused: {stderr}");
    let results: Value = serde_json::from_str(&read(&json_path)).unwrap();
    let episode = &results["scenarios"][0]["episode_metrics"]["planner (HMDP-MPC)"][0];
    let decisions = episode["decisions"].as_u64().expect("decisions");
    eprintln!("bridge with the key beside a forger ({forgeries} forgeries): {decisions} decisions, {stderr}");
    assert!(decisions > 0, "{episode}");
}
