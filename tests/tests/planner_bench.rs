//! `planner bench --json` as a process: the report a user would script against.

use std::process::Command;

use system_tests::binary;

#[test]
fn bench_reports_full_agreement_and_ordered_percentiles() {
    let out = Command::new(binary("planner"))
        .args(["bench", "--json", "--per-class", "4", "--seed", "11"])
        .output()
        .expect("planner runs");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON on stdout");
    assert_eq!(report["situations"], 72);
    assert_eq!(report["agreement"]["rate"], 1.0, "{}", report["agreement"]);
    assert_eq!(report["classes"].as_array().unwrap().len(), 18);
    for backend in ["milp", "enumeration"] {
        let t = &report["backends"][backend];
        assert_eq!(t["count"], 72);
        let (p50, p99, max) = (
            t["p50_us"].as_u64().unwrap(),
            t["p99_us"].as_u64().unwrap(),
            t["max_us"].as_u64().unwrap(),
        );
        assert!(p50 <= p99 && p99 <= max, "{t}");
    }
    let target = &report["target_class"]["class"];
    assert_eq!((target["lanes"].as_u64(), target["svs"].as_u64()), (Some(4), Some(10)));
}

#[test]
fn bench_rejects_a_bad_config_file_with_a_message() {
    let dir = std::env::temp_dir().join(format!("planner-bad-config-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("bad.toml");
    std::fs::write(&path, "[hysteresis]\ngamma1 = 2.0\n").unwrap();
    let out = Command::new(binary("planner"))
        .args(["bench", "--per-class", "1", "--config"])
        .arg(&path)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("gamma1"), "{err}");
}
