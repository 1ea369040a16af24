//! The `planner` command line.

use std::process::Command;

use decision::PlannerConfig;

#[test]
fn default_config_prints_the_defaults_as_toml() {
    let out = Command::new(env!("CARGO_BIN_EXE_planner"))
        .arg("default-config")
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert_eq!(PlannerConfig::from_toml_str(&text).unwrap(), PlannerConfig::default());
}

#[test]
fn unknown_subcommand_fails_with_usage() {
    let out = Command::new(env!("CARGO_BIN_EXE_planner")).arg("fly").output().unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("Usage"));
}
