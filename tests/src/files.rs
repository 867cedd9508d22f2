//! Harnesses for the tests of what Strata writes: a writer killed at random moments, and two
//! writers racing on one path while a reader watches. Used by the scene, mesh export, PNG and
//! world tests, which differ only in what they write and how they check it.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// Runs the test `child_test` of the calling test binary as a child process (`--ignored`,
/// with `env_var` set to `path`: the child's loop of writes) `rounds` times; each time kills it
/// after a pseudo-random delay in `delay_us` (microseconds, the same sequence every run), waits
/// for it and calls `check(round)`, which inspects what the kill left.
pub fn kill_at_random_moments(
    child_test: &str,
    env_var: &str,
    path: &Path,
    rounds: usize,
    delay_us: std::ops::Range<u64>,
    mut check: impl FnMut(usize),
) {
    let exe = std::env::current_exe().expect("the test binary's path");
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    for round in 0..rounds {
        let mut child = std::process::Command::new(&exe)
            .args([child_test, "--exact", "--ignored", "--test-threads=1"])
            .env(env_var, path)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .expect("the child process starts");
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        std::thread::sleep(Duration::from_micros(delay_us.start + seed % (delay_us.end - delay_us.start).max(1)));
        child.kill().expect("the child is killed");
        child.wait().expect("the child is reaped");
        check(round);
    }
}

/// Runs `writers` on threads of their own while `read` is called again and again on another
/// until they all return; returns how many reads said `true` (a whole file) and how many `false`
/// (a corrupt or partial one).
pub fn race_writers_with_reader(
    writers: Vec<Box<dyn FnOnce() + Send + '_>>,
    read: impl Fn() -> bool + Sync,
) -> (u32, u32) {
    let done = AtomicBool::new(false);
    std::thread::scope(|s| {
        let handles: Vec<_> = writers.into_iter().map(|w| s.spawn(w)).collect();
        let reader = s.spawn(|| {
            let (mut good, mut bad) = (0u32, 0u32);
            while !done.load(Ordering::Relaxed) {
                if read() {
                    good += 1;
                } else {
                    bad += 1;
                }
            }
            (good, bad)
        });
        for h in handles {
            h.join().expect("a writer panicked");
        }
        done.store(true, Ordering::Relaxed);
        reader.join().expect("the reader panicked")
    })
}
