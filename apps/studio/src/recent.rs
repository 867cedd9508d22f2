//! Recently opened and saved scenes, newest first, kept in a text file (one path a line) beside
//! the recovery files, so the list survives restarts.

use std::path::{Path, PathBuf};

/// The file the list lives in, in the recovery folder.
pub const FILE_NAME: &str = "recent.txt";

/// How many scenes the list keeps.
pub const KEEP: usize = 8;

/// The recent-files list.
#[derive(Debug, Default)]
pub struct Recent {
    file: PathBuf,
    paths: Vec<PathBuf>,
}

impl Recent {
    /// The list stored at `file` (empty if it cannot be read, is not text or is over 64 KiB;
    /// paths that no longer exist are dropped).
    pub fn load(file: PathBuf) -> Self {
        let paths = strata_files::read_limited(&file, 64 << 10)
            .ok()
            .and_then(|bytes| String::from_utf8(bytes).ok())
            .map(|text| text.lines().filter(|l| !l.is_empty()).map(PathBuf::from).filter(|p| p.is_file()).collect())
            .unwrap_or_default();
        let mut r = Recent { file, paths };
        r.paths.truncate(KEEP);
        r
    }

    /// The scenes, newest first.
    pub fn paths(&self) -> &[PathBuf] {
        &self.paths
    }

    /// Puts `path` first (once) and writes the list; a list that cannot be written stays in
    /// memory.
    pub fn add(&mut self, path: &Path) {
        let path = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
        self.paths.retain(|p| *p != path);
        self.paths.insert(0, path);
        self.paths.truncate(KEEP);
        if let Some(dir) = self.file.parent() {
            let _ = std::fs::create_dir_all(dir);
        }
        let text: String = self.paths.iter().map(|p| format!("{}\n", p.display())).collect();
        let _ = strata_files::write_atomically::<std::io::Error>(&self.file, |f| {
            std::io::Write::write_all(f, text.as_bytes())
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recent_scenes_are_kept_newest_first_and_survive_a_restart() {
        let dir = std::env::temp_dir().join(format!("strata-recent-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let scene = |i: usize| {
            let p = dir.join(format!("s{i}.strata"));
            std::fs::write(&p, b"x").unwrap();
            std::fs::canonicalize(p).unwrap()
        };
        let mut r = Recent::load(dir.join(FILE_NAME));
        assert!(r.paths().is_empty());
        for i in 0..10 {
            r.add(&scene(i));
        }
        r.add(&scene(3));
        assert_eq!(r.paths().len(), KEEP);
        assert_eq!(r.paths()[0], scene(3), "the newest first");
        assert_eq!(r.paths()[1], scene(9));
        std::fs::remove_file(scene(9)).unwrap();
        let again = Recent::load(dir.join(FILE_NAME));
        assert_eq!(again.paths()[0], scene(3));
        assert!(!again.paths().contains(&dir.join("s9.strata")), "a deleted scene is dropped");
    }
}
