use super::*;

#[test]
fn encodings_round_trip_and_are_canonical() {
    let n = 16;
    let mut rows = vec![0u128; n * n];
    rows[3] = 0b1111_0000_1111;
    rows[200] = (1 << 16) - 1;
    let mut ids = vec![0u8; n * n * n];
    for (i, v) in ids.iter_mut().enumerate() {
        *v = (i / 700) as u8;
    }
    let enc = ChunkMaterials::encode(&ids, &rows, n).expect("mixed");
    assert!(matches!(enc, ChunkMaterials::Runs(_)));
    enc.check(&rows, n).unwrap();
    let mut back = Vec::new();
    ChunkMaterials::decode_into(Some(&enc), n * n * n, &mut back);
    for (r, &row) in rows.iter().enumerate() {
        for x in 0..n {
            if row >> x & 1 == 1 {
                assert_eq!(back[x + n * r], ids[x + n * r]);
            }
        }
    }
    // One id everywhere: uniform, and nothing at all for id 0.
    assert_eq!(ChunkMaterials::encode(&[4; 4096], &rows, n), Some(ChunkMaterials::Uniform(4)));
    assert_eq!(ChunkMaterials::encode(&[0; 4096], &rows, n), None);
    assert_eq!(ChunkMaterials::encode(&[4; 4096], &vec![0; n * n], n), None);
    // Not canonical: a change point on an empty node, a redundant one.
    let mut bytes = Vec::new();
    push_varint(&mut bytes, 0);
    bytes.push(1);
    push_varint(&mut bytes, 1);
    bytes.push(2);
    assert!(ChunkMaterials::Runs(bytes.into()).check(&rows, n).is_err());
    let raw = RawMaterials::Runs(vec![0, 1, 5, 1].into());
    assert!(ChunkMaterials::try_from(raw).is_err());
    assert!(ChunkMaterials::try_from(RawMaterials::Uniform(0)).is_err());
    assert!(ChunkMaterials::try_from(RawMaterials::Runs(vec![0x80].into())).is_err());
}

#[test]
fn reading_rows_in_order_gives_what_decoding_gives() {
    let n = 16;
    let nodes = n * n * n;
    let mut seed = 7u64;
    let mut next = |m: u64| {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (seed >> 33) % m
    };
    for _ in 0..50 {
        // Random solid rows and random ids in runs.
        let rows: Vec<u128> = (0..n * n).map(|_| if next(4) == 0 { 0 } else { (next(1 << 16) as u128) | 1 }).collect();
        let mut ids = vec![0u8; nodes];
        let mut id = 0;
        for v in ids.iter_mut() {
            if next(40) == 0 {
                id = next(4) as u8;
            }
            *v = id;
        }
        let m = ChunkMaterials::encode(&ids, &rows, n);
        let mut all = Vec::new();
        ChunkMaterials::decode_into(m.as_ref(), nodes, &mut all);
        let mut reader = IdReader::new(m.as_ref());
        let mut start = 0;
        while start < nodes {
            // Runs that follow each other or skip nodes.
            let len = 1 + next(20) as usize;
            let len = len.min(nodes - start);
            let mut got = vec![0u8; len];
            reader.read(start, &mut got);
            assert_eq!(got, all[start..start + len]);
            start += [len, len + 1, len + next(300) as usize][next(3) as usize];
        }
    }
}
