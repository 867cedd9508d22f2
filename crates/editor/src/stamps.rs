//! The stamp tool's images and settings: the built-in stamps and grey-scale PNGs loaded from a
//! file, kept by the editor under the hash of their pixels (a tool setting names a stamp; the
//! image stays with the editor).

use std::collections::HashMap;
use std::hash::{Hash, Hasher};
use std::path::Path;
use std::sync::Arc;

use serde::{Deserialize, Serialize};
use strata_volume::tools::{BuiltinStamp, STAMP_MAX_SIDE, StampImage};
use thiserror::Error;

/// The surface moves by this fraction of the radius, times the field strength, where a stamp
/// is white.
pub const STAMP_HEIGHT: f64 = 0.2;

/// Which image the stamp tool uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum StampSource {
    /// One made in code.
    Builtin(BuiltinStamp),
    /// One loaded into the editor ([`crate::Editor::add_stamp`]), by the hash of its pixels.
    Loaded(u64),
}

impl Default for StampSource {
    fn default() -> Self {
        StampSource::Builtin(BuiltinStamp::Dome)
    }
}

/// How a stroke lays stamps.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum StampStroke {
    /// A stamp every dab spacing along the stroke, like any tool.
    #[default]
    Spray,
    /// One stamp: pressing places its middle, dragging sizes and turns it (its top points at the
    /// pointer), releasing applies it.
    Drag,
}

/// The stamp tool's settings.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct StampSettings {
    /// The image.
    pub source: StampSource,
    /// Spray or drag.
    pub stroke: StampStroke,
    /// A sprayed stamp's top points along the stroke (else up the pose's y axis: the world's
    /// up, or the surface normal's frame when brushes are oriented to the surface).
    pub follow_stroke: bool,
    /// A further turn about the surface normal, counter-clockwise seen from outside (degrees).
    pub angle: f64,
}

impl Default for StampSettings {
    fn default() -> Self {
        StampSettings { source: StampSource::default(), stroke: StampStroke::Spray, follow_stroke: false, angle: 0.0 }
    }
}

/// Why an image file could not become a stamp.
#[derive(Debug, Error)]
pub enum StampLoadError {
    /// Reading the file failed.
    #[error("could not read {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// Not a PNG, or a damaged one.
    #[error("{path} is not a PNG image this can read: {reason}")]
    Decode {
        /// The file.
        path: String,
        /// What the decoder said.
        reason: String,
    },
    /// Too large or empty.
    #[error("{path} is {width} × {height} pixels: a stamp must be 1 to {STAMP_MAX_SIDE} on a side")]
    Size {
        /// The file.
        path: String,
        /// Pixels across.
        width: u32,
        /// Pixels down.
        height: u32,
    },
}

/// Reads a PNG as a stamp: grey is the luminance of its colours (Rec. 709), times its alpha
/// where it has one; any bit depth, palette or grey; 16-bit images keep their precision.
pub fn load_png(path: &Path) -> Result<StampImage, StampLoadError> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| StampLoadError::Io { path: name.clone(), source })?;
    decode_png(&bytes, &name)
}

/// [`load_png`] on bytes in memory; `name` names them in errors.
pub fn decode_png(bytes: &[u8], name: &str) -> Result<StampImage, StampLoadError> {
    let decode = |e: png::DecodingError| StampLoadError::Decode { path: name.to_string(), reason: e.to_string() };
    let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::EXPAND);
    let mut reader = decoder.read_info().map_err(decode)?;
    let (width, height) = (reader.info().width, reader.info().height);
    if width == 0 || height == 0 || width as usize > STAMP_MAX_SIDE || height as usize > STAMP_MAX_SIDE {
        return Err(StampLoadError::Size { path: name.to_string(), width, height });
    }
    let size = reader.output_buffer_size().ok_or_else(|| StampLoadError::Decode {
        path: name.to_string(),
        reason: "the image is too large to decode".into(),
    })?;
    let mut buf = vec![0u8; size];
    let frame = reader.next_frame(&mut buf).map_err(decode)?;
    let channels = frame.color_type.samples();
    let wide = frame.bit_depth == png::BitDepth::Sixteen;
    let sample = |i: usize| -> f64 {
        if wide { u16::from_be_bytes([buf[2 * i], buf[2 * i + 1]]) as f64 / 65535.0 } else { buf[i] as f64 / 255.0 }
    };
    let pixels = width as usize * height as usize;
    let row = frame.line_size / if wide { 2 } else { 1 };
    if frame.color_type == png::ColorType::Indexed {
        return Err(StampLoadError::Decode { path: name.to_string(), reason: "its palette was not expanded".into() });
    }
    let mut values = Vec::with_capacity(pixels);
    for y in 0..height as usize {
        for x in 0..width as usize {
            let i = y * row + x * channels;
            let (grey, alpha) = match frame.color_type {
                png::ColorType::Grayscale => (sample(i), 1.0),
                png::ColorType::GrayscaleAlpha => (sample(i), sample(i + 1)),
                png::ColorType::Rgb | png::ColorType::Indexed => {
                    (luminance(sample(i), sample(i + 1), sample(i + 2)), 1.0)
                }
                png::ColorType::Rgba => (luminance(sample(i), sample(i + 1), sample(i + 2)), sample(i + 3)),
            };
            values.push(((grey * alpha).clamp(0.0, 1.0) * 65535.0).round() as u16);
        }
    }
    StampImage::new(width as usize, height as usize, values)
        .map_err(|e| StampLoadError::Decode { path: name.to_string(), reason: e.to_string() })
}

fn luminance(r: f64, g: f64, b: f64) -> f64 {
    0.2126 * r + 0.7152 * g + 0.0722 * b
}

/// The images the stamp tool can use: the built-in ones, made once, and those loaded.
#[derive(Clone, Debug, Default)]
pub struct StampLibrary {
    builtin: HashMap<BuiltinStamp, Arc<StampImage>>,
    loaded: Vec<Loaded>,
}

/// A picture loaded into the library.
#[derive(Clone, Debug)]
struct Loaded {
    id: u64,
    name: String,
    /// The file it came from, if any.
    path: Option<std::path::PathBuf>,
    image: Arc<StampImage>,
}

impl StampLibrary {
    /// The image of `source`, if the library has it (a built-in one is made on first use).
    pub fn image(&mut self, source: StampSource) -> Option<Arc<StampImage>> {
        match source {
            StampSource::Builtin(b) => Some(self.builtin.entry(b).or_insert_with(|| Arc::new(b.image())).clone()),
            StampSource::Loaded(id) => self.find(id).map(|l| l.image.clone()),
        }
    }

    fn find(&self, id: u64) -> Option<&Loaded> {
        self.loaded.iter().find(|l| l.id == id)
    }

    /// Adds `image` under `name` (the same pixels again are not added twice) and names it.
    pub fn add(&mut self, name: &str, image: StampImage) -> StampSource {
        self.insert(name.to_string(), None, image)
    }

    /// Adds `image` read from the file `path`, named by the file's name (see
    /// [`StampLibrary::add`]); the library remembers the path ([`StampLibrary::path`]).
    pub fn add_file(&mut self, path: &Path, image: StampImage) -> StampSource {
        let name = path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
        self.insert(name, Some(path.to_path_buf()), image)
    }

    fn insert(&mut self, name: String, path: Option<std::path::PathBuf>, image: StampImage) -> StampSource {
        let id = pixel_hash(&image);
        match self.loaded.iter_mut().find(|l| l.id == id) {
            Some(l) if l.path.is_none() => l.path = path,
            Some(_) => {}
            None => self.loaded.push(Loaded { id, name, path, image: Arc::new(image) }),
        }
        StampSource::Loaded(id)
    }

    /// The loaded stamps, in the order added: (source, name).
    pub fn loaded(&self) -> impl Iterator<Item = (StampSource, &str)> {
        self.loaded.iter().map(|l| (StampSource::Loaded(l.id), l.name.as_str()))
    }

    /// A name for `source`: the built-in one's, or the loaded file's.
    pub fn name(&self, source: StampSource) -> Option<&str> {
        match source {
            StampSource::Builtin(b) => Some(b.name()),
            StampSource::Loaded(id) => self.find(id).map(|l| l.name.as_str()),
        }
    }

    /// The file a loaded picture came from, if it came from one.
    pub fn path(&self, source: StampSource) -> Option<&Path> {
        match source {
            StampSource::Builtin(_) => None,
            StampSource::Loaded(id) => self.find(id).and_then(|l| l.path.as_deref()),
        }
    }
}

/// A hash of an image's size and pixels (FNV-1a, the same on every machine).
fn pixel_hash(image: &StampImage) -> u64 {
    struct Fnv(u64);
    impl Hasher for Fnv {
        fn finish(&self) -> u64 {
            self.0
        }
        fn write(&mut self, bytes: &[u8]) {
            for &b in bytes {
                self.0 = (self.0 ^ b as u64).wrapping_mul(0x0100_0000_01b3);
            }
        }
    }
    let mut h = Fnv(0xcbf2_9ce4_8422_2325);
    (image.width() as u64, image.height() as u64).hash(&mut h);
    for v in image.values() {
        h.write(&v.to_le_bytes());
    }
    h.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A PNG of `color` type and `depth` with the given raw rows.
    fn png(width: u32, height: u32, color: png::ColorType, depth: png::BitDepth, data: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        {
            let mut e = png::Encoder::new(&mut out, width, height);
            e.set_color(color);
            e.set_depth(depth);
            let mut w = e.write_header().unwrap();
            w.write_image_data(data).unwrap();
        }
        out
    }

    #[test]
    fn grey_colour_alpha_and_sixteen_bit_pngs_read_as_grey() {
        use png::{BitDepth, ColorType};
        let grey = png(2, 1, ColorType::Grayscale, BitDepth::Eight, &[0, 255]);
        assert_eq!(decode_png(&grey, "g").unwrap().values(), &[0, 65535]);
        let wide = png(1, 1, ColorType::Grayscale, BitDepth::Sixteen, &[0x80, 0x01]);
        assert_eq!(decode_png(&wide, "w").unwrap().values(), &[0x8001]);
        // Pure green is bright (Rec. 709), and alpha darkens.
        let rgba = png(2, 1, ColorType::Rgba, BitDepth::Eight, &[0, 255, 0, 255, 255, 255, 255, 0]);
        let v = decode_png(&rgba, "c").unwrap();
        assert_eq!(v.values()[1], 0, "a transparent pixel is black");
        assert!((v.values()[0] as f64 / 65535.0 - 0.7152).abs() < 1e-3);
        let ga = png(1, 1, ColorType::GrayscaleAlpha, BitDepth::Eight, &[255, 128]);
        assert!((decode_png(&ga, "ga").unwrap().values()[0] as f64 / 65535.0 - 128.0 / 255.0).abs() < 1e-4);
        // Two rows: the first is the top.
        let rows = png(1, 2, ColorType::Grayscale, BitDepth::Eight, &[255, 0]);
        assert_eq!(decode_png(&rows, "r").unwrap().sample(0.0, 1.0), 1.0);
    }

    #[test]
    fn damaged_or_oversized_pngs_are_clear_errors() {
        let good = png(2, 2, png::ColorType::Grayscale, png::BitDepth::Eight, &[1, 2, 3, 4]);
        assert!(matches!(decode_png(b"not a png", "x"), Err(StampLoadError::Decode { .. })));
        assert!(matches!(decode_png(&good[..good.len() - 20], "cut"), Err(StampLoadError::Decode { .. })));
        let big = png(STAMP_MAX_SIDE as u32 + 1, 1, png::ColorType::Grayscale, png::BitDepth::Eight, &[0; 4097]);
        let e = decode_png(&big, "big.png").unwrap_err();
        assert!(matches!(e, StampLoadError::Size { .. }) && e.to_string().contains("big.png"), "{e}");
        let missing = load_png(Path::new("/nonexistent/stamp.png")).unwrap_err();
        assert!(matches!(missing, StampLoadError::Io { .. }));
    }

    #[test]
    fn the_library_keeps_built_in_and_loaded_stamps_once_each() {
        let mut lib = StampLibrary::default();
        let dome = lib.image(StampSource::Builtin(BuiltinStamp::Dome)).unwrap();
        assert!(Arc::ptr_eq(&dome, &lib.image(StampSource::Builtin(BuiltinStamp::Dome)).unwrap()));
        let img = StampImage::new(1, 1, vec![7]).unwrap();
        let a = lib.add("a.png", img.clone());
        assert_eq!(lib.add("again.png", img), a, "the same pixels are the same stamp");
        assert_eq!(lib.loaded().count(), 1);
        assert_eq!(lib.name(a), Some("a.png"));
        assert_eq!(lib.image(a).unwrap().values(), &[7]);
        assert!(lib.image(StampSource::Loaded(12345)).is_none());
        let other = lib.add("b.png", StampImage::new(1, 1, vec![8]).unwrap());
        assert_ne!(other, a);
    }
}
