//! Bounded reads: a file is read whole only when it is a regular file within a stated size,
//! checked before the first byte and again while reading.

use std::io::{self, Read};
use std::path::Path;

/// Reads the whole regular file at `path`, refusing (with [`io::ErrorKind::InvalidInput`])
/// anything that is not a regular file or holds more than `limit` bytes, before reading it and
/// again while reading it (a file that grows meanwhile).
pub fn read_limited(path: &Path, limit: u64) -> io::Result<Vec<u8>> {
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        return Err(io::Error::new(io::ErrorKind::InvalidInput, "not a regular file"));
    }
    let too_large = || io::Error::new(io::ErrorKind::InvalidInput, format!("larger than the limit of {limit} bytes"));
    if meta.len() > limit {
        return Err(too_large());
    }
    let f = std::fs::File::open(path)?;
    // Checked again on the open file: the path may have been replaced since.
    if !f.metadata()?.is_file() {
        return Err(io::Error::new(io::ErrorKind::InvalidInput, "not a regular file"));
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    f.take(limit.saturating_add(1)).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(too_large());
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_within_the_limit_and_refuses_past_it_or_a_folder() {
        let d = std::env::temp_dir().join(format!("strata-read-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        let f = d.join("x.bin");
        std::fs::write(&f, [7u8; 100]).unwrap();
        assert_eq!(read_limited(&f, 100).unwrap(), vec![7u8; 100]);
        let e = read_limited(&f, 99).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidInput);
        assert!(e.to_string().contains("99 bytes"), "{e}");
        assert_eq!(read_limited(&d, 1 << 20).unwrap_err().kind(), io::ErrorKind::InvalidInput);
        assert_eq!(read_limited(&d.join("missing"), 10).unwrap_err().kind(), io::ErrorKind::NotFound);
        std::fs::remove_dir_all(&d).unwrap();
    }
}
