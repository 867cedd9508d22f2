//! Both storage back-ends keep the same things: a room created, operations appended, a
//! snapshot folding the log, all read back; a room is held by one opener at a time.

use glam::DVec3;
use strata_editor::{DabRecord, EditOp, LayerTransform, ToolSettings};
use strata_net::protocol::{Entry, Ordered};
use strata_server::{PgStorage, RedbStorage, Storage, StoreError};
use strata_tests::collab::{fresh_room, pg_url, temp_dir};

fn ordered(seq: u64) -> Ordered {
    let at = DVec3::new(seq as f64, 0.0, 0.0);
    Ordered {
        seq,
        author: 7,
        number: seq,
        entry: Entry::Edit(Box::new(EditOp {
            surface: 0,
            transform: LayerTransform::default(),
            tool: ToolSettings::default(),
            dabs: vec![DabRecord::Dab {
                at,
                from: at,
                orientation: glam::DQuat::IDENTITY,
                pressure: 1.0,
                inverted: false,
            }],
            stroke: 0,
        })),
    }
}

fn check(storage: &dyn Storage, name: &str) {
    let mut room = storage.open(name).unwrap();
    assert!(matches!(storage.open(name), Err(StoreError::Busy(_))), "a room opened twice");
    assert_eq!(room.load().unwrap(), None);
    room.create([3; 32], b"first").unwrap();
    room.append(&[ordered(1), ordered(2)]).unwrap();
    room.append(&[ordered(3)]).unwrap();
    let loaded = room.load().unwrap().unwrap();
    assert_eq!(loaded.token_hash, [3; 32]);
    assert_eq!((loaded.snapshot_seq, loaded.snapshot.as_slice()), (0, &b"first"[..]));
    assert_eq!(loaded.ops, vec![ordered(1), ordered(2), ordered(3)]);
    room.compact(2, b"second", &[(7, 2)]).unwrap();
    room.append(&[ordered(4)]).unwrap();
    let loaded = room.load().unwrap().unwrap();
    assert_eq!((loaded.snapshot_seq, loaded.snapshot.as_slice()), (2, &b"second"[..]));
    assert_eq!(loaded.clients, vec![(7, 2)]);
    assert_eq!(loaded.ops, vec![ordered(3), ordered(4)]);
    assert_eq!(loaded.token_hash, [3; 32], "compaction kept the token");
    drop(room);
    // Released: opened again, it reads the same.
    let mut again = storage.open(name).unwrap();
    assert_eq!(again.load().unwrap().unwrap(), loaded);
}

#[test]
fn redb_keeps_rooms() {
    let dir = temp_dir("store-redb");
    let path = dir.join("rooms.redb");
    check(&RedbStorage::open(&path).unwrap(), "a");
    // And after the file is closed and opened again.
    let storage = RedbStorage::open(&path).unwrap();
    assert_eq!(storage.open("a").unwrap().load().unwrap().unwrap().ops.len(), 2);
}

#[test]
fn postgres_keeps_rooms() {
    let Some(url) = pg_url() else { return };
    check(&PgStorage::open(&url).unwrap(), &fresh_room("store"));
}
