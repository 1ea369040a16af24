//! Running a helper process (a Python client, the SUMO bridge) to its end.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// What a process left when it ended.
#[derive(Debug)]
pub struct Finished {
    /// Its exit code (-1 when a signal ended it).
    pub code: i32,
    pub stdout: String,
    pub stderr: String,
    /// From its start to its end, for the test's report (never asserted on).
    pub elapsed: Duration,
}

impl Finished {
    /// Exit code, stdout and stderr, for an assertion's message.
    pub fn report(&self) -> String {
        format!("exit {}\nstdout:\n{}\nstderr:\n{}", self.code, self.stdout, self.stderr)
    }
}

/// Runs `command` to its end with stdin closed and its output in `dir/{name}.stdout` and
/// `.stderr` (files, so that a chatty process cannot block on a full pipe); one still running
/// after `limit` is killed and fails the test with its stderr.
pub fn run_to_end(command: &mut Command, dir: &Path, name: &str, limit: Duration) -> Finished {
    let (out_path, err_path) = (dir.join(format!("{name}.stdout")), dir.join(format!("{name}.stderr")));
    let started = Instant::now();
    let mut child = command
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&out_path).expect("stdout file"))
        .stderr(std::fs::File::create(&err_path).expect("stderr file"))
        .spawn()
        .unwrap_or_else(|e| panic!("{name} does not start: {e}"));
    let status = loop {
        if let Some(status) = child.try_wait().expect("the child's status") {
            break status;
        }
        if started.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!(
                "{name} still running after {limit:?}\n{}",
                std::fs::read_to_string(&err_path).unwrap_or_default()
            );
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    Finished {
        code: status.code().unwrap_or(-1),
        stdout: std::fs::read_to_string(&out_path).unwrap_or_default(),
        stderr: std::fs::read_to_string(&err_path).unwrap_or_default(),
        elapsed: started.elapsed(),
    }
}
