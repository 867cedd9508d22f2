//! Reference images in scene files: scenes with masks and references save and reopen equal,
//! version 5 files (before references) still open, damaged or hostile pictures are dropped and
//! named (never a panic), numbers out of range are repaired and said, and a shared room's
//! snapshot leaves them out.

use glam::{DQuat, DVec3};
use proptest::prelude::*;
use strata_editor::file::{self, decode, encode, load, save};
use strata_editor::{Picture, ReferenceImage, ReferencePlane, Scene};
use strata_volume::brush::Sphere;

/// A `w` × `h` picture in `format`: a colour ramp, so every pixel differs from its neighbours.
fn picture_bytes(w: u32, h: u32, format: image::ImageFormat) -> Vec<u8> {
    let img = image::RgbImage::from_fn(w, h, |x, y| image::Rgb([(x * 255 / w) as u8, (y * 255 / h) as u8, 128]));
    let mut out = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut out), format).unwrap();
    out
}

fn picture(w: u32, h: u32) -> Picture {
    Picture::decode(picture_bytes(w, h, image::ImageFormat::Png), "ramp.png").unwrap()
}

/// A scene with a sphere, a masked cap, and three references: front, side (locked, turned in
/// its plane, a JPEG) and top (hidden).
fn scene() -> Scene {
    let mut s = Scene::default();
    let v = &mut s.layers[0].volume;
    v.add(&Sphere::new(DVec3::new(10.0, 10.0, 10.0), 8.0).unwrap()).unwrap();
    let dab = strata_volume::tools::Dab::new(DVec3::new(10.0, 18.0, 10.0), 4.0, 1.0).unwrap();
    strata_volume::tools::mask(v, &dab, strata_volume::tools::MaskStroke::Add).unwrap();
    assert!(!v.mask().is_clear());
    let bounds = Some((DVec3::splat(2.0), DVec3::splat(18.0)));
    let jpeg = Picture::decode(picture_bytes(20, 12, image::ImageFormat::Jpeg), "side.jpg").unwrap();
    let front = ReferenceImage::new("front.png", picture(16, 24), ReferencePlane::Front, bounds);
    let side = ReferenceImage {
        locked: true,
        opacity: 0.8,
        rotation: ReferencePlane::Side.rotation() * DQuat::from_rotation_z(0.4),
        ..ReferenceImage::new("side.jpg", jpeg, ReferencePlane::Side, bounds)
    };
    let top = ReferenceImage {
        visible: false,
        width: 3.5,
        ..ReferenceImage::new("top", picture(5, 5), ReferencePlane::Top, None)
    };
    s.references = vec![front, side, top];
    s
}

fn temp(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("strata-references-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn scenes_with_masks_and_references_save_and_reopen_equal() {
    let s = scene();
    assert!(file::is_valid(&s));
    let path = temp("refs.strata");
    assert!(save(&s, &path).unwrap().is_clean());
    let back = load(&path).unwrap();
    assert!(back.report.is_clean(), "{}", back.report);
    assert_eq!(back.version, file::VERSION);
    assert_eq!(back.scene, s, "layers, masks and references all equal");
    assert_eq!(back.scene.references[1].picture.bytes(), s.references[1].picture.bytes(), "the JPEG kept as it was");
    assert_eq!(encode(&back.scene).unwrap(), encode(&s).unwrap(), "the same bytes again");
    assert_eq!(back.scene.layers[0].volume.mask(), s.layers[0].volume.mask());
}

#[test]
fn version_5_files_open_without_references_and_equal_otherwise() {
    let s = scene();
    let old = decode(&file::encode_version_5(&s).unwrap()).unwrap();
    assert_eq!(old.version, 5);
    assert!(old.report.is_clean(), "{}", old.report);
    assert!(old.scene.references.is_empty());
    assert_eq!(Scene { references: s.references.clone(), ..old.scene }, s);
}

#[test]
fn a_shared_rooms_snapshot_leaves_the_references_out_and_loading_one_keeps_your_own() {
    let s = scene();
    let bytes = file::encode_shared(&s).unwrap();
    let shared = decode(&bytes).unwrap();
    assert_eq!(shared.version, 5, "a snapshot is version 5, which builds before references read");
    assert!(shared.scene.references.is_empty());
    assert_eq!(shared.scene.layers, s.layers);
    assert_eq!(file::chunk_digests(&s).unwrap(), file::chunk_digests(&shared.scene).unwrap());
    // A hostile snapshot with pictures: they are left out unread, and said.
    let full = file::decode_shared(&encode(&s).unwrap()).unwrap();
    assert!(full.scene.references.is_empty());
    assert!(full.report.to_string().contains("left out"), "{}", full.report);
    // An editor loading a room's scene keeps its own references (hosting, a resync).
    let mut e = strata_editor::Editor::new(s.clone());
    let content = strata_editor::room::decode(&bytes).unwrap();
    assert!(e.load_room(&content).unwrap());
    assert_eq!(e.scene.references, s.references);
}

#[test]
fn a_damaged_picture_is_dropped_and_named_and_the_rest_opens() {
    let s = scene();
    let mut record = file::scene_record(&s, true).unwrap();
    // The front picture's bytes flipped (its checksum now fails), the side one's cut short with
    // a matching checksum (it fails to decode).
    let n = record.references[0].bytes.len();
    record.references[0].bytes[n / 2] ^= 0x40;
    let side = &mut record.references[1];
    side.bytes.truncate(side.bytes.len() / 3);
    side.crc = crc32fast::hash(&side.bytes);
    let back = decode(&file::encode_record(&record).unwrap()).unwrap();
    let said = back.report.to_string();
    assert!(said.contains("\"front.png\"") && said.contains("checksum"), "{said}");
    assert!(said.contains("\"side.jpg\"") && said.contains("does not decode"), "{said}");
    assert_eq!(back.scene.references, vec![s.references[2].clone()]);
    assert_eq!(back.scene.layers, s.layers, "the volume is untouched");
}

#[test]
fn references_out_of_range_are_repaired_and_said_and_too_many_are_cut() {
    let s = scene();
    let mut record = file::scene_record(&s, true).unwrap();
    record.references[0].opacity = f32::NAN;
    record.references[1].width = -4.0;
    record.references[2].rotation = DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0);
    record.references[2].center = DVec3::new(f64::INFINITY, 0.0, 0.0);
    let back = decode(&file::encode_record(&record).unwrap()).unwrap();
    assert!(back.scene.references.iter().all(ReferenceImage::is_valid));
    assert_eq!(back.report.repairs.len(), 3, "{}", back.report);
    assert_eq!(back.scene.references[0].opacity, 0.5);
    assert_eq!(back.scene.references[2].rotation, DQuat::IDENTITY);
    // Saving an invalid scene writes the repaired one and says so.
    let mut bad = s.clone();
    bad.references[0].width = f64::NAN;
    let path = temp("repaired.strata");
    let report = save(&bad, &path).unwrap();
    assert_eq!(report.repairs.len(), 1, "{report}");
    assert!(load(&path).unwrap().scene.references[0].is_valid());
    // More than a scene holds: the first ones are kept.
    let mut many = file::scene_record(&s, true).unwrap();
    let one = file::scene_record(&s, true).unwrap().references.remove(2);
    many.references = (0..strata_editor::reference::MAX_REFERENCES + 3)
        .map(|i| file::ReferenceRecord { name: format!("r{i}"), bytes: one.bytes.clone(), ..one.clone() })
        .collect();
    let back = decode(&file::encode_record(&many).unwrap()).unwrap();
    assert_eq!(back.scene.references.len(), strata_editor::reference::MAX_REFERENCES);
    assert!(back.report.to_string().contains("were dropped"), "{}", back.report);
}

fn plane() -> impl Strategy<Value = ReferencePlane> {
    prop_oneof![Just(ReferencePlane::Front), Just(ReferencePlane::Side), Just(ReferencePlane::Top)]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Any valid references round trip exactly, whatever their plane, turn, size, opacity and
    /// flags.
    #[test]
    fn random_references_round_trip_exactly(
        refs in prop::collection::vec(
            (plane(), -3.0f64..3.0, prop::array::uniform3(-1e3f64..1e3), 1e-3f64..1e4, 0.0f32..=1.0, any::<bool>(), any::<bool>(), 1u32..9, 1u32..9),
            0..5,
        ),
    ) {
        let mut s = Scene::default();
        for (i, (plane, turn, at, width, opacity, visible, locked, w, h)) in refs.into_iter().enumerate() {
            s.references.push(ReferenceImage {
                name: format!("ref {i}"),
                picture: picture(w, h),
                center: DVec3::from_array(at),
                rotation: plane.rotation() * DQuat::from_rotation_z(turn),
                width,
                opacity,
                visible,
                locked,
            });
        }
        prop_assert!(file::is_valid(&s));
        let back = decode(&encode(&s).unwrap()).unwrap();
        prop_assert!(back.report.is_clean());
        prop_assert_eq!(back.scene, s);
    }

    /// Picture bytes damaged behind a matching checksum (what a hostile file holds) never make
    /// the reader panic: the reference opens or is dropped and named.
    #[test]
    fn hostile_picture_bytes_never_panic(flips in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8), jpeg in any::<bool>()) {
        let format = if jpeg { image::ImageFormat::Jpeg } else { image::ImageFormat::Png };
        let mut s = Scene::default();
        let p = Picture::decode(picture_bytes(12, 7, format), "p").unwrap();
        s.references.push(ReferenceImage::new("victim", p, ReferencePlane::Front, None));
        let mut record = file::scene_record(&s, true).unwrap();
        let bytes = &mut record.references[0].bytes;
        for (at, value) in flips {
            let i = at.index(bytes.len());
            bytes[i] = value;
        }
        record.references[0].crc = crc32fast::hash(&record.references[0].bytes);
        let back = decode(&file::encode_record(&record).unwrap()).unwrap();
        prop_assert!(back.scene.references.len() == 1 || back.report.to_string().contains("\"victim\""));
    }
}
