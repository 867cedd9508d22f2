//! Atomic, durable writes: into a temporary file beside the target with a name unique to the
//! write, synced, renamed over the target, the folder synced. A crash or an error mid-write keeps
//! the old file; two writes to one path, from one process or several, never share a temporary
//! file.

use std::fs;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// The suffix of every temporary file.
const TEMP_SUFFIX: &str = ".strata-tmp";

/// A name unique to one write (process, a counter, the time), for the temporary file beside
/// `path`: `.NAME.PID-COUNTER-NANOS.strata-tmp`.
pub fn temp_path(path: &Path) -> PathBuf {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let count = COUNTER.fetch_add(1, Ordering::Relaxed);
    let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.subsec_nanos());
    let mut name = std::ffi::OsString::from(".");
    name.push(path.file_name().unwrap_or_default());
    name.push(format!(".{}-{count}-{nanos}{TEMP_SUFFIX}", std::process::id()));
    path.with_file_name(name)
}

/// Temporary files of writes of `path` whose process is gone (killed mid-write), which the next
/// write removes. Only files named by [`temp_path`] for this very target are considered, and
/// only when their process no longer runs (on systems without `/proc`, when they are over an
/// hour old), so a write in progress in another process is never disturbed.
pub fn stale_temp_files(path: &Path) -> Vec<PathBuf> {
    let Some(name) = path.file_name().and_then(|n| n.to_str()) else { return Vec::new() };
    let prefix = format!(".{name}.");
    let Ok(entries) = fs::read_dir(parent(path)) else { return Vec::new() };
    let me = std::process::id();
    let mut out = Vec::new();
    for e in entries.flatten() {
        let file = e.file_name();
        let Some(file) = file.to_str() else { continue };
        let Some(rest) = file.strip_prefix(&prefix).and_then(|r| r.strip_suffix(TEMP_SUFFIX)) else { continue };
        let Some(pid) = rest.split('-').next().and_then(|p| p.parse::<u32>().ok()) else { continue };
        if pid == me || rest.split('-').count() != 3 {
            continue;
        }
        let gone = if Path::new("/proc/self").exists() {
            !Path::new(&format!("/proc/{pid}")).exists()
        } else {
            e.metadata()
                .and_then(|m| m.modified())
                .ok()
                .and_then(|t| t.elapsed().ok())
                .is_some_and(|age| age > std::time::Duration::from_secs(3600))
        };
        if gone {
            out.push(e.path());
        }
    }
    out
}

/// Writes through `write` into a temporary file beside `path` (see [`temp_path`]), syncs it,
/// renames it over `path` and syncs the folder. If anything fails, the temporary file is
/// removed and `path` is untouched. Stale temporary files of earlier, killed writes of `path`
/// are removed first.
pub fn write_atomically<E: From<io::Error>>(
    path: &Path,
    write: impl FnOnce(&mut fs::File) -> Result<(), E>,
) -> Result<(), E> {
    for stale in stale_temp_files(path) {
        let _ = fs::remove_file(stale);
    }
    let tmp = temp_path(path);
    let result = (|| {
        let mut f = fs::OpenOptions::new().write(true).create_new(true).open(&tmp)?;
        write(&mut f)?;
        f.sync_all()?;
        drop(f);
        fs::rename(&tmp, path)?;
        sync_parent(path)?;
        Ok(())
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result
}

/// The folder holding `path` (`.` for a bare name).
fn parent(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Syncs the folder holding `path`, so a rename into it survives a power cut.
fn sync_parent(path: &Path) -> io::Result<()> {
    #[cfg(unix)]
    {
        fs::File::open(parent(path))?.sync_all()
    }
    #[cfg(not(unix))]
    {
        // Folders cannot be opened for syncing here; the rename itself is what the system offers.
        let _ = path;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("strata-atomic-{}-{name}", std::process::id()));
        let _ = fs::remove_dir_all(&d);
        fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn writes_to_one_path_from_many_threads_never_mix_and_leave_no_temporary_files() {
        let d = dir("threads");
        let path = d.join("mesh.stl");
        // Each thread writes a file of its own byte, 64 KiB long, in small pieces.
        std::thread::scope(|s| {
            for t in 0..8u8 {
                let path = &path;
                s.spawn(move || {
                    for _ in 0..4 {
                        write_atomically::<io::Error>(path, |f| {
                            for _ in 0..64 {
                                f.write_all(&[t; 1024])?;
                            }
                            Ok(())
                        })
                        .unwrap();
                    }
                });
            }
        });
        let bytes = fs::read(&path).unwrap();
        assert_eq!(bytes.len(), 64 * 1024, "one whole write");
        assert!(bytes.iter().all(|&b| b == bytes[0]), "from one writer only");
        let left: Vec<_> = fs::read_dir(&d).unwrap().flatten().map(|e| e.file_name()).collect();
        assert_eq!(left, vec![std::ffi::OsString::from("mesh.stl")], "no temporary file left");
        fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_failed_write_keeps_the_old_file_and_removes_its_temporary() {
        let d = dir("fail");
        let path = d.join("shot.png");
        fs::write(&path, b"old").unwrap();
        let r = write_atomically(&path, |f| {
            f.write_all(b"half")?;
            Err(io::Error::other("disk full"))
        });
        assert!(r.is_err());
        assert_eq!(fs::read(&path).unwrap(), b"old");
        assert_eq!(fs::read_dir(&d).unwrap().count(), 1);
        fs::remove_dir_all(&d).unwrap();
    }
}
