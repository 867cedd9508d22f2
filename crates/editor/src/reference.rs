//! Reference images: pictures placed in the scene as flat planes to sculpt against (a front and a
//! side drawing of a head, a map under a terrain), as Blender's reference images and ZBrush's
//! spotlight are used.
//!
//! A [`ReferenceImage`] is a [`Picture`] on a rectangle in the world: its middle, its turn (the
//! picture's right is the turn's x axis, its up the y axis, the side it shows its face to the z
//! axis), its width (its height follows the picture's aspect), its opacity, and whether it is
//! shown and whether it is locked (a locked one cannot be moved, turned, scaled or deleted until
//! unlocked). A new one is placed square to a [`ReferencePlane`] (the front, side or top view)
//! behind what it is a reference for, as those views see it.
//!
//! The picture keeps the file's bytes as they were loaded (a PNG or a JPEG), which is what scene
//! files store (see [`crate::file`]), and the pixels shown, decoded once and at most
//! [`SHOWN_SIDE`] a side. References are scene data: adding, changing and deleting them are
//! undo steps ([`crate::Editor::add_reference`]). They are each person's own view aids: a shared
//! room does not send them.

use std::hash::{Hash, Hasher};
use std::path::Path;
use std::sync::Arc;

use glam::{DQuat, DVec3};
use thiserror::Error;

/// The largest picture file read (bytes).
pub const MAX_PICTURE_BYTES: u64 = 64 << 20;
/// The largest picture decoded, a side (pixels).
pub const MAX_PICTURE_SIDE: u32 = 8192;
/// The largest side of the pixels shown: larger pictures are shown scaled down to it (the file's
/// bytes are kept whole).
pub const SHOWN_SIDE: u32 = 4096;
/// The most references a scene holds.
pub const MAX_REFERENCES: usize = 64;
/// The smallest and largest width of a reference (world units).
pub const WIDTH_RANGE: (f64, f64) = (1e-6, 1e9);

/// Why a picture could not be read.
#[derive(Debug, Error)]
pub enum PictureError {
    /// Reading the file failed, or it is larger than [`MAX_PICTURE_BYTES`].
    #[error("could not read the picture {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// Not a PNG or JPEG that decodes.
    #[error("{name} is not a picture Strata reads (PNG or JPEG): {reason}")]
    Decode {
        /// The file's name.
        name: String,
        /// What the decoder said.
        reason: String,
    },
    /// Empty, or more than [`MAX_PICTURE_SIDE`] a side.
    #[error("{name} is {width} × {height} pixels; a reference picture is 1 to {MAX_PICTURE_SIDE} pixels a side")]
    Size {
        /// The file's name.
        name: String,
        /// Its width.
        width: u32,
        /// Its height.
        height: u32,
    },
}

/// A picture: the file's bytes and the pixels shown.
#[derive(Clone)]
pub struct Picture {
    bytes: Arc<Vec<u8>>,
    key: u64,
    /// Height over width of the picture as decoded (the pixels shown may be rounded).
    aspect: f64,
    width: u32,
    height: u32,
    rgba: Arc<Vec<u8>>,
}

impl std::fmt::Debug for Picture {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Picture")
            .field("bytes", &self.bytes.len())
            .field("key", &format_args!("{:016x}", self.key))
            .field("shown", &(self.width, self.height))
            .finish()
    }
}

/// Two pictures are equal when their files' bytes are (the pixels shown follow from them).
impl PartialEq for Picture {
    fn eq(&self, other: &Self) -> bool {
        self.key == other.key && self.bytes == other.bytes
    }
}

impl Picture {
    /// Decodes `bytes` (a PNG or a JPEG; `name` names it in errors), scaling what is shown down
    /// to [`SHOWN_SIDE`] a side.
    pub fn decode(bytes: Vec<u8>, name: &str) -> Result<Picture, PictureError> {
        let decode_err = |e: image::ImageError| PictureError::Decode { name: name.to_string(), reason: e.to_string() };
        let reader = || {
            image::ImageReader::new(std::io::Cursor::new(&bytes[..]))
                .with_guessed_format()
                .map_err(|e| PictureError::Decode { name: name.to_string(), reason: e.to_string() })
        };
        // (The size from the header first: a huge picture is refused before it is decoded.)
        let (width, height) = reader()?.into_dimensions().map_err(decode_err)?;
        if width == 0 || height == 0 || width > MAX_PICTURE_SIDE || height > MAX_PICTURE_SIDE {
            return Err(PictureError::Size { name: name.to_string(), width, height });
        }
        let mut limits = image::Limits::default();
        limits.max_image_width = Some(MAX_PICTURE_SIDE);
        limits.max_image_height = Some(MAX_PICTURE_SIDE);
        // (Four bytes a pixel at most sixteen bits a channel: what the largest side allows.)
        limits.max_alloc = Some(2 * 4 * width as u64 * height as u64 + (16 << 20));
        let mut reader = reader()?;
        reader.limits(limits);
        // (Through the decoder, for its orientation: a phone's photo stores its pixels as the
        // sensor saw them and says in EXIF how to turn them.)
        let mut decoder = reader.into_decoder().map_err(decode_err)?;
        let orientation =
            image::ImageDecoder::orientation(&mut decoder).unwrap_or(image::metadata::Orientation::NoTransforms);
        let mut decoded = image::DynamicImage::from_decoder(decoder).map_err(decode_err)?;
        decoded.apply_orientation(orientation);
        let mut rgba = decoded.to_rgba8();
        let (width, height) = (rgba.width(), rgba.height());
        let side = width.max(height);
        if side > SHOWN_SIDE {
            let scale = SHOWN_SIDE as f64 / side as f64;
            let w = ((width as f64 * scale).round() as u32).clamp(1, SHOWN_SIDE);
            let h = ((height as f64 * scale).round() as u32).clamp(1, SHOWN_SIDE);
            rgba = image::imageops::thumbnail(&rgba, w, h);
        }
        let mut hasher = std::collections::hash_map::DefaultHasher::new();
        bytes.hash(&mut hasher);
        Ok(Picture {
            key: hasher.finish(),
            aspect: height as f64 / width as f64,
            width: rgba.width(),
            height: rgba.height(),
            rgba: Arc::new(rgba.into_raw()),
            bytes: Arc::new(bytes),
        })
    }

    /// Reads and decodes the picture at `path` (at most [`MAX_PICTURE_BYTES`]).
    pub fn load(path: &Path) -> Result<Picture, PictureError> {
        let bytes = strata_files::read_limited(path, MAX_PICTURE_BYTES)
            .map_err(|source| PictureError::Io { path: path.display().to_string(), source })?;
        let name = path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
        Picture::decode(bytes, &name)
    }

    /// The file's bytes as loaded.
    pub fn bytes(&self) -> &[u8] {
        &self.bytes
    }

    /// A hash of the file's bytes: the same picture always has the same key (a renderer keeps
    /// its texture by it).
    pub fn key(&self) -> u64 {
        self.key
    }

    /// The pixels shown: width, height and straight-alpha sRGB RGBA bytes, rows from the top.
    pub fn shown(&self) -> (u32, u32, &[u8]) {
        (self.width, self.height, &self.rgba)
    }

    /// Height over width (of the picture, not of the pixels shown, which are rounded when
    /// scaled down).
    pub fn aspect(&self) -> f64 {
        self.aspect
    }
}

/// The view a reference is placed square to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ReferencePlane {
    /// Facing +z, as the front view (numpad 1) sees it: right is +x, up +y.
    Front,
    /// Facing +x, as the right view (numpad 3) sees it: right is −z, up +y.
    Side,
    /// Facing +y, as the top view (numpad 7) sees it: right is +x, up −z.
    Top,
}

impl ReferencePlane {
    /// Every plane, in menu order.
    pub const ALL: [ReferencePlane; 3] = [ReferencePlane::Front, ReferencePlane::Side, ReferencePlane::Top];

    /// Its name in the UI.
    pub fn name(self) -> &'static str {
        match self {
            ReferencePlane::Front => "Front",
            ReferencePlane::Side => "Side",
            ReferencePlane::Top => "Top",
        }
    }

    /// The turn that lays a picture square to the view: its x axis the view's right, y its up,
    /// z towards the viewer.
    pub fn rotation(self) -> DQuat {
        match self {
            ReferencePlane::Front => DQuat::IDENTITY,
            ReferencePlane::Side => DQuat::from_rotation_y(std::f64::consts::FRAC_PI_2),
            ReferencePlane::Top => DQuat::from_rotation_x(-std::f64::consts::FRAC_PI_2),
        }
    }

    /// The world axis the picture faces (towards the viewer of the view).
    pub fn normal(self) -> DVec3 {
        self.rotation() * DVec3::Z
    }

    /// The turn that lays a picture square to the opposite view (back, left, bottom), upright
    /// and not mirrored as that view's camera sees it.
    pub fn opposite_rotation(self) -> DQuat {
        let half = match self {
            ReferencePlane::Front | ReferencePlane::Side => DQuat::from_rotation_y(std::f64::consts::PI),
            ReferencePlane::Top => DQuat::from_rotation_x(std::f64::consts::PI),
        };
        half * self.rotation()
    }
}

/// Why a reference was refused (the scene is unchanged).
#[derive(Clone, Debug, PartialEq, Error)]
pub enum ReferenceError {
    /// No reference with this number.
    #[error("there is no reference image {0}")]
    NoReference(usize),
    /// The reference is locked.
    #[error("reference image {0:?} is locked: unlock it to move, change or delete it")]
    Locked(String),
    /// A middle, turn, width or opacity that is not finite or out of range.
    #[error("reference image {0:?}: its position, turn, width or opacity is not finite or out of range")]
    Invalid(String),
    /// The scene holds [`MAX_REFERENCES`] already.
    #[error("a scene holds at most {MAX_REFERENCES} reference images")]
    TooMany,
    /// The editor is on a streamed world, which is not saved as a scene.
    #[error("reference images are for scenes: a streamed world does not keep them")]
    OnWorld,
}

/// A picture placed in the world.
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceImage {
    /// Shown in the references panel (the file's name when loaded).
    pub name: String,
    /// The picture.
    pub picture: Picture,
    /// The middle of the picture (world).
    pub center: DVec3,
    /// Its turn: x along the picture's width, y up it, z the way its face looks (unit).
    pub rotation: DQuat,
    /// Its width in world units (its height is the width times the picture's aspect).
    pub width: f64,
    /// 0 transparent to 1 opaque.
    pub opacity: f32,
    /// Drawn or not.
    pub visible: bool,
    /// A locked reference cannot be moved, turned, scaled or deleted.
    pub locked: bool,
}

impl ReferenceImage {
    /// `picture` square to `plane`, behind `bounds` (world; the scene's, if it has any) as that
    /// view sees them and as wide as their largest side, half transparent; without bounds, at
    /// the origin, 64 units wide.
    pub fn new(
        name: impl Into<String>,
        picture: Picture,
        plane: ReferencePlane,
        bounds: Option<(DVec3, DVec3)>,
    ) -> Self {
        ReferenceImage::facing(name, picture, plane.rotation(), bounds)
    }

    /// [`ReferenceImage::new`] turned by `rotation` (unit; its z axis the way the picture
    /// faces), placed behind `bounds` as seen from that side.
    pub fn facing(name: impl Into<String>, picture: Picture, rotation: DQuat, bounds: Option<(DVec3, DVec3)>) -> Self {
        let normal = rotation * DVec3::Z;
        let (center, width) = match bounds.filter(|(lo, hi)| lo.is_finite() && hi.is_finite()) {
            Some((lo, hi)) => {
                let mid = (lo + hi) * 0.5;
                let size = hi - lo;
                let depth = size.dot(normal.abs()) * 0.5;
                // Just behind the bounds, so the picture never cuts the model it shows.
                let back = depth + size.max_element() * 0.05 + 1e-3;
                (mid - normal * back, size.max_element().max(1e-3))
            }
            None => (DVec3::ZERO, 64.0),
        };
        ReferenceImage {
            name: name.into(),
            picture,
            center,
            rotation,
            width: width.clamp(WIDTH_RANGE.0, WIDTH_RANGE.1),
            opacity: 0.5,
            visible: true,
            locked: false,
        }
    }

    /// Its height in world units.
    pub fn height(&self) -> f64 {
        self.width * self.picture.aspect()
    }

    /// The corners (world): bottom left, bottom right, top right, top left of the picture as it
    /// faces its viewer.
    pub fn corners(&self) -> [DVec3; 4] {
        let right = self.rotation * DVec3::X * (self.width * 0.5);
        let up = self.rotation * DVec3::Y * (self.height() * 0.5);
        let c = self.center;
        [c - right - up, c + right - up, c + right + up, c - right + up]
    }

    /// The plane the picture lies in, if it lies square to a view (within a thousandth of a
    /// radian), whatever its turn within the plane and whichever way it faces.
    pub fn plane(&self) -> Option<ReferencePlane> {
        self.view().map(|(p, _)| p)
    }

    /// The view the picture faces, if it lies square to one: its plane, and whether it faces
    /// the opposite view (back, left, bottom).
    pub fn view(&self) -> Option<(ReferencePlane, bool)> {
        let facing = self.rotation * DVec3::Z;
        ReferencePlane::ALL.into_iter().find_map(|p| {
            let d = facing.dot(p.normal());
            (d.abs() > 1.0 - 5e-7).then_some((p, d < 0.0))
        })
    }

    /// Whether its middle, turn, width and opacity are finite and in range.
    pub fn is_valid(&self) -> bool {
        self.center.is_finite()
            && self.rotation.is_finite()
            && (self.rotation.length() - 1.0).abs() < 1e-6
            && self.width.is_finite()
            && (WIDTH_RANGE.0..=WIDTH_RANGE.1).contains(&self.width)
            && (0.0..=1.0).contains(&self.opacity)
    }

    /// The nearest valid reference: a middle that is not finite becomes the origin, a turn that
    /// cannot be normalised none, a width or an opacity out of range the nearest bound (a NaN
    /// width 64, a NaN opacity ½).
    pub fn repaired(&self) -> ReferenceImage {
        let l = self.rotation.length();
        let turned = self.rotation.is_finite() && l.is_finite() && l > 1e-9;
        ReferenceImage {
            center: if self.center.is_finite() { self.center } else { DVec3::ZERO },
            rotation: if turned { self.rotation / l } else { DQuat::IDENTITY },
            width: if self.width.is_nan() { 64.0 } else { self.width.clamp(WIDTH_RANGE.0, WIDTH_RANGE.1) },
            opacity: if self.opacity.is_nan() { 0.5 } else { self.opacity.clamp(0.0, 1.0) },
            ..self.clone()
        }
    }

    /// The same reference laid square to `plane`, keeping its middle and width.
    pub fn laid_to(&self, plane: ReferencePlane) -> ReferenceImage {
        ReferenceImage { rotation: plane.rotation(), ..self.clone() }
    }
}

/// Reference images in the editor: each change is an undo step (while the editor records
/// operations for a room, none is: the room's undo is of shared operations, and references are
/// not shared). Refused on a world (a world is not saved as a scene file).
impl crate::Editor {
    /// Adds `reference` as the last one (its numbers checked as [`ReferenceImage::is_valid`]
    /// checks them); returns its number.
    pub fn add_reference(&mut self, reference: ReferenceImage) -> Result<usize, crate::EditorError> {
        self.check_references()?;
        if self.scene.references.len() >= MAX_REFERENCES {
            return Err(ReferenceError::TooMany.into());
        }
        if !reference.is_valid() {
            return Err(ReferenceError::Invalid(reference.name).into());
        }
        let mut list = self.scene.references.clone();
        list.push(reference);
        self.replace_references(list, None, false);
        Ok(self.scene.references.len() - 1)
    }

    /// Replaces reference `i` with `reference`. A locked reference takes only a new name,
    /// opacity, visibility or lock: its place, turn and width stay (unlock it first, then move
    /// it). With `merge`, a change
    /// that follows another change of the references (as while a handle or a value is dragged)
    /// joins its undo step, so a drag is one step.
    pub fn set_reference(
        &mut self,
        i: usize,
        reference: ReferenceImage,
        merge: bool,
    ) -> Result<(), crate::EditorError> {
        self.check_references()?;
        let old = self.scene.references.get(i).ok_or(ReferenceError::NoReference(i))?;
        if !reference.is_valid() {
            return Err(ReferenceError::Invalid(reference.name).into());
        }
        let moved = old.center != reference.center
            || old.rotation != reference.rotation
            || old.width != reference.width
            || old.picture != reference.picture;
        if old.locked && moved {
            return Err(ReferenceError::Locked(old.name.clone()).into());
        }
        if *old == reference {
            return Ok(());
        }
        let mut list = self.scene.references.clone();
        list[i] = reference;
        self.replace_references(list, Some(i), merge);
        Ok(())
    }

    /// Deletes reference `i` (refused while it is locked) and returns it.
    pub fn remove_reference(&mut self, i: usize) -> Result<ReferenceImage, crate::EditorError> {
        self.check_references()?;
        let r = self.scene.references.get(i).ok_or(ReferenceError::NoReference(i))?;
        if r.locked {
            return Err(ReferenceError::Locked(r.name.clone()).into());
        }
        let mut list = self.scene.references.clone();
        let removed = list.remove(i);
        self.replace_references(list, None, false);
        Ok(removed)
    }

    fn check_references(&self) -> Result<(), crate::EditorError> {
        if self.world.is_some() {
            return Err(ReferenceError::OnWorld.into());
        }
        Ok(())
    }

    /// Puts `list` in place of the references as an undo step (`changed`: the one reference it
    /// changes, if it changes one alone). With `merge`, a change of one reference joins the
    /// newest step when that changed the same reference alone (a drag continuing); a joined
    /// change forgets the redo steps, as a new step does.
    fn replace_references(&mut self, list: Vec<ReferenceImage>, changed: Option<usize>, merge: bool) {
        self.end_stroke();
        let old = std::mem::replace(&mut self.scene.references, list);
        let joins = merge && changed.is_some_and(|i| self.history.last_is_reference(i));
        if self.records_ops() {
        } else if joins {
            self.history.forget_redo();
        } else {
            self.history.push(crate::HistoryEntry { references: Some(old), reference: changed, ..Default::default() });
        }
        self.revision += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A PNG of `w` × `h` pixels, red on the left half, blue on the right, the top row white.
    pub(crate) fn test_png(w: u32, h: u32) -> Vec<u8> {
        let mut img = image::RgbaImage::new(w, h);
        for (x, y, p) in img.enumerate_pixels_mut() {
            *p = if y == 0 {
                image::Rgba([255, 255, 255, 255])
            } else if x < w / 2 {
                image::Rgba([255, 0, 0, 255])
            } else {
                image::Rgba([0, 0, 255, 255])
            };
        }
        let mut out = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png).unwrap();
        out
    }

    #[test]
    fn pictures_decode_with_their_size_and_keep_their_bytes() {
        let bytes = test_png(8, 4);
        let p = Picture::decode(bytes.clone(), "t.png").unwrap();
        assert_eq!(p.bytes(), &bytes[..]);
        let (w, h, rgba) = p.shown();
        assert_eq!((w, h, rgba.len()), (8, 4, 8 * 4 * 4));
        assert_eq!(&rgba[..4], &[255, 255, 255, 255], "the first row is the top");
        assert_eq!(&rgba[8 * 4..][..4], &[255, 0, 0, 255], "the second row starts red");
        assert_eq!(p.aspect(), 0.5);
        assert_eq!(p, Picture::decode(bytes, "other name").unwrap());
    }

    #[test]
    fn a_photo_is_turned_as_its_exif_orientation_says() {
        use image::ImageEncoder;
        // A TIFF header and one IFD entry: orientation (0x0112), a SHORT, 6 (turn 90° clockwise).
        let exif = vec![0x49, 0x49, 0x2a, 0, 8, 0, 0, 0, 1, 0, 0x12, 0x01, 3, 0, 1, 0, 0, 0, 6, 0, 0, 0, 0, 0, 0, 0];
        let rgb: Vec<u8> = (0..8 * 4).flat_map(|i| if i % 8 < 4 { [255, 0, 0] } else { [0, 0, 255] }).collect();
        let mut bytes = Vec::new();
        let mut encoder = image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, 95);
        encoder.set_exif_metadata(exif).unwrap();
        encoder.write_image(&rgb, 8, 4, image::ExtendedColorType::Rgb8).unwrap();
        let p = Picture::decode(bytes, "photo.jpg").unwrap();
        let (w, h, rgba) = p.shown();
        assert_eq!((w, h), (4, 8), "stored 8 × 4, shown turned");
        assert_eq!(p.aspect(), 2.0);
        // Turned clockwise, the stored left (red) is at the top.
        assert!(rgba[0] > 200 && rgba[2] < 60, "{:?}", &rgba[..4]);
        assert!(rgba[(7 * 4) * 4 + 2] > 200, "the bottom is blue");
    }

    #[test]
    fn large_pictures_are_shown_scaled_down_and_kept_whole() {
        let bytes = test_png(SHOWN_SIDE + 100, 10);
        let p = Picture::decode(bytes.clone(), "wide.png").unwrap();
        let (w, h, _) = p.shown();
        assert_eq!(w, SHOWN_SIDE);
        assert!((9..=10).contains(&h), "{h}");
        assert_eq!(p.bytes().len(), bytes.len());
    }

    #[test]
    fn what_is_not_a_picture_is_refused_with_its_name() {
        let e = Picture::decode(b"not a picture at all".to_vec(), "notes.txt").unwrap_err();
        assert!(matches!(e, PictureError::Decode { .. }), "{e}");
        assert!(e.to_string().contains("notes.txt"), "{e}");
        let mut truncated = test_png(16, 16);
        truncated.truncate(truncated.len() / 2);
        assert!(Picture::decode(truncated, "half.png").is_err());
        let e = Picture::load(Path::new("/nonexistent/picture.png")).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/picture.png"), "{e}");
    }

    #[test]
    fn a_new_reference_faces_its_view_behind_the_bounds_upright() {
        let p = Picture::decode(test_png(4, 2), "p.png").unwrap();
        let bounds = Some((DVec3::new(0.0, 0.0, 0.0), DVec3::new(10.0, 20.0, 30.0)));
        for plane in ReferencePlane::ALL {
            let r = ReferenceImage::new("r", p.clone(), plane, bounds);
            assert!(r.is_valid());
            assert_eq!(r.plane(), Some(plane));
            assert_eq!(r.width, 30.0);
            assert!((r.height() - 15.0).abs() < 1e-9);
            // Behind the bounds along the view's axis, in their middle across it.
            let n = plane.normal();
            let lo_along = DVec3::ZERO.dot(n).min(DVec3::new(10.0, 20.0, 30.0).dot(n));
            assert!(r.center.dot(n) < lo_along, "{plane:?} {:?}", r.center);
            let [bl, br, tr, tl] = r.corners();
            for c in [bl, br, tr, tl] {
                assert!((c - r.center).dot(n).abs() < 1e-9, "flat");
            }
            // Upright and not mirrored as the view sees it: right and up as its camera's.
            let (right, up) = match plane {
                ReferencePlane::Front => (DVec3::X, DVec3::Y),
                ReferencePlane::Side => (DVec3::NEG_Z, DVec3::Y),
                ReferencePlane::Top => (DVec3::X, DVec3::NEG_Z),
            };
            assert!(((br - bl).normalize() - right).length() < 1e-9, "{plane:?}");
            assert!(((tl - bl).normalize() - up).length() < 1e-9, "{plane:?}");
        }
        // The opposite views (back, left, bottom): facing them, behind the bounds as they see
        // them, upright and not mirrored.
        for plane in ReferencePlane::ALL {
            let r = ReferenceImage::facing("r", p.clone(), plane.opposite_rotation(), bounds);
            assert_eq!(r.view(), Some((plane, true)));
            let n = -plane.normal();
            let lo_along = DVec3::ZERO.dot(n).min(DVec3::new(10.0, 20.0, 30.0).dot(n));
            assert!(r.center.dot(n) < lo_along, "{plane:?} opposite: {:?}", r.center);
            let [bl, br, _, tl] = r.corners();
            let (right, up) = match plane {
                ReferencePlane::Front => (DVec3::NEG_X, DVec3::Y),
                ReferencePlane::Side => (DVec3::Z, DVec3::Y),
                ReferencePlane::Top => (DVec3::X, DVec3::Z),
            };
            assert!(((br - bl).normalize() - right).length() < 1e-9, "{plane:?} opposite");
            assert!(((tl - bl).normalize() - up).length() < 1e-9, "{plane:?} opposite");
        }
        let lone = ReferenceImage::new("r", p, ReferencePlane::Front, None);
        assert_eq!((lone.center, lone.width), (DVec3::ZERO, 64.0));
    }

    #[test]
    fn bad_numbers_are_found_and_repaired_to_the_nearest_valid_reference() {
        let p = Picture::decode(test_png(2, 2), "p.png").unwrap();
        let good = ReferenceImage::new("r", p, ReferencePlane::Top, None);
        for bad in [
            ReferenceImage { center: DVec3::new(f64::NAN, 0.0, 0.0), ..good.clone() },
            ReferenceImage { rotation: DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0), ..good.clone() },
            ReferenceImage { width: f64::INFINITY, ..good.clone() },
            ReferenceImage { width: 0.0, ..good.clone() },
            ReferenceImage { opacity: f32::NAN, ..good.clone() },
            ReferenceImage { opacity: 1.5, ..good.clone() },
        ] {
            assert!(!bad.is_valid(), "{bad:?}");
            let fixed = bad.repaired();
            assert!(fixed.is_valid(), "{fixed:?}");
        }
        assert_eq!(good.repaired(), good);
        let turned = ReferenceImage { rotation: DQuat::from_rotation_z(0.3) * good.rotation, ..good.clone() };
        assert_eq!(turned.plane(), None, "a turn about an axis across the plane leaves it");
        let spun = ReferenceImage { rotation: good.rotation * DQuat::from_rotation_z(0.3), ..good.clone() };
        assert_eq!(spun.plane(), Some(ReferencePlane::Top), "a turn within the plane keeps it");
        assert_eq!(spun.laid_to(ReferencePlane::Front).plane(), Some(ReferencePlane::Front));
    }

    #[test]
    fn adding_moving_and_deleting_references_are_undo_steps_and_a_drag_is_one() {
        let p = Picture::decode(test_png(4, 4), "p.png").unwrap();
        let mut e = crate::Editor::default();
        let r = ReferenceImage::new("front", p.clone(), ReferencePlane::Front, None);
        let rev = e.revision();
        assert_eq!(e.add_reference(r.clone()).unwrap(), 0);
        assert!(e.revision() > rev, "unsaved work");
        for k in 1..=5 {
            let moved = ReferenceImage { center: DVec3::X * k as f64, ..r.clone() };
            e.set_reference(0, moved, k > 1).unwrap();
        }
        assert_eq!(e.scene.references[0].center, DVec3::X * 5.0);
        assert!(e.undo());
        assert_eq!(e.scene.references, vec![r.clone()], "the drag was one step");
        assert!(e.redo());
        assert_eq!(e.scene.references[0].center, DVec3::X * 5.0);
        // A drag's change never joins a step of another reference, nor the add.
        e.add_reference(ReferenceImage::new("second", p.clone(), ReferencePlane::Top, None)).unwrap();
        let steps = e.history().undo_len();
        e.set_reference(1, ReferenceImage { opacity: 0.9, ..e.scene.references[1].clone() }, true).unwrap();
        assert_eq!(e.history().undo_len(), steps + 1, "its own step");
        e.set_reference(0, ReferenceImage { opacity: 0.9, ..e.scene.references[0].clone() }, true).unwrap();
        assert_eq!(e.history().undo_len(), steps + 2, "its own step");
        assert!(e.undo() && e.undo() && e.undo());
        assert_eq!(e.scene.references.len(), 1);
        // A merged change after an undo forgets the stale redo step.
        e.set_reference(0, ReferenceImage { width: 3.0, ..e.scene.references[0].clone() }, false).unwrap();
        assert!(e.undo());
        e.set_reference(0, ReferenceImage { width: 4.0, ..e.scene.references[0].clone() }, false).unwrap();
        e.set_reference(0, ReferenceImage { width: 5.0, ..e.scene.references[0].clone() }, true).unwrap();
        assert!(!e.redo(), "nothing stale to redo");
        assert_eq!(e.scene.references[0].width, 5.0);
        let gone = e.remove_reference(0).unwrap();
        assert!(e.scene.references.is_empty());
        assert!(e.undo());
        assert_eq!(e.scene.references, vec![gone]);
        assert!(e.undo() && e.undo() && e.undo(), "the widths, the drag and the add");
        assert!(e.scene.references.is_empty(), "back before the add");
    }

    #[test]
    fn a_locked_reference_keeps_its_place_but_takes_opacity_and_its_unlock() {
        let p = Picture::decode(test_png(4, 4), "p.png").unwrap();
        let mut e = crate::Editor::default();
        let r = ReferenceImage { locked: true, ..ReferenceImage::new("side", p, ReferencePlane::Side, None) };
        e.add_reference(r.clone()).unwrap();
        let moved = ReferenceImage { width: 3.0, ..r.clone() };
        assert!(matches!(
            e.set_reference(0, moved, false),
            Err(crate::EditorError::Reference(ReferenceError::Locked(_)))
        ));
        let unlocked_and_moved = ReferenceImage { width: 3.0, locked: false, ..r.clone() };
        assert!(e.set_reference(0, unlocked_and_moved, false).is_err(), "unlock first, then move");
        assert!(matches!(e.remove_reference(0), Err(crate::EditorError::Reference(ReferenceError::Locked(_)))));
        e.set_reference(0, ReferenceImage { opacity: 0.9, visible: false, ..r.clone() }, false).unwrap();
        let unlocked = ReferenceImage { locked: false, ..e.scene.references[0].clone() };
        e.set_reference(0, unlocked.clone(), false).unwrap();
        e.set_reference(0, ReferenceImage { width: 3.0, ..unlocked }, false).unwrap();
        assert_eq!(e.scene.references[0].width, 3.0);
        let bad = ReferenceImage { opacity: f32::NAN, ..e.scene.references[0].clone() };
        assert!(e.set_reference(0, bad, false).is_err());
        assert!(e.set_reference(7, r.clone(), false).is_err());
        assert_eq!(e.scene.references[0].width, 3.0, "refusals change nothing");
        for _ in 0..MAX_REFERENCES - 1 {
            e.add_reference(ReferenceImage { locked: false, ..r.clone() }).unwrap();
        }
        assert!(matches!(e.add_reference(r), Err(crate::EditorError::Reference(ReferenceError::TooMany))));
    }
}
