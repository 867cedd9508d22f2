//! # strata-files
//!
//! The one way every Strata writer and reader touches a file: scenes, mesh exports, PNGs,
//! presets and recovery files all go through here.
//!
//! - [`write_atomically`]: into a temporary file beside the target whose name is unique to the
//!   write (process, a counter, the time), synced, renamed over the target, the folder synced.
//!   A crash or an error mid-write keeps the old file; two writes to one path, from one process
//!   or several, never share a temporary file; temporary files of killed writes are removed by
//!   the next write of the same target.
//! - [`read_limited`]: a whole regular file of at most a stated size, refused before reading
//!   anything larger (and again if it grows meanwhile).
//!
//! The terrain's world files are redb databases: redb makes their commits durable itself.
#![warn(missing_docs)]

mod atomic;
mod read;

pub use atomic::{stale_temp_files, temp_path, write_atomically};
pub use read::read_limited;
