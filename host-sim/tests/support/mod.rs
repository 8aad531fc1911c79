//! Runs the `host-sim` binary as a user would, with bounded time and memory.

// Each test file uses its own part of these helpers.
#![allow(dead_code)]

use std::io::Read;
use std::os::unix::process::ExitStatusExt;
use std::path::PathBuf;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::thread;
use std::time::{Duration, Instant};

pub const BIN: &str = env!("CARGO_BIN_EXE_host-sim");

/// Virtual memory the binary may map (KiB): an oversized allocation aborts instead of swapping.
const MEMORY_LIMIT_KIB: u64 = 4_000_000;

/// How long a refusal of bad input may take.
pub const REFUSAL_TIME: Duration = Duration::from_secs(1);

/// What one run of the binary did.
#[derive(Debug)]
pub struct Outcome {
    pub args: Vec<String>,
    /// `None` when the run was killed at its time limit.
    pub status: Option<ExitStatus>,
    pub stdout: String,
    pub stderr: String,
    pub elapsed: Duration,
}

impl Outcome {
    /// The exit code; `None` when killed by a signal or at the time limit.
    pub fn code(&self) -> Option<i32> {
        self.status.and_then(|status| status.code())
    }

    /// The signal that ended the run, if one did.
    pub fn signal(&self) -> Option<i32> {
        self.status.and_then(|status| status.signal())
    }

    pub fn stderr_lines(&self) -> Vec<&str> {
        self.stderr.lines().collect()
    }

    /// Asserts a refusal: exit code 2 within [`REFUSAL_TIME`] and exactly one stderr line,
    /// `error: …`, containing each of `words`; nothing on stdout.
    pub fn assert_refused(&self, words: &[&str]) {
        assert_eq!(self.code(), Some(2), "{self:#?}");
        assert!(self.elapsed < REFUSAL_TIME, "slow refusal: {self:#?}");
        let lines = self.stderr_lines();
        assert_eq!(lines.len(), 1, "{self:#?}");
        assert!(lines[0].starts_with("error: "), "{self:#?}");
        for word in words {
            assert!(lines[0].contains(word), "no {word:?} in {:?}", lines[0]);
        }
        assert_eq!(self.stdout, "", "{self:#?}");
    }
}

/// Runs `host-sim args…` with standard input empty, killing it after `time_limit`.
pub fn run<S: AsRef<str>>(args: &[S], time_limit: Duration) -> Outcome {
    let args: Vec<String> = args.iter().map(|arg| arg.as_ref().to_string()).collect();
    let started = Instant::now();
    let mut child = Command::new("sh")
        .arg("-c")
        .arg(format!("ulimit -v {MEMORY_LIMIT_KIB}; exec \"$0\" \"$@\""))
        .arg(BIN)
        .args(&args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("sh runs");
    let stdout = drain(child.stdout.take());
    let stderr = drain(child.stderr.take());
    let status = wait(&mut child, started + time_limit);
    Outcome {
        args,
        status,
        stdout: stdout.join().expect("stdout reader"),
        stderr: stderr.join().expect("stderr reader"),
        elapsed: started.elapsed(),
    }
}

/// Waits for `child` until `deadline`, then kills it (`None`).
fn wait(child: &mut Child, deadline: Instant) -> Option<ExitStatus> {
    loop {
        if let Some(status) = child.try_wait().expect("the child can be waited for") {
            return Some(status);
        }
        if Instant::now() >= deadline {
            let _ = child.kill();
            let _ = child.wait();
            return None;
        }
        thread::sleep(Duration::from_millis(2));
    }
}

fn drain(pipe: Option<impl Read + Send + 'static>) -> thread::JoinHandle<String> {
    thread::spawn(move || {
        let mut bytes = Vec::new();
        if let Some(mut pipe) = pipe {
            let _ = pipe.read_to_end(&mut bytes);
        }
        String::from_utf8_lossy(&bytes).into_owned()
    })
}

/// A fresh directory for one test's files, under cargo's scratch directory for tests.
pub fn scratch_dir(name: &str) -> PathBuf {
    static NEXT: AtomicUsize = AtomicUsize::new(0);
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!(
        "host-sim-{name}-{}-{}",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::create_dir_all(&dir).expect("scratch directory");
    dir
}

/// The decoded event log of a short QEMU run that passes the check.
pub fn golden_log() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/expected/qemu-short-scenario.log")
}
