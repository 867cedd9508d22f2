//! Checks of input and output paths, done before any work starts: a command that would fail to
//! read its input or write its output says so at once, not after minutes of work.

use std::path::Path;

use anyhow::{Result, bail};

/// The lower-case extension of `path`, if any.
pub fn extension(path: &Path) -> Option<String> {
    path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase)
}

/// Checks that `path` is a readable regular file whose extension is one of `kinds` (`what`
/// names them in the error).
pub fn check_input(path: &Path, kinds: &[&str], what: &str) -> Result<()> {
    let shown = path.display();
    match extension(path) {
        Some(e) if kinds.contains(&e.as_str()) => {}
        _ => bail!("{shown}: not a {what} (use {})", list(kinds)),
    }
    let meta = match std::fs::metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => bail!("{shown}: no such file"),
        Err(e) => bail!("{shown}: {e}"),
    };
    if !meta.is_file() {
        bail!("{shown}: not a regular file");
    }
    if let Err(e) = std::fs::File::open(path) {
        bail!("{shown}: cannot be read: {e}");
    }
    Ok(())
}

/// Checks that `path` can be written: its extension is one of `kinds`, it is not a folder, and
/// its folder exists and takes a new file (tried with a probe file, removed at once).
pub fn check_output(path: &Path, kinds: &[&str], what: &str) -> Result<()> {
    let shown = path.display();
    match extension(path) {
        Some(e) if kinds.contains(&e.as_str()) => {}
        _ => bail!("{shown}: not a {what} name (use {})", list(kinds)),
    }
    if path.is_dir() {
        bail!("{shown}: is a folder");
    }
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    if !dir.is_dir() {
        bail!("{shown}: the folder {} does not exist", dir.display());
    }
    let probe = dir.join(format!(".strata-probe-{}", std::process::id()));
    match std::fs::File::create(&probe) {
        Ok(_) => {
            let _ = std::fs::remove_file(&probe);
        }
        Err(e) => bail!("{shown}: cannot write in {}: {e}", dir.display()),
    }
    Ok(())
}

fn list(kinds: &[&str]) -> String {
    kinds.iter().map(|k| format!(".{k}")).collect::<Vec<_>>().join(", ")
}
