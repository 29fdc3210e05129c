//! Running a test's body in a child process under an address-space limit, so that a test
//! can show a loader's peak memory stays small: an allocation past the limit fails in the
//! child (an abort there, a failed test here) instead of exhausting the machine.

use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Set in the child: run the body instead of spawning.
const CHILD_ENV: &str = "DGI_TEST_CHILD";

/// What a child run measured.
#[derive(Debug)]
pub struct ChildRun {
    /// Wall time of the child, start to exit.
    pub elapsed: Duration,
    /// The child's standard output and error.
    pub output: String,
}

/// A command that runs `exe` with its address space limited to `limit_bytes` (through
/// `sh -c 'ulimit -v ...; exec ...'`): an allocation past the limit fails inside it. Add the
/// program's arguments with `.args(...)`.
pub fn capped_command(exe: &std::path::Path, limit_bytes: u64) -> Command {
    let mut c = Command::new("sh");
    c.arg("-c")
        .arg(format!(
            "ulimit -v {} && exec \"$0\" \"$@\"",
            limit_bytes / 1024
        ))
        .arg(exe);
    c
}

/// In the parent: runs the test `test_name` of the current test binary again, alone, in a
/// child process whose address space is limited to `limit_bytes` (`ulimit -v`) and whose
/// wall time is limited to `timeout`; panics with the child's output when the child fails,
/// is killed, or did not run exactly one test. In the child: runs `body`.
///
/// Returns `None` in the child (after `body` ran) and the measurements in the parent.
pub fn in_child(
    test_name: &str,
    limit_bytes: u64,
    timeout: Duration,
    body: impl FnOnce(),
) -> Option<ChildRun> {
    if std::env::var_os(CHILD_ENV).is_some() {
        body();
        return None;
    }
    let exe = std::env::current_exe().expect("the test binary's path");
    let dir = crate::hostile::scratch_dir("child");
    let log: PathBuf = dir.join("output.txt");
    let file = std::fs::File::create(&log).expect("child log");
    let start = Instant::now();
    let mut child = capped_command(&exe, limit_bytes)
        .args([test_name, "--exact", "--nocapture", "--test-threads=1"])
        .env(CHILD_ENV, "1")
        .env("RUST_BACKTRACE", "0")
        .stdout(Stdio::from(file.try_clone().expect("log handle")))
        .stderr(Stdio::from(file))
        .spawn()
        .expect("spawn the child test (needs sh)");
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait for the child") {
            break Some(status);
        }
        if start.elapsed() > timeout {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let elapsed = start.elapsed();
    let output = std::fs::read_to_string(&log).unwrap_or_default();
    let _ = std::fs::remove_dir_all(&dir);
    let limit_mib = limit_bytes >> 20;
    match status {
        None => panic!(
            "{test_name}: still running after {timeout:?} under a {limit_mib} MiB address space\n{output}"
        ),
        Some(s) if !s.success() => panic!(
            "{test_name}: failed ({s}) under a {limit_mib} MiB address space after {elapsed:?}\n{output}"
        ),
        Some(_) if !output.contains("1 passed") => {
            panic!("{test_name}: the child did not run exactly this test\n{output}")
        }
        Some(_) => Some(ChildRun { elapsed, output }),
    }
}
