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

#[test]
fn keygen_writes_a_private_key_and_its_public_key() {
    use std::os::unix::fs::PermissionsExt;
    let dir = std::env::temp_dir().join(format!("hmdp-keygen-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let secret = dir.join("planner.key");
    let out = Command::new(env!("CARGO_BIN_EXE_planner"))
        .arg("keygen")
        .arg(&secret)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let mode = std::fs::metadata(&secret).unwrap().permissions().mode();
    assert_eq!(mode & 0o077, 0, "the secret key is readable by others: {mode:o}");
    let signer = protocol::ResponseSigner::from_file(&secret).unwrap();
    let public = protocol::ResponseVerifier::from_file(&dir.join("planner.key.pub")).unwrap();
    assert_eq!(signer.verifier(), public);
    // A second run must not replace the key vehicles already trust.
    let again = Command::new(env!("CARGO_BIN_EXE_planner"))
        .arg("keygen")
        .arg(&secret)
        .output()
        .unwrap();
    assert!(!again.status.success());
    assert_eq!(protocol::ResponseSigner::from_file(&secret).unwrap().verifier(), public);
    // `serve` refuses a key file it cannot use, before serving anything.
    std::fs::write(dir.join("bad.key"), "not a key").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_planner"))
        .args(["serve", "--iceoryx2", "--signing-key"])
        .arg(dir.join("bad.key"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("64 hex digits"));
    std::fs::remove_dir_all(&dir).unwrap();
}
