use super::cursor::skip_marks;
use super::*;
use crate::Volume;
use crate::brush::Sphere;
use glam::{DVec3, I64Vec3};

fn spheres() -> [Sphere; 2] {
    [Sphere::new(DVec3::new(7.3, 9.1, 5.6), 6.2).unwrap(), Sphere::new(DVec3::new(3.0, 12.5, 4.0), 3.1).unwrap()]
}

fn sample_lists() -> (Volume, ChunkLists) {
    sample_lists_at(Level::BASE)
}

/// The sample chunk, lowered or raised to `level`.
fn sample_lists_at(level: Level) -> (Volume, ChunkLists) {
    let mut v = Volume::new();
    let [a, b] = spheres();
    v.add(&a).unwrap();
    v.subtract(&b).unwrap();
    v.set_chunk_level(crate::ChunkKey::new(0, 0, 0), level);
    assert_eq!(v.stored_level(crate::ChunkKey::new(0, 0, 0)), Some(level));
    let lists = match v.chunk(crate::ChunkKey::new(0, 0, 0)) {
        Some(Chunk::Lists(l)) => l.clone(),
        other => panic!("expected lists, got {other:?}"),
    };
    (v, lists)
}

#[test]
fn derived_start_states_equal_the_node_states() {
    let (_, lists) = sample_lists();
    let [a, b] = spheres();
    let n = lists.level().cells();
    for axis in Axis::ALL {
        let starts = lists.family_starts(axis);
        let mut cursor = lists.cursor(axis, 0);
        for index in 0..n * n {
            let (u, w) = (index % n, index / n);
            let node = I64Vec3::from_array(crate::axis::compose(axis, 0, u as i64, w as i64));
            let inside = |s: &Sphere| crate::brush_contains_node(s, node, Level::BASE);
            let expect = inside(&a) && !inside(&b);
            assert_eq!(starts.get(index), expect, "{axis:?} line {index}");
            assert_eq!(cursor.next_line().start_inside, expect);
        }
    }
}

#[test]
fn serialised_lists_round_trip_at_every_level() {
    for level in Level::ALL {
        let (_, lists) = sample_lists_at(level);
        let bytes = postcard::to_allocvec(&lists).unwrap();
        let raw = postcard::from_bytes::<RawChunkLists>(&bytes).unwrap_or_else(|e| panic!("level {level:?}: {e}"));
        let back = ChunkLists::from_raw(raw).unwrap_or_else(|e| panic!("level {level:?}: {e}"));
        assert_eq!(back, lists, "level {level:?}");
        assert_eq!(back.level(), level);
    }
}

#[test]
fn serialised_lists_round_trip_and_tampering_is_refused() {
    let (_, lists) = sample_lists();
    let bytes = postcard::to_allocvec(&lists).unwrap();
    assert_eq!(postcard::from_bytes::<ChunkLists>(&bytes).unwrap(), lists);
    let raw = || postcard::from_bytes::<RawChunkLists>(&bytes).unwrap();
    let refuse = |r: RawChunkLists, why: &str| {
        let b = postcard::to_allocvec(&r).unwrap();
        assert!(postcard::from_bytes::<ChunkLists>(&b).is_err(), "accepted: {why}");
    };
    let mut r = raw();
    let last = r.positions.iter().position(|&q| q & LAST != 0).unwrap();
    r.positions[last] &= !LAST;
    refuse(r, "a line without its end mark");
    let mut r = raw();
    r.positions[0] |= LAST;
    refuse(r, "an extra end mark");
    let mut r = raw();
    r.nonempty[0] ^= 1 << r.nonempty[0].trailing_zeros();
    refuse(r, "a nonempty line marked empty");
    let mut r = raw();
    r.family_start[0] += 1;
    refuse(r, "a wrong family offset");
    let mut r = raw();
    r.normals = r.normals[1..].into();
    refuse(r, "normals missing");
    let mut r = raw();
    r.positions[0] = 0;
    refuse(r, "a crossing on a node");
    let mut r = raw();
    r.nonempty = r.nonempty[1..].into();
    refuse(r, "nonempty bits cut short");
    let mut r = raw();
    r.positions = vec![2; 3 * 16 * 16 * 16 + 1].into();
    r.normals = r.positions.clone();
    refuse(r, "more crossings than cells");
}

#[test]
fn skipping_end_marks_agrees_with_a_scalar_loop() {
    // A word-aligned buffer, read from several offsets (aligned and not).
    let mut words = vec![0u64; 40];
    let raw: &mut [u16] = bytemuck::cast_slice_mut(&mut words);
    let mut seed = 3u64;
    for q in raw.iter_mut() {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        *q = ((seed >> 40) as u16) & !LAST | u16::from((seed >> 20).is_multiple_of(3));
    }
    let raw: &[u16] = raw;
    let marks = raw.iter().filter(|&&q| q & LAST != 0).count();
    for from in [0, 1, 3, 4, 5, 17, 64] {
        let ahead = raw[from..].iter().filter(|&&q| q & LAST != 0).count();
        for k in 0..=ahead {
            let mut i = from;
            let mut left = k;
            while left > 0 {
                left -= (raw[i] & LAST) as usize;
                i += 1;
            }
            assert_eq!(skip_marks(raw, from, k), i, "from {from} k {k}");
        }
    }
    assert!(marks > 20);
}

#[test]
fn counting_ones_agrees_with_a_bit_loop() {
    let words = [0x0123_4567_89ab_cdefu64, u64::MAX, 0, 0xf0f0_0000_ffff_0001];
    for from in 0..256 {
        for to in from..=256 {
            let expect = (from..to).filter(|&i| (words[i >> 6] >> (i & 63)) & 1 == 1).count();
            assert_eq!(count_ones(&words, from, to), expect, "{from}..{to}");
        }
    }
}

#[test]
fn bit_fields_and_nonzero_bytes_agree_with_plain_loops() {
    let mut seed = 5u64;
    let mut next = move || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        seed
    };
    for _ in 0..2000 {
        // Words with many zero and 0x80 bytes.
        let w = next() & next() & 0x80ff_00ff_8000_ff80 | (next() & 0x0080_0080_0000_0001);
        let plain = w.to_le_bytes().iter().filter(|&&b| b != 0).count();
        assert_eq!(nonzero_bytes(w), plain, "{w:#x}");
        let (start, width) = ((next() % 120) as usize, (next() % 64 + 1) as u32);
        let value = next() & if width == 64 { u64::MAX } else { (1 << width) - 1 };
        let mut words = [0u64; 3];
        write_bits(&mut words, start, width, value);
        assert_eq!(read_bits(&words, start, width), value, "{start} {width}");
        let set: usize = words.iter().map(|w| w.count_ones() as usize).sum();
        assert_eq!(set, value.count_ones() as usize, "nothing outside the field is written");
    }
}
