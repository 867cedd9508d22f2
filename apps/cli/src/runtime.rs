//! A private runtime folder for `strata render`. Creating the GPU instance probes for a Wayland
//! display; without an absolute `XDG_RUNTIME_DIR` (a bare X session, a container, ssh) the
//! Wayland client library prints `error: XDG_RUNTIME_DIR is invalid or not set in the
//! environment.` twice on standard error, though nothing is wrong and the render succeeds.
//!
//! The variable cannot be set safely inside a running multi-threaded process (`set_var` is
//! `unsafe` since Rust 2024, and the workspace denies `unsafe`), so [`rerun_with_runtime_dir`]
//! runs the same command again as a child with the variable naming a new private folder (mode
//! 0700), passes on its exit code and removes the folder.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

use anyhow::{Context, Result};

/// The variable the Wayland client library reads.
pub const RUNTIME_DIR_VAR: &str = "XDG_RUNTIME_DIR";

/// Set in the child, so that it never runs itself again whatever it finds.
const RERUN_VAR: &str = "STRATA_RUNTIME_DIR_RERUN";

/// Whether this process should run the render in a child with a private runtime folder: the
/// variable is not usable and this process is not already that child.
pub fn needs_runtime_dir() -> bool {
    std::env::var_os(RERUN_VAR).is_none() && !runtime_dir_usable(std::env::var_os(RUNTIME_DIR_VAR).as_ref())
}

/// Whether `value` (the variable's value, if set) is what the Wayland client library accepts
/// silently: an absolute path, here also required to be an existing folder.
pub fn runtime_dir_usable(value: Option<&OsString>) -> bool {
    value.map(Path::new).is_some_and(|p| p.is_absolute() && p.is_dir())
}

/// A new private folder under the temporary folder (mode 0700 on Unix).
fn private_dir() -> Result<PathBuf> {
    let base = std::env::temp_dir();
    let mut last = None;
    for attempt in 0..16u32 {
        let dir = base.join(format!("strata-runtime-{}-{attempt}", std::process::id()));
        let mut builder = std::fs::DirBuilder::new();
        #[cfg(unix)]
        std::os::unix::fs::DirBuilderExt::mode(&mut builder, 0o700);
        match builder.create(&dir) {
            Ok(()) => return Ok(dir),
            Err(e) => last = Some(e),
        }
    }
    let e = last.expect("at least one attempt");
    Err(e).with_context(|| format!("creating a private runtime folder in {}", base.display()))
}

/// Runs this program again with the same arguments and `XDG_RUNTIME_DIR` naming a new private
/// folder, waits for it and returns its exit code (standard output and error are the child's).
pub fn rerun_with_runtime_dir() -> Result<ExitCode> {
    let exe = std::env::current_exe().context("finding the strata binary to run the render")?;
    let dir = private_dir()?;
    let status =
        Command::new(&exe).args(std::env::args_os().skip(1)).env(RUNTIME_DIR_VAR, &dir).env(RERUN_VAR, "1").status();
    let _ = std::fs::remove_dir_all(&dir);
    let status = status.with_context(|| format!("running {}", exe.display()))?;
    Ok(match status.code() {
        Some(0) => ExitCode::SUCCESS,
        Some(code) => ExitCode::from(u8::try_from(code).unwrap_or(1).max(1)),
        // Killed by a signal.
        None => ExitCode::FAILURE,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_absolute_existing_folders_are_usable() {
        assert!(!runtime_dir_usable(None));
        assert!(!runtime_dir_usable(Some(&OsString::from(""))));
        assert!(!runtime_dir_usable(Some(&OsString::from("relative/dir"))));
        assert!(!runtime_dir_usable(Some(&OsString::from("/nonexistent/strata-runtime"))));
        assert!(runtime_dir_usable(Some(&std::env::temp_dir().into_os_string())));
        let dir = private_dir().unwrap();
        assert!(runtime_dir_usable(Some(&dir.clone().into_os_string())));
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            assert_eq!(std::fs::metadata(&dir).unwrap().permissions().mode() & 0o777, 0o700);
        }
        std::fs::remove_dir(&dir).unwrap();
    }
}
