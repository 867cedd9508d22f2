//! Autosave and crash recovery: while a scene has unsaved changes, a copy is written at a set
//! interval (on a worker thread, atomically, like any save) to a recovery file of this process
//! in the user's state folder; saving, opening, starting anew or quitting cleanly removes it.
//! A recovery file whose process no longer runs is what a crash or a kill left behind, and the
//! studio offers to recover it when it starts.

use std::path::{Path, PathBuf};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime};

use strata_editor::Scene;
use strata_editor::file;

use crate::studio::Studio;
use strata_viewport::view_of;

/// Where recovery files live: `$XDG_STATE_HOME/strata`, `~/.local/state/strata`, or a folder in
/// the temporary directory.
pub fn default_dir() -> PathBuf {
    if let Some(d) = std::env::var_os("XDG_STATE_HOME").filter(|d| !d.is_empty()) {
        return PathBuf::from(d).join("strata");
    }
    if let Some(h) = std::env::var_os("HOME").filter(|h| !h.is_empty()) {
        return PathBuf::from(h).join(".local/state/strata");
    }
    std::env::temp_dir().join("strata-recovery")
}

fn scene_file(dir: &Path, pid: u32) -> PathBuf {
    dir.join(format!("recovery-{pid}.strata"))
}

fn origin_file(dir: &Path, pid: u32) -> PathBuf {
    dir.join(format!("recovery-{pid}.origin"))
}

/// The periodic autosave of one studio.
#[derive(Debug)]
pub struct Autosave {
    dir: PathBuf,
    /// How often unsaved work is written (default one minute).
    pub interval: Duration,
    last: Instant,
    /// The editor revision in the recovery file, if one was written.
    written: Option<u64>,
    job: Option<(u64, JoinHandle<Result<(), String>>)>,
    /// The last autosave's error, for the status bar.
    pub error: Option<String>,
}

impl Autosave {
    /// An autosave into `dir` every minute.
    pub fn new(dir: PathBuf) -> Self {
        Autosave { dir, interval: Duration::from_secs(60), last: Instant::now(), written: None, job: None, error: None }
    }

    /// This process's recovery file.
    pub fn path(&self) -> PathBuf {
        scene_file(&self.dir, std::process::id())
    }

    /// Called every frame while there are unsaved changes: collects a finished write and starts
    /// the next when the interval has passed and the scene changed since the last one.
    pub fn tick(&mut self, studio: &Studio, revision: u64) {
        if let Some((rev, job)) = self.job.take_if(|(_, j)| j.is_finished()) {
            match job.join() {
                Ok(Ok(())) => {
                    self.written = Some(rev);
                    self.error = None;
                }
                Ok(Err(e)) => self.error = Some(e),
                Err(_) => self.error = Some("the autosave thread panicked".into()),
            }
        }
        if self.job.is_some() || self.written == Some(revision) || self.last.elapsed() < self.interval {
            return;
        }
        self.last = Instant::now();
        let mut scene: Scene = studio.scene_editor().scene.clone();
        scene.view = view_of(&studio.scene_camera());
        let (dir, origin) = (self.dir.clone(), studio.path.clone());
        let job = std::thread::spawn(move || write(&dir, &scene, origin.as_deref()));
        self.job = Some((revision, job));
    }

    /// Waits for a write in progress (tests, and before removing the file).
    pub fn wait(&mut self) {
        if let Some((rev, job)) = self.job.take()
            && let Ok(Ok(())) = job.join()
        {
            self.written = Some(rev);
        }
    }

    /// The work is safe elsewhere (saved, or given up): removes this process's recovery file.
    pub fn forget(&mut self) {
        self.wait();
        let pid = std::process::id();
        let _ = std::fs::remove_file(scene_file(&self.dir, pid));
        let _ = std::fs::remove_file(origin_file(&self.dir, pid));
        self.written = None;
        self.last = Instant::now();
    }
}

fn write(dir: &Path, scene: &Scene, origin: Option<&Path>) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("autosave: cannot create {}: {e}", dir.display()))?;
    let pid = std::process::id();
    let origin_text = origin.map(|p| p.display().to_string()).unwrap_or_default();
    file::write_atomically(&origin_file(dir, pid), |f| std::io::Write::write_all(f, origin_text.as_bytes()))
        .map_err(|e| format!("autosave: {e}"))?;
    file::save(scene, &scene_file(dir, pid)).map(|_| ()).map_err(|e| format!("autosave: {e}"))
}

/// A recovery file left by a process that no longer runs.
#[derive(Clone, Debug)]
pub struct Found {
    /// The recovery scene.
    pub path: PathBuf,
    /// The file the work belonged to, if it had one.
    pub origin: Option<PathBuf>,
    /// When it was written.
    pub modified: SystemTime,
}

impl Found {
    /// The autosaved scene.
    pub fn load(&self) -> Result<Scene, String> {
        file::load(&self.path).map(|l| l.scene).map_err(|e| e.to_string())
    }

    /// Removes the recovery files.
    pub fn discard(&self) {
        let _ = std::fs::remove_file(&self.path);
        let _ = std::fs::remove_file(self.path.with_extension("origin"));
    }

    /// "3 minutes ago" and the like.
    pub fn age_text(&self) -> String {
        let secs = self.modified.elapsed().map_or(0, |d| d.as_secs());
        match secs {
            0..=89 => "a minute ago or less".into(),
            90..=5399 => format!("{} minutes ago", (secs + 30) / 60),
            _ => format!("{} hours ago", (secs + 1800) / 3600),
        }
    }
}

/// The newest recovery file in `dir` whose process is gone.
pub fn find(dir: &Path) -> Option<Found> {
    let me = std::process::id();
    let mut best: Option<Found> = None;
    for e in std::fs::read_dir(dir).ok()?.flatten() {
        let name = e.file_name();
        let Some(pid) = name
            .to_str()
            .and_then(|n| n.strip_prefix("recovery-"))
            .and_then(|n| n.strip_suffix(".strata"))
            .and_then(|n| n.parse::<u32>().ok())
        else {
            continue;
        };
        if pid == me || process_runs(pid) {
            continue;
        }
        let Ok(modified) = e.metadata().and_then(|m| m.modified()) else { continue };
        let origin = strata_files::read_limited(&origin_file(dir, pid), 64 << 10)
            .ok()
            .and_then(|b| String::from_utf8(b).ok())
            .filter(|s| !s.is_empty())
            .map(PathBuf::from);
        if best.as_ref().is_none_or(|b| modified > b.modified) {
            best = Some(Found { path: e.path(), origin, modified });
        }
    }
    best
}

/// Whether a process with this id runs (where `/proc` tells; elsewhere assumed gone).
fn process_runs(pid: u32) -> bool {
    Path::new("/proc/self").exists() && Path::new(&format!("/proc/{pid}")).exists()
}
