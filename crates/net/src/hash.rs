//! The digest rooms and clients compare to find a diverged client.

use strata_editor::Scene;
use strata_editor::file::chunk_digests;

/// A 64-bit digest of every chunk of `scene` (FNV-1a over the chunk digests of
/// [`chunk_digests`]); `None` when the scene cannot be encoded (a layer with an invalid
/// transform, which a room never holds).
pub fn state_hash(scene: &Scene) -> Option<u64> {
    let digests = chunk_digests(scene).ok()?;
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h ^= b as u64;
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    eat(&(scene.layers.len() as u64).to_le_bytes());
    for d in digests {
        eat(&d.layer.to_le_bytes());
        for k in d.key {
            eat(&k.to_le_bytes());
        }
        eat(&d.lists.to_le_bytes());
        eat(&d.materials.to_le_bytes());
    }
    Some(h)
}
