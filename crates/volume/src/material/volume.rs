//! A volume's materials: per-chunk storage, queries by node and point, the pass that keeps
//! materials with the node states after an edit ([`Volume::update_materials`]), resampling
//! across levels and the invariant check.

use super::*;

/// The materials of a volume's chunks (chunks absent are material 0 wherever solid).
pub(crate) type MaterialMap = HashMap<ChunkKey, ChunkMaterials, Hash>;

/// What an edit does to the materials of the nodes it changes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum MaterialRule {
    /// Nodes made solid get this id (adding matter with a material).
    Fill(MaterialId),
    /// Nodes made solid take the id of a face neighbour that was solid, else of the run they
    /// continue (tools that move the surface: smoothing does not carry a material across a
    /// boundary it did not touch).
    Nearest,
}

/// Own node states of a chunk, `rows[y + n z]` bit `x`.
pub(crate) fn own_states(view: ChunkView<'_>, level: Level) -> Vec<u128> {
    let n = level.cells();
    match view {
        ChunkView::Uniform(false) => vec![0; n * n],
        ChunkView::Uniform(true) => vec![(1u128 << n) - 1; n * n],
        ChunkView::Lists(l) => {
            // The x lines, in index order `y + n z`, unpacked a line at a time.
            let mut cursor = l.cursor(Axis::X, 0);
            let mut line = crate::chunk::WorkLine::EMPTY;
            let own = (1u128 << n) - 1;
            (0..n * n)
                .map(|_| {
                    line.load(cursor.next_line(), level);
                    line.states & own
                })
                .collect()
        }
    }
}

/// Chunk-local node `(x, y, z)` of index `i`.
#[inline]
fn node_of(i: usize, n: usize) -> [usize; 3] {
    [i % n, (i / n) % n, i / (n * n)]
}

/// The new materials of one chunk whose node states went from `before` to `after`.
fn next_materials(
    old: Option<&ChunkMaterials>,
    before: &[u128],
    after: &[u128],
    n: usize,
    rule: MaterialRule,
    hint: MaterialId,
    ids: &mut Vec<MaterialId>,
) -> Option<ChunkMaterials> {
    let any_after = after.iter().any(|&r| r != 0);
    if !any_after {
        return None;
    }
    let any_before = before.iter().any(|&r| r != 0);
    let uniform = match old {
        None => Some(0),
        Some(ChunkMaterials::Uniform(id)) => Some(*id),
        Some(ChunkMaterials::Runs(_)) => None,
    };
    let fill = match rule {
        MaterialRule::Fill(f) => f,
        MaterialRule::Nearest => hint,
    };
    if !any_before {
        return (fill != 0).then_some(ChunkMaterials::Uniform(fill));
    }
    if let Some(u) = uniform {
        let grows = after.iter().zip(before).any(|(a, b)| a & !b != 0);
        if !grows || rule == MaterialRule::Nearest || fill == u {
            return (u != 0).then_some(ChunkMaterials::Uniform(u));
        }
    }
    ChunkMaterials::decode_into(old, n * n * n, ids);
    for (r, (&a, &b)) in after.iter().zip(before).enumerate() {
        let mut grown = a & !b;
        while grown != 0 {
            let x = grown.trailing_zeros() as usize;
            grown &= grown - 1;
            let i = x + n * r;
            ids[i] = match rule {
                MaterialRule::Fill(f) => f,
                MaterialRule::Nearest => nearest_old(ids, before, i, n).unwrap_or(ids[i]),
            };
        }
    }
    ChunkMaterials::encode(ids, after, n)
}

/// The id of a face neighbour of node `i` that was solid (`before`), if any.
fn nearest_old(ids: &[MaterialId], before: &[u128], i: usize, n: usize) -> Option<MaterialId> {
    let [x, y, z] = node_of(i, n);
    let solid = |x: usize, y: usize, z: usize| before[y + n * z] >> x & 1 == 1;
    let at = |x: usize, y: usize, z: usize| ids[x + n * (y + n * z)];
    let candidates = [
        (x > 0).then(|| (x - 1, y, z)),
        (x + 1 < n).then(|| (x + 1, y, z)),
        (y > 0).then(|| (x, y - 1, z)),
        (y + 1 < n).then(|| (x, y + 1, z)),
        (z > 0).then(|| (x, y, z - 1)),
        (z + 1 < n).then(|| (x, y, z + 1)),
    ];
    candidates.into_iter().flatten().find(|&(x, y, z)| solid(x, y, z)).map(|(x, y, z)| at(x, y, z))
}

/// The previous materials of chunks an edit changed, for its undo record.
pub(crate) type MaterialUndo = Vec<(ChunkKey, Option<ChunkMaterials>)>;

impl Volume {
    /// The material id of every own node of chunk `key` (x-major, `n³` at the chunk's level);
    /// empty nodes carry the id of the run before them.
    pub(crate) fn decode_materials(&self, key: ChunkKey, level: Level, out: &mut Vec<MaterialId>) {
        let n = level.cells();
        ChunkMaterials::decode_into(self.materials.get(&key), n * n * n, out);
    }

    /// Whether any node of the volume has a material other than 0.
    pub fn has_materials(&self) -> bool {
        !self.materials.is_empty()
    }

    /// The stored materials of chunk `key` (`None`: material 0 wherever solid).
    pub fn chunk_materials(&self, key: ChunkKey) -> Option<&ChunkMaterials> {
        self.materials.get(&key)
    }

    /// Chunks with stored materials.
    pub fn material_chunks(&self) -> impl Iterator<Item = (ChunkKey, &ChunkMaterials)> {
        self.materials.iter().map(|(k, m)| (*k, m))
    }

    /// Replaces the stored materials of chunk `key` (for loaders); nothing is checked: call
    /// [`Volume::check_chunk_materials`] before or [`Volume::check_invariants`] after.
    pub fn set_chunk_materials(&mut self, key: ChunkKey, materials: Option<ChunkMaterials>) {
        self.store_materials(key, materials);
    }

    /// Whether `materials` fit the chunk at `key` as it is stored now, as
    /// [`Volume::check_invariants`] requires: a chunk that is not empty, one id per node of the
    /// chunk's level (a uniform chunk's: the volume's level), in canonical form. `Err` says why
    /// not. Loaders call it after the chunks and the volume's level are in place.
    pub fn check_chunk_materials(&self, key: ChunkKey, materials: &ChunkMaterials) -> Result<(), String> {
        if !self.chunks.contains_key(&key) {
            return Err("materials stored for an empty chunk".into());
        }
        let level = self.level_of(key);
        materials.check(&own_states(self.view(key), level), level.cells())
    }

    /// Stores (or removes) the materials of `key`; returns what was there. The map's table is
    /// freed when its last entry goes, so a volume painted back to material 0 costs nothing.
    pub(crate) fn store_materials(
        &mut self,
        key: ChunkKey,
        materials: Option<ChunkMaterials>,
    ) -> Option<ChunkMaterials> {
        let was = match materials {
            Some(m) => self.materials.insert(key, m),
            None => self.materials.remove(&key),
        };
        if self.materials.is_empty() {
            self.materials = MaterialMap::default();
        }
        was
    }

    /// The largest material id any node has (`None` for an empty volume; 0 without materials).
    pub fn max_material(&self) -> Option<MaterialId> {
        if self.chunks.is_empty() {
            return None;
        }
        let ids = self.materials.values().flat_map(|m| m.change_points().unwrap_or_default().into_iter().map(|p| p.1));
        Some(ids.max().unwrap_or(0))
    }

    /// Gives the nodes whose material is `count` or above material 0 (after a palette lost
    /// entries); returns how many chunks changed. Node states are untouched.
    pub fn clamp_materials(&mut self, count: usize) -> usize {
        let bad: Vec<ChunkKey> = self
            .materials
            .iter()
            .filter(|(_, m)| m.change_points().map_or(true, |p| p.iter().any(|e| e.1 as usize >= count)))
            .map(|(k, _)| *k)
            .collect();
        let mut ids = Vec::new();
        for &key in &bad {
            let level = self.level_of(key);
            self.decode_materials(key, level, &mut ids);
            for id in ids.iter_mut() {
                if *id as usize >= count {
                    *id = 0;
                }
            }
            let rows = own_states(self.view(key), level);
            let next = ChunkMaterials::encode(&ids, &rows, level.cells());
            self.store_materials(key, next);
        }
        bad.len()
    }

    /// Gives every solid node material `id` (for scenes written before materials were stored,
    /// where a layer had one material).
    pub fn fill_materials(&mut self, id: MaterialId) {
        self.materials.clear();
        if id != 0 {
            let keys: Vec<ChunkKey> = self.chunks.keys().copied().collect();
            for k in keys {
                self.materials.insert(k, ChunkMaterials::Uniform(id));
            }
        }
    }

    /// The material of node `local` (chunk-local, each coordinate in `0..=n` at `level`) of chunk
    /// `key`, read in the chunk that owns the node (coordinates equal to `n` belong to the next
    /// chunk, which may be stored at another level: the nearest of its nodes is read).
    pub(crate) fn node_material(&self, key: ChunkKey, level: Level, local: [usize; 3]) -> MaterialId {
        let n = level.cells();
        let mut owner = key.0;
        let mut frac = [0.0f64; 3];
        for i in 0..3 {
            if local[i] >= n {
                owner[i] += 1;
                frac[i] = (local[i] - n) as f64 / n as f64;
            } else {
                frac[i] = local[i] as f64 / n as f64;
            }
        }
        let owner = ChunkKey(owner);
        let Some(m) = self.materials.get(&owner) else { return 0 };
        if let ChunkMaterials::Uniform(id) = m {
            return *id;
        }
        let on = self.level_of(owner).cells();
        let idx = |f: f64| ((f * on as f64).round() as usize).min(on - 1);
        let i = idx(frac[0]) + on * (idx(frac[1]) + on * idx(frac[2]));
        let mut point = 0;
        let mut id = 0;
        for (d, to) in Entries::new(match m {
            ChunkMaterials::Runs(b) => b,
            ChunkMaterials::Uniform(_) => unreachable!("handled above"),
        })
        .map_while(Result::ok)
        {
            point += d;
            if point > i {
                break;
            }
            id = to;
        }
        id
    }

    /// The material of node `node` (global node coordinates at the volume's level, in a chunk
    /// stored at that level), or `None` when the node is empty.
    pub fn node_material_at(&self, node: I64Vec3) -> Option<MaterialId> {
        if !self.node_inside(node) {
            return None;
        }
        let n = self.level.cells() as i64;
        let key = node.div_euclid(I64Vec3::splat(n));
        let local = node - key * n;
        let key = ChunkKey(key.as_ivec3());
        Some(self.node_material(key, self.level, [local.x as usize, local.y as usize, local.z as usize]))
    }

    /// The material of the solid node nearest `p` (grid coordinates) among the corners of the
    /// cell holding `p`, or `None` when they are all empty (an eyedropper's reading).
    pub fn material_near(&self, p: DVec3) -> Option<MaterialId> {
        if !p.is_finite() {
            return None;
        }
        let c = CHUNK_CELLS as f64;
        let key = (p / c).floor();
        if key.abs().max_element() > i32::MAX as f64 - 2.0 {
            return None;
        }
        let key = ChunkKey(key.as_ivec3());
        let level = self.level_of(key);
        let n = level.cells();
        let local = (p - key.origin_grid().as_dvec3()) / level.spacing();
        let cell = local.floor().clamp(DVec3::ZERO, DVec3::splat(n as f64 - 1.0));
        let mut corners: Vec<(f64, [usize; 3])> = (0..8)
            .map(|k| {
                let c = cell + DVec3::new((k & 1) as f64, (k >> 1 & 1) as f64, (k >> 2 & 1) as f64);
                ((c - local).length_squared(), [c.x as usize, c.y as usize, c.z as usize])
            })
            .collect();
        corners.sort_by(|a, b| a.0.total_cmp(&b.0));
        let origin = key.origin_grid();
        corners.into_iter().map(|(_, l)| l).find_map(|l| {
            let g = origin.as_dvec3() + DVec3::new(l[0] as f64, l[1] as f64, l[2] as f64) * level.spacing();
            self.is_inside(g).then(|| self.node_material(key, level, l))
        })
    }

    /// Brings the materials of the chunks `previous` lists (each with its contents before the
    /// edit) in line with their new node states under `rule`; returns the previous materials of
    /// the chunks whose materials changed. `rows[i]`, where the writer kept it, lists the x
    /// lines whose own node states it changed in `previous[i]`'s chunk: only those rows are
    /// decoded ([`splice_rows`]) unless nodes were made solid under [`MaterialRule::Nearest`]
    /// (which looks at the rows around them) or the chunk changed level.
    pub(crate) fn update_materials(
        &mut self,
        previous: &[(ChunkKey, Option<crate::chunk::Chunk>)],
        rule: MaterialRule,
        rows: &[Option<Vec<RowChange>>],
    ) -> MaterialUndo {
        if self.materials.is_empty() && matches!(rule, MaterialRule::Nearest | MaterialRule::Fill(0)) {
            return Vec::new();
        }
        let mut ids = Vec::new();
        let mut updates = Vec::with_capacity(previous.len());
        for (i, (key, old_chunk)) in previous.iter().enumerate() {
            let level = self.level_of(*key);
            let old = self.materials.get(key);
            let same_level = match old_chunk {
                Some(crate::chunk::Chunk::Lists(l)) => l.level() == level,
                _ => true,
            };
            // The rows the writer noted, and the id nodes made solid take, where the rows alone
            // decide the chunk's materials.
            let spliced = rows.get(i).and_then(Option::as_ref).filter(|_| same_level).and_then(|changes| {
                let fill = match rule {
                    MaterialRule::Fill(f) => Some(f),
                    MaterialRule::Nearest => changes.iter().all(|c| c.after & !c.before == 0).then_some(0),
                };
                fill.map(|f| (changes, f))
            });
            let next = match spliced {
                Some((changes, f)) => {
                    if changes.is_empty() {
                        // No own node changed state: the materials stay.
                        debug_assert_eq!(
                            old.cloned(),
                            self.whole_chunk_materials(*key, old_chunk.as_ref(), rule, &mut ids)
                        );
                        continue;
                    }
                    let next = splice_rows(old, changes, f, self.view(*key), level);
                    debug_assert_eq!(
                        next,
                        self.whole_chunk_materials(*key, old_chunk.as_ref(), rule, &mut ids),
                        "materials spliced by rows equal the whole chunk's pass"
                    );
                    next
                }
                _ => self.whole_chunk_materials(*key, old_chunk.as_ref(), rule, &mut ids),
            };
            if next.as_ref() != self.materials.get(key) {
                updates.push((*key, next));
            }
        }
        let mut undo = Vec::with_capacity(updates.len());
        for (key, next) in updates {
            let was = self.store_materials(key, next);
            undo.push((key, was));
        }
        undo
    }

    /// The materials of chunk `key` (contents before the edit `old_chunk`) under `rule`, from
    /// every node of the chunk before and after.
    fn whole_chunk_materials(
        &self,
        key: ChunkKey,
        old_chunk: Option<&crate::chunk::Chunk>,
        rule: MaterialRule,
        ids: &mut Vec<MaterialId>,
    ) -> Option<ChunkMaterials> {
        let level = self.level_of(key);
        let before_view = ChunkView::of(old_chunk);
        let before_level = match before_view {
            ChunkView::Lists(l) => l.level(),
            ChunkView::Uniform(_) => level,
        };
        let old = self.materials.get(&key);
        // Cases decided without the previous node states: a chunk of one material that
        // gains nodes of that material (or only loses or moves nodes), or of material 0
        // that gains material 0.
        let keeps = match (old, rule) {
            (Some(ChunkMaterials::Uniform(u)), MaterialRule::Fill(f)) => (f == *u).then_some(*u),
            (Some(ChunkMaterials::Uniform(u)), MaterialRule::Nearest) => Some(*u),
            (None, MaterialRule::Fill(0)) => Some(0),
            _ => None,
        };
        if let (Some(u), true) = (keeps, before_level == level) {
            return match self.view(key) {
                ChunkView::Uniform(false) => None,
                ChunkView::Uniform(true) => (u != 0).then_some(ChunkMaterials::Uniform(u)),
                // (A list chunk may, rarely, have no solid node of its own.)
                view => own_states(view, level)
                    .iter()
                    .any(|&r| r != 0)
                    .then_some(ChunkMaterials::Uniform(u))
                    .filter(|_| u != 0),
            };
        }
        let after = own_states(self.view(key), level);
        if before_level == level {
            let before = own_states(before_view, level);
            let hint = if rule == MaterialRule::Nearest && old.is_none() { self.neighbour_hint(key) } else { 0 };
            next_materials(old, &before, &after, level.cells(), rule, hint, ids)
        } else {
            // The edit replaced a chunk of another level: resample (see `resampled`).
            self.resampled(key, before_level, level, &after, ids)
        }
    }

    /// An id for new matter in chunk `key` that had no solid node: a face neighbour's (its
    /// uniform id or its first run's), else 0.
    fn neighbour_hint(&self, key: ChunkKey) -> MaterialId {
        [IVec3::X, IVec3::NEG_X, IVec3::Y, IVec3::NEG_Y, IVec3::Z, IVec3::NEG_Z]
            .into_iter()
            .find_map(|d| match self.materials.get(&ChunkKey(key.0 + d)) {
                Some(ChunkMaterials::Uniform(id)) => Some(*id),
                Some(m @ ChunkMaterials::Runs(_)) => m.change_points().ok().and_then(|p| p.first().map(|e| e.1)),
                None => None,
            })
            .unwrap_or(0)
    }

    /// The materials of chunk `key`, stored at `from`, read at `to` (whose own node states are
    /// `after`): a node that coincides with a stored node takes its id, any other the id of the
    /// nearest stored node (rounding down on ties), so raising then lowering gives back the
    /// original ids.
    pub(crate) fn resampled(
        &self,
        key: ChunkKey,
        from: Level,
        to: Level,
        after: &[u128],
        ids: &mut Vec<MaterialId>,
    ) -> Option<ChunkMaterials> {
        let old = self.materials.get(&key);
        match old {
            None => return None,
            Some(ChunkMaterials::Uniform(id)) => {
                return after.iter().any(|&r| r != 0).then_some(ChunkMaterials::Uniform(*id));
            }
            Some(ChunkMaterials::Runs(_)) => {}
        }
        let (fnn, tn) = (from.cells(), to.cells());
        let mut src = Vec::new();
        ChunkMaterials::decode_into(old, fnn * fnn * fnn, &mut src);
        let map = |i: usize| -> usize { if tn >= fnn { i / (tn / fnn) } else { (i * (fnn / tn)).min(fnn - 1) } };
        ids.clear();
        ids.resize(tn * tn * tn, 0);
        for z in 0..tn {
            for y in 0..tn {
                let base = fnn * (map(y) + fnn * map(z));
                for x in 0..tn {
                    ids[x + tn * (y + tn * z)] = src[base + map(x)];
                }
            }
        }
        ChunkMaterials::encode(ids, after, tn)
    }

    /// Checks the materials of every chunk against its node states (part of
    /// [`Volume::check_invariants`]).
    pub(crate) fn check_materials(&self) -> Result<(), crate::InvariantViolation> {
        for (key, m) in &self.materials {
            self.check_chunk_materials(*key, m).map_err(|what| crate::InvariantViolation { key: *key, what })?;
        }
        Ok(())
    }

    /// Gives the nodes of the chunks in `previous` (with their contents before an edit) that
    /// the edit made solid the material of the node of `other` they came from (`node - shift`,
    /// in node units of this volume's level, which `other` shares); records the previous
    /// materials of chunks not yet in `undo`.
    pub(crate) fn carry_materials(
        &mut self,
        other: &Volume,
        shift: I64Vec3,
        previous: &[(ChunkKey, Option<crate::chunk::Chunk>)],
        undo: &mut MaterialUndo,
    ) {
        if other.materials.is_empty() {
            return;
        }
        let level = self.level;
        let n = level.cells();
        let ni = n as i64;
        let mut decoded: HashMap<ChunkKey, Vec<MaterialId>, Hash> = HashMap::default();
        let mut ids = Vec::new();
        let mut updates = Vec::new();
        for (key, old_chunk) in previous {
            if self.level_of(*key) != level {
                continue;
            }
            let before = own_states(ChunkView::of(old_chunk.as_ref()), level);
            let after = own_states(self.view(*key), level);
            self.decode_materials(*key, level, &mut ids);
            let origin = key.0.as_i64vec3() * ni;
            for (r, (&a, &b)) in after.iter().zip(&before).enumerate() {
                let mut grown = a & !b;
                while grown != 0 {
                    let x = grown.trailing_zeros() as usize;
                    grown &= grown - 1;
                    let node = origin + I64Vec3::new(x as i64, (r % n) as i64, (r / n) as i64) - shift;
                    let okey = node.div_euclid(I64Vec3::splat(ni));
                    let local = node - okey * ni;
                    let okey = ChunkKey(okey.as_ivec3());
                    let src = decoded.entry(okey).or_insert_with(|| {
                        let mut v = Vec::new();
                        other.decode_materials(okey, level, &mut v);
                        v
                    });
                    ids[x + n * r] = src[(local.x + ni * (local.y + ni * local.z)) as usize];
                }
            }
            let next = ChunkMaterials::encode(&ids, &after, n);
            if next.as_ref() != self.materials.get(key) {
                updates.push((*key, next));
            }
        }
        for (key, next) in updates {
            let was = self.store_materials(key, next);
            if !undo.iter().any(|(k, _)| *k == key) {
                undo.push((key, was));
            }
        }
    }

    /// Heap and table bytes of the materials.
    pub(crate) fn material_bytes(&self) -> usize {
        crate::memory::hash_table_bytes(self.materials.capacity(), std::mem::size_of::<(ChunkKey, ChunkMaterials)>())
            + self.materials.values().map(ChunkMaterials::heap_bytes).sum::<usize>()
    }
}
