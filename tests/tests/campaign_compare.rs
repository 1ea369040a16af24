//! `sim_client compare` end to end: two campaign runs of the real binary, one of them with
//! another planner configuration, paired trial by trial. The figures `compare` recomputes
//! from trials.jsonl must be the ones each campaign wrote to its results.json; runs of
//! another seed are refused with a clear error. An independent oracle,
//! clients/campaign_check/check_trials.py (Python, from the metrics' definitions), recomputes
//! every row of results.json from trials.jsonl, and catches a tampered trial.

use std::path::Path;
use std::process::{Command, Output};

use serde_json::Value;
use system_tests::{binary, scratch_dir};

const CONFIGS: &str = r#"
[[config]]
lanes = 3
sv_count = 8
speed_range = [20.0, 30.0]
trials = 8

[[config]]
lanes = 2
sv_count = 6
speed_range = [25.0, 35.0]
trials = 8
"#;

fn sim_client(args: &[&str]) -> Output {
    Command::new(binary("sim_client"))
        .args(args)
        .output()
        .expect("sim_client runs")
}

fn succeed(args: &[&str]) -> String {
    let out = sim_client(args);
    assert!(
        out.status.success(),
        "sim_client {args:?}: {}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn campaign(dir: &Path, configs: &str, name: &str, seed: &str, planner_config: Option<&Path>) -> String {
    let out = dir.join(name);
    let (config, out_s) = (dir.join(configs), out.to_str().unwrap().to_owned());
    let mut args = vec![
        "campaign",
        "--config",
        config.to_str().unwrap(),
        "--seed",
        seed,
        "--threads",
        "1",
        "--baselines",
        "false",
        "--out",
        &out_s,
    ];
    if let Some(p) = planner_config {
        args.extend(["--planner-config", p.to_str().unwrap()]);
    }
    succeed(&args);
    out_s
}

/// The planner's overall row of a run's results.json.
fn overall(run: &str) -> Value {
    let text = std::fs::read_to_string(Path::new(run).join("campaign/results.json")).unwrap();
    let v: Value = serde_json::from_str(&text).unwrap();
    v["overall"]
        .as_array()
        .unwrap()
        .iter()
        .find(|g| g["driver"] == "planner")
        .unwrap()
        .clone()
}

fn figure<'a>(cmp: &'a Value, name: &str) -> &'a Value {
    cmp["figures"]
        .as_array()
        .unwrap()
        .iter()
        .find(|f| f["name"] == name)
        .unwrap()
}

#[test]
fn compare_pairs_two_runs_and_recomputes_their_reported_figures() {
    let dir = scratch_dir("campaign-compare");
    std::fs::write(dir.join("configs.toml"), CONFIGS).unwrap();
    // The IDM's b of formulation.md against the shipped one: a change that moves the speed.
    let b2 = dir.join("b2.toml");
    std::fs::write(&b2, "[idm]\ncomfort_decel_mps2 = 2.0\n").unwrap();
    let base = campaign(&dir, "configs.toml", "base", "77", Some(&b2));
    let cand = campaign(&dir, "configs.toml", "cand", "77", None);
    let json = dir.join("cmp.json");
    let table = succeed(&[
        "compare",
        &base,
        &cand,
        "--json",
        json.to_str().unwrap(),
        "--lowest-ttc",
        "3",
    ]);
    assert!(table.contains("16 paired trials"), "{table}");
    let cmp: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let (ob, oc) = (overall(&base), overall(&cand));
    let pairs = [
        ("mean speed (m/s)", "/mean_speed_mps"),
        ("beta switches/min", "/beta_switches_per_min"),
        ("hard brakes/h", "/safety/hard_braking_per_hour"),
        ("min TTC p50 (s)", "/safety/min_ttc_p50_s"),
    ];
    for (name, pointer) in pairs {
        let f = figure(&cmp, name);
        for (side, row) in [("baseline", &ob), ("candidate", &oc)] {
            let reported = row.pointer(pointer).unwrap().as_f64();
            assert_eq!(f[side].as_f64(), reported, "{name} {side}: {f} against results.json");
        }
        if let Some(i) = f["interval"].as_array() {
            let (lo, hi) = (i[0].as_f64().unwrap(), i[1].as_f64().unwrap());
            assert!(lo <= hi, "{name}: [{lo}, {hi}]");
        }
    }
    // A run against itself: every figure the same, every interval the point 0.
    let same = dir.join("same.json");
    succeed(&["compare", &base, &base, "--json", same.to_str().unwrap()]);
    let same: Value = serde_json::from_str(&std::fs::read_to_string(&same).unwrap()).unwrap();
    for f in same["figures"].as_array().unwrap() {
        if f["verdict"] != "undefined" {
            assert_eq!(f["verdict"], "no_difference", "{f}");
            assert_eq!(f["interval"], serde_json::json!([0.0, 0.0]), "{f}");
        }
    }
    // The Python oracle agrees with every row, and notices one switch more in one trial.
    let check = |run: &str| {
        Command::new("python3")
            .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("../clients/campaign_check/check_trials.py"))
            .arg(run)
            .output()
            .expect("python3 runs")
    };
    let ok = check(&base);
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    assert!(String::from_utf8_lossy(&ok.stdout).contains("all 3 rows agree"));
    let tampered = dir.join("tampered");
    std::fs::create_dir_all(tampered.join("campaign")).unwrap();
    std::fs::copy(
        Path::new(&base).join("campaign/results.json"),
        tampered.join("campaign/results.json"),
    )
    .unwrap();
    let trials = std::fs::read_to_string(Path::new(&base).join("campaign/trials.jsonl")).unwrap();
    let first = trials.lines().next().unwrap();
    let mut v: Value = serde_json::from_str(first).unwrap();
    let switches = v["metrics"]["beta_switches"].as_u64().unwrap();
    v["metrics"]["beta_switches"] = (switches + 1).into();
    let rest: Vec<&str> = trials.lines().skip(1).collect();
    std::fs::write(
        tampered.join("campaign/trials.jsonl"),
        format!("{v}\n{}\n", rest.join("\n")),
    )
    .unwrap();
    let bad = check(tampered.to_str().unwrap());
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("MISMATCH"));
    // Another seed met other traffic: nothing to pair.
    let other = campaign(&dir, "configs.toml", "other", "78", None);
    let out = sim_client(&["compare", &base, &other]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("different seeds"), "{err}");
    // The same seed and configuration ids, other traffic (more SVs): nothing to pair either.
    std::fs::write(
        dir.join("denser.toml"),
        CONFIGS.replace("sv_count = 8", "sv_count = 12"),
    )
    .unwrap();
    let denser = campaign(&dir, "denser.toml", "denser", "77", None);
    let out = sim_client(&["compare", &base, &denser]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("other traffic"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}
