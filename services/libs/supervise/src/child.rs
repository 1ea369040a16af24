//! Child processes that never outlive their welcome, and the shared memory they leave.

use std::path::Path;
use std::process::{Child, Command, ExitStatus};
use std::time::{Duration, Instant};

/// A child process, stopped when dropped (also on error or panic): SIGTERM first, so that
/// it can remove its shared memory, SIGKILL if it has not exited after the grace period.
pub struct Supervised {
    child: Child,
    grace: Duration,
    /// Removed after the child has exited (dropped after `Drop::drop`).
    prefix: Option<ShmPrefix>,
}

impl Supervised {
    /// Spawns `command`. With `die_with_parent` the kernel sends the child SIGTERM when this
    /// process dies without stopping it (a signal, SIGPIPE): it must not live on.
    pub fn spawn(command: &mut Command, die_with_parent: bool) -> std::io::Result<Self> {
        #[cfg(target_os = "linux")]
        if die_with_parent {
            use std::os::unix::process::CommandExt;
            // SAFETY: prctl is async-signal-safe; nothing else runs between fork and exec.
            unsafe {
                command.pre_exec(|| {
                    libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM);
                    Ok(())
                });
            }
        }
        Ok(Self {
            child: command.spawn()?,
            grace: Duration::from_secs(5),
            prefix: None,
        })
    }

    /// How long a drop waits after SIGTERM before SIGKILL (default 5 s).
    pub fn with_grace(mut self, grace: Duration) -> Self {
        self.grace = grace;
        self
    }

    /// Makes the child own `prefix`: its files go once the child has stopped.
    pub fn owning(mut self, prefix: ShmPrefix) -> Self {
        self.prefix = Some(prefix);
        self
    }

    /// The process id.
    pub fn id(&self) -> u32 {
        self.child.id()
    }

    /// SIGTERM, then waits up to `wait` for the exit; the exit status, if it exited.
    pub fn terminate(&mut self, wait: Duration) -> Option<ExitStatus> {
        if let Ok(Some(status)) = self.child.try_wait() {
            return Some(status);
        }
        if let Ok(pid) = i32::try_from(self.child.id()) {
            // SAFETY: signals our own child, which has not been reaped yet.
            unsafe { libc::kill(pid, libc::SIGTERM) };
        }
        let until = Instant::now() + wait;
        loop {
            if let Ok(Some(status)) = self.child.try_wait() {
                return Some(status);
            }
            if Instant::now() >= until {
                return None;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// SIGKILL: the process gets no chance to clean up.
    pub fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }

    /// Whether the process is still running.
    pub fn is_running(&mut self) -> bool {
        matches!(self.child.try_wait(), Ok(None))
    }

    /// Waits for the exit.
    pub fn wait(&mut self) -> std::io::Result<ExitStatus> {
        self.child.wait()
    }
}

impl Drop for Supervised {
    fn drop(&mut self) {
        if self.terminate(self.grace).is_none() {
            self.kill();
        }
    }
}

/// An iceoryx2 shared-memory prefix owned by this process: dropping it removes every file
/// left under it (iceoryx2 keeps a management segment per prefix after its last node is gone,
/// and a SIGKILLed process leaves more).
#[derive(Debug)]
pub struct ShmPrefix(String);

impl ShmPrefix {
    /// A prefix no other process (nor another call in this one) uses: `stem`, the process id,
    /// a counter.
    pub fn unique(stem: &str) -> Self {
        use std::sync::atomic::{AtomicU32, Ordering};
        static NEXT: AtomicU32 = AtomicU32::new(0);
        Self(format!(
            "{stem}{}x{}_",
            std::process::id(),
            NEXT.fetch_add(1, Ordering::Relaxed)
        ))
    }

    /// The prefix.
    pub fn as_str(&self) -> &str {
        &self.0
    }
}

impl Drop for ShmPrefix {
    fn drop(&mut self) {
        remove_under(Path::new("/dev/shm"), &self.0);
        remove_under(&std::env::temp_dir().join("iceoryx2"), &self.0);
    }
}

fn remove_under(dir: &Path, prefix: &str) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            remove_under(&path, prefix);
        } else if entry.file_name().to_string_lossy().starts_with(prefix) {
            let _ = std::fs::remove_file(&path);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_dropped_child_is_stopped_and_its_prefix_files_removed() {
        let prefix = ShmPrefix::unique("supervisetest");
        let file = std::env::temp_dir()
            .join("iceoryx2")
            .join(format!("{}probe", prefix.as_str()));
        std::fs::create_dir_all(file.parent().unwrap()).unwrap();
        std::fs::write(&file, b"x").unwrap();
        let mut child = Supervised::spawn(Command::new("sleep").arg("30"), true)
            .unwrap()
            .owning(prefix);
        assert!(child.is_running());
        let pid = child.id();
        drop(child);
        assert!(!file.exists(), "prefix file left");
        assert!(!Path::new(&format!("/proc/{pid}")).exists() || !is_alive(pid));
        assert_ne!(ShmPrefix::unique("a").as_str(), ShmPrefix::unique("a").as_str());
    }

    fn is_alive(pid: u32) -> bool {
        std::fs::read_to_string(format!("/proc/{pid}/stat"))
            .map(|s| !s.contains(") Z "))
            .unwrap_or(false)
    }
}
