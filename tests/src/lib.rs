//! Shared helpers for the cross-crate scenarios (also used by other crates' tests).

pub mod collab;
pub mod files;

use glam::DVec3;

/// The box `[min, min + size]` as twelve triangles over its eight corners, counter-clockwise
/// from outside: with integer corners, every face lies on a grid plane.
pub fn box_mesh(min: DVec3, size: DVec3) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let v =
        (0..8).map(|i| min + size * DVec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64)).collect();
    let t = vec![
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ];
    (v, t)
}

/// The nice value this process started with (its main thread's), read from `/proc` (Linux;
/// `None` elsewhere). A thread may not take a higher priority than this without privileges.
pub fn process_nice() -> Option<i32> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    nice_field(&stat)
}

/// The nice value in a `/proc/.../stat` line: after the name in parentheses come the fields
/// from the third on; the nice value is the nineteenth.
fn nice_field(stat: &str) -> Option<i32> {
    let rest = stat.rfind(')').map(|i| &stat[i + 1..])?;
    rest.split_whitespace().nth(16).and_then(|f| f.parse().ok())
}

/// The nice values of this process's threads whose names start with `prefix`, read from
/// `/proc` (Linux; empty elsewhere). Higher is a lower scheduling priority.
pub fn thread_nice(prefix: &str) -> Vec<i32> {
    let Ok(tasks) = std::fs::read_dir("/proc/self/task") else { return Vec::new() };
    let mut out = Vec::new();
    for task in tasks.flatten() {
        let Ok(name) = std::fs::read_to_string(task.path().join("comm")) else { continue };
        if !name.trim_end().starts_with(prefix) {
            continue;
        }
        let Ok(stat) = std::fs::read_to_string(task.path().join("stat")) else { continue };
        if let Some(nice) = nice_field(&stat) {
            out.push(nice);
        }
    }
    out
}
