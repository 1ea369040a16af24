//! Helpers for tests that run the workspace's binaries as separate processes.

use std::path::PathBuf;

/// Path of a workspace binary built in the same profile as the running test.
///
/// `cargo test --workspace` builds every package's binaries because each binary package
/// has integration tests; they land next to the test executable's `deps/` directory.
pub fn binary(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    let dir = exe
        .parent()
        .and_then(|deps| deps.parent())
        .expect("target profile directory");
    let path = dir.join(name);
    assert!(
        path.exists(),
        "{} not built; run the tests with `cargo test --workspace`",
        path.display()
    );
    path
}
