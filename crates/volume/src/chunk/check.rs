//! The structural check of a chunk's own data, run on every load and by
//! [`crate::Volume::check_invariants`].

use super::*;

/// Structural problems found in a chunk's own data (see [`crate::Volume::check_invariants`]).
pub(crate) fn check_lists(lists: &ChunkLists) -> Result<(), String> {
    let level = lists.level();
    let n = level.cells();
    let per_axis = n * n;
    let s = level.steps_per_cell();
    let m = lists.crossing_count();
    if m == 0 {
        return Err("a chunk without crossings must be stored as uniform".into());
    }
    // The stored rows: one nonzero byte per row bit, then a zero byte to an even number.
    let stored = lists.stored_rows();
    if count_ones(lists.words.get(), field::ROWS, field::ROWS + ChunkLists::row_count(level)) != stored {
        return Err("stored row count is wrong".into());
    }
    let bytes = lists.row_bytes();
    if bytes[..stored].contains(&0) || bytes[stored..].iter().any(|&b| b != 0) {
        return Err("nonempty rows stored wrongly".into());
    }
    let values = lists.values();
    if values.len() < 2 * m || values[2 * m..].iter().any(|&v| v != 0) {
        return Err("crossing storage has the wrong size".into());
    }
    let raw = lists.raw_positions();
    let mut cross = 0usize;
    for axis in Axis::ALL {
        if lists.family_start(axis) != cross {
            return Err(format!("axis {axis:?} start offset is wrong"));
        }
        let nonempty = lists.family_nonempty(axis);
        for index in 0..per_axis {
            if !nonempty.get(index) {
                continue;
            }
            let mut last_edge: Option<usize> = None;
            loop {
                let Some(&stored) = raw.get(cross) else {
                    return Err("the nonempty bits name more lines than the crossings end".into());
                };
                cross += 1;
                let q = stored & !LAST;
                if (q as u32).is_multiple_of(s) {
                    return Err(format!("{axis:?} line {index}: crossing {q} sits on a node"));
                }
                let e = edge_of(LocalPos(q), level);
                if last_edge.is_some_and(|l| l >= e) {
                    return Err(format!("{axis:?} line {index}: crossings unsorted or two in one cell"));
                }
                last_edge = Some(e);
                if stored & LAST != 0 {
                    break;
                }
            }
        }
    }
    if cross != m {
        return Err("stored crossings not all named by the nonempty lines".into());
    }
    Ok(())
}
