//! A process writing PNGs is killed at random moments: the file left behind is always one
//! whole image, the old or the new, never a partial one. Needs no GPU: the images are made on
//! the CPU and written by [`Image::save_png`], the writer of every screenshot.

use std::path::{Path, PathBuf};

use strata_render::Image;
use strata_tests::files::kill_at_random_moments;

const SIZE: u32 = 1024;

/// Two images that differ in every pixel (noisy, so the PNG is megabytes and a write takes a
/// while).
fn images() -> [Image; 2] {
    [1u64, 2].map(|seed| {
        let mut x = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15);
        let rgba = (0..4 * SIZE * SIZE)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                (x as u8 & 0xfe) | seed as u8 & 1
            })
            .collect();
        Image { width: SIZE, height: SIZE, rgba }
    })
}

/// The pixels of the PNG at `path`, or why it could not be read.
fn decode(path: &Path) -> Result<Vec<u8>, String> {
    let file = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let mut reader = png::Decoder::new(std::io::BufReader::new(file)).read_info().map_err(|e| e.to_string())?;
    let mut buf = vec![0; reader.output_buffer_size().ok_or("no size")?];
    let info = reader.next_frame(&mut buf).map_err(|e| e.to_string())?;
    buf.truncate(info.buffer_size());
    Ok(buf)
}

fn temp_files(path: &Path) -> Vec<PathBuf> {
    let name = path.file_name().unwrap().to_string_lossy().into_owned();
    std::fs::read_dir(path.parent().unwrap())
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.file_name().unwrap().to_string_lossy().starts_with(&format!(".{name}.")))
        .collect()
}

/// Run by `png_writes_killed_midway_leave_the_old_or_the_new_image` in a child process: writes
/// the two images to the path in `STRATA_PNG_CHILD` in turn until it is killed.
#[test]
#[ignore = "a helper: run as a child process by the kill test"]
fn png_child_process() {
    let Ok(path) = std::env::var("STRATA_PNG_CHILD") else { return };
    let [a, b] = images();
    loop {
        a.save_png(Path::new(&path)).unwrap();
        b.save_png(Path::new(&path)).unwrap();
    }
}

#[test]
fn png_writes_killed_midway_leave_the_old_or_the_new_image() {
    let dir = std::env::temp_dir().join(format!("strata-png-kill-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("shot.png");
    let [a, b] = images();
    a.save_png(&path).unwrap();
    let mut left_temporary = 0;
    // The child needs tens of milliseconds to start and make its images; kill it later, at a
    // random moment of its writes.
    kill_at_random_moments("png_child_process", "STRATA_PNG_CHILD", &path, 30, 60_000..260_000, |round| {
        let pixels = decode(&path).unwrap_or_else(|e| panic!("round {round}: the PNG does not decode: {e}"));
        assert!(pixels == a.rgba || pixels == b.rgba, "round {round}: the PNG is neither image");
        let temps = temp_files(&path);
        left_temporary += temps.len();
        assert!(temps.len() <= 1, "round {round}: temporary files accumulate: {temps:?}");
    });
    // The next write removes what a killed write left.
    a.save_png(&path).unwrap();
    assert!(temp_files(&path).is_empty());
    eprintln!("{left_temporary} of 30 kills left a temporary file (removed by the next write)");
    std::fs::remove_dir_all(&dir).unwrap();
}
