//! The density a [`Recipe`] describes, and its writer into segment lists.
//!
//! [`TerrainField`] answers [`NodeField`]: the volume asks it for a chunk's node states once and
//! for the crossing in each cell where a line's state changes. Three kinds of work are skipped:
//!
//! - **whole chunks** above the highest or below the lowest possible surface (and below the cave
//!   floor) are decided by interval bounds, first from the recipe's global ranges and then from
//!   the height field over the chunk's columns, without visiting a node;
//! - **nodes** whose column height puts them further from the surface than the overhang noise
//!   can reach are decided from the column alone (a 2D sample shared by the column's 17 nodes),
//!   and the cave noise is sampled only where the cave bound allows a cave;
//! - **boxes** of 4³ nodes (`BOX`) are decided whole where the noises' proven ranges over the box
//!   ([`crate::bound`]) allow: no cave can reach the box, or all of it is cave, or the surface
//!   lies wholly above or below it; a chunk wholly under the surface is decided whole the same
//!   way by the cave noise;
//! - **crossings** are found only on the edges where the node states differ: two secant steps
//!   on the exact density, and a normal from three forward differences; an edge's nodes take
//!   their columns' heights from the footprint cache.
//!
//! Every decision uses the same density expression, with margins larger than its rounding, so a
//! node's state is exactly `density(node) ≤ 0` whichever path decided it.

use std::cell::RefCell;

use glam::{DVec3, I64Vec3};
use strata_volume::coords::CHUNK_CELLS;
use strata_volume::{Axis, Level, MaterialId, NodeField};

use crate::bound::PerlinRange;
use crate::perlin::Perlin;
use crate::recipe::{Recipe, RecipeError};

/// Fractal sum of Perlin octaves, normalised into `[-1, 1]`.
#[derive(Clone, Debug)]
struct Fbm {
    octaves: Vec<Perlin>,
    /// Proven ranges of each octave's noise over a box.
    ranges: Vec<PerlinRange>,
    inv_wavelength: f64,
    lacunarity: f64,
    gain: f64,
    norm: f64,
}

impl Fbm {
    fn new(seed: u32, salt: u32, octaves: u32, wavelength: f64, lacunarity: f64, gain: f64) -> Self {
        let seeds: Vec<u32> =
            (0..octaves).map(|k| seed.wrapping_mul(0x9E37_79B9).wrapping_add(salt * 97 + k)).collect();
        let octaves: Vec<Perlin> = seeds.iter().map(|&s| Perlin::new(s)).collect();
        let ranges = seeds.iter().map(|&s| PerlinRange::new(s)).collect();
        let norm = (0..octaves.len()).map(|k| gain.powi(k as i32)).sum::<f64>();
        Fbm { octaves, ranges, inv_wavelength: 1.0 / wavelength, lacunarity, gain, norm: 1.0 / norm }
    }

    /// Plain and ridged sums at a ground point.
    #[inline]
    fn both2(&self, x: f64, z: f64) -> (f64, f64) {
        let (mut f, mut amp) = (self.inv_wavelength, 1.0);
        let (mut plain, mut ridged) = (0.0, 0.0);
        for o in &self.octaves {
            let n = o.get2([x * f, z * f]);
            plain += amp * n;
            ridged += amp * (1.0 - 2.0 * n.abs());
            f *= self.lacunarity;
            amp *= self.gain;
        }
        (plain * self.norm, ridged * self.norm)
    }

    #[inline]
    fn get3(&self, p: DVec3) -> f64 {
        let (mut f, mut amp, mut sum) = (self.inv_wavelength, 1.0, 0.0);
        for o in &self.octaves {
            sum += amp * o.get3([p.x * f, p.y * f, p.z * f]);
            f *= 2.0;
            amp *= 0.5;
        }
        sum * self.norm
    }

    /// A range holding [`Fbm::get3`] at every point of the box `[lo, hi]` (grid units): each
    /// octave's box is the one its samples are taken in (the same products with the same
    /// frequencies, which keep their order), so its range holds them.
    fn range3(&self, lo: DVec3, hi: DVec3) -> (f64, f64) {
        let (mut f, mut amp) = (self.inv_wavelength, 1.0);
        let (mut a, mut b) = (0.0, 0.0);
        for r in &self.ranges {
            let (l, h) = r.range([lo.x * f, lo.y * f, lo.z * f], [hi.x * f, hi.y * f, hi.z * f]);
            a += amp * l;
            b += amp * h;
            f *= 2.0;
            amp *= 0.5;
        }
        (a * self.norm, b * self.norm)
    }
}

/// A footprint's key: `(field, x, z, level)`. The field's id is part of it: two fields (two
/// worlds, or a recipe changed and generated again) on one thread share the cache, and heights
/// are the field's own.
type FootprintKey = (u64, i64, i64, i8);

/// The columns of the chunk footprints a thread computed last, up to [`FOOTPRINTS`] of them:
/// a world's workers take chunks nearest the viewer first, so the chunks of one column of
/// chunks come far apart in a worker's order, not one after the other.
#[derive(Debug, Default)]
struct ColumnCache {
    /// Key → slot.
    slots: std::collections::HashMap<FootprintKey, usize>,
    /// Each slot's key and heights (x-major, `(n + 1)²`).
    entries: Vec<(FootprintKey, Vec<f64>)>,
    /// The slot filled next once all are taken (the oldest).
    next: usize,
    /// The slot of the footprint asked for last (what [`TerrainField::column_height`] reads).
    last: Option<usize>,
}

/// Footprints a thread keeps (a base-level one is 2.3 KB, a level-1 one 8.7 KB).
const FOOTPRINTS: usize = 512;

/// Ids of fields built so far ([`TerrainField::new`]; a clone keeps its field's id, and its
/// recipe).
static FIELDS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

thread_local! {
    static COLUMNS: RefCell<ColumnCache> = RefCell::new(ColumnCache::default());
}

/// Nodes a side of the boxes whose surface and caves [`NodeField::node_states`] decides at
/// once where the noises' ranges allow (see [`crate::bound`]).
const BOX: usize = 4;

/// What a box of nodes is, by one of the density's terms.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Decision {
    /// Not asked yet.
    Unknown,
    /// The term is true at every node of the box.
    All,
    /// At none.
    None,
    /// Each node must be sampled.
    Sample,
}

impl From<Option<bool>> for Decision {
    fn from(d: Option<bool>) -> Self {
        match d {
            Some(true) => Decision::All,
            Some(false) => Decision::None,
            None => Decision::Sample,
        }
    }
}

impl Decision {
    /// The box's answer, or the node's own by `sample`.
    #[inline]
    fn or_else(self, sample: impl FnOnce() -> bool) -> bool {
        match self {
            Decision::All => true,
            Decision::None => false,
            _ => sample(),
        }
    }
}

/// A recipe made ready to evaluate: its noises built once.
#[derive(Clone, Debug)]
pub struct TerrainField {
    /// Unique to this field and its clones: the column cache's key.
    id: u64,
    recipe: Recipe,
    heights: Fbm,
    warp_x: Perlin,
    warp_z: Perlin,
    overhangs: Fbm,
    caves: Fbm,
}

impl TerrainField {
    /// The field of `recipe` (validated first).
    pub fn new(recipe: &Recipe) -> Result<Self, RecipeError> {
        recipe.validate()?;
        let s = recipe.seed;
        let h = &recipe.heights;
        // Fractal sums of cave and overhang noise use lacunarity 2 and gain 1/2.
        Ok(TerrainField {
            id: FIELDS.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            recipe: recipe.clone(),
            heights: Fbm::new(s, 1, h.octaves, h.wavelength, h.lacunarity, h.gain),
            warp_x: Perlin::new(s.wrapping_mul(0x9E37_79B9).wrapping_add(7001)),
            warp_z: Perlin::new(s.wrapping_mul(0x9E37_79B9).wrapping_add(7002)),
            overhangs: Fbm::new(s, 2, recipe.overhangs.octaves, recipe.overhangs.wavelength, 2.0, 0.5),
            caves: Fbm::new(s, 3, recipe.caves.octaves, recipe.caves.wavelength, 2.0, 0.5),
        })
    }

    /// The recipe.
    pub fn recipe(&self) -> &Recipe {
        &self.recipe
    }

    /// Surface height `H(x, z)`.
    #[inline]
    pub fn height(&self, x: f64, z: f64) -> f64 {
        let w = &self.recipe.warp;
        let (x, z) = if w.amplitude > 0.0 {
            let f = 1.0 / w.wavelength;
            (x + w.amplitude * self.warp_x.get2([x * f, z * f]), z + w.amplitude * self.warp_z.get2([x * f, z * f]))
        } else {
            (x, z)
        };
        let h = &self.recipe.heights;
        let (plain, ridged) = self.heights.both2(x, z);
        h.base + h.amplitude * ((1.0 - h.ridged) * plain + h.ridged * ridged)
    }

    /// Distance-like surface term `s(p)` given the column height.
    #[inline]
    fn surface(&self, p: DVec3, h: f64) -> f64 {
        let o = &self.recipe.overhangs;
        let bump = if o.amplitude > 0.0 { o.amplitude * self.overhangs.get3(p) } else { 0.0 };
        p.y - h - bump
    }

    /// The cave fade below the floor.
    #[inline]
    fn fade(&self, y: f64) -> f64 {
        let c = &self.recipe.caves;
        c.strength * (c.floor - y).max(0.0) / c.fade
    }

    /// Cave term (positive inside a cave); `None` without caves.
    #[inline]
    fn cave(&self, p: DVec3) -> Option<f64> {
        let c = &self.recipe.caves;
        (c.strength > 0.0).then(|| c.strength * (self.caves.get3(p) - c.threshold) - self.fade(p.y))
    }

    /// The largest value the cave term can take at height `y` (`-∞` without caves).
    #[inline]
    fn cave_max(&self, y: f64) -> f64 {
        let c = &self.recipe.caves;
        if c.strength > 0.0 { c.strength * (1.0 - c.threshold) - self.fade(y) } else { f64::NEG_INFINITY }
    }

    /// Whether the caves decide every node of the box `[lo, hi]` (grid units) whichever the
    /// surface: `Some(false)` where no node of it can be in a cave, `Some(true)` where every
    /// node is, `None` where the nodes must be sampled. From the cave noise's proven range over
    /// the box ([`crate::bound`]) and the fade's extremes at the box's top and bottom.
    fn caves_in_box(&self, lo: DVec3, hi: DVec3) -> Option<bool> {
        let c = &self.recipe.caves;
        if c.strength <= 0.0 {
            return Some(false);
        }
        // The fade falls as y rises: the cave term is largest at the top, smallest at the bottom.
        if self.cave_max(hi.y) < -self.margin(hi.y, 0.0) {
            return Some(false);
        }
        let (a, b) = self.caves.range3(lo, hi);
        let eps = self.margin(lo.y.abs().max(hi.y.abs()), 0.0);
        if c.strength * (b - c.threshold) - self.fade(hi.y) < -eps {
            Some(false)
        } else if c.strength * (a - c.threshold) - self.fade(lo.y) > eps {
            Some(true)
        } else {
            None
        }
    }

    /// Whether every node of the box `[lo, hi]` (grid units), whose columns' heights lie in
    /// `[h0, h1]`, is under the surface (`s ≤ 0`): `Some(true)` where all are, `Some(false)`
    /// where none is, `None` where the nodes must be sampled. From the overhang noise's proven
    /// range over the box ([`crate::bound`]).
    fn under_surface_in_box(&self, lo: DVec3, hi: DVec3, h0: f64, h1: f64) -> Option<bool> {
        let o = &self.recipe.overhangs;
        let (b0, b1) = if o.amplitude > 0.0 {
            let (f0, f1) = self.overhangs.range3(lo, hi);
            (o.amplitude * f0, o.amplitude * f1)
        } else {
            (0.0, 0.0)
        };
        let eps = self.margin(lo.y.abs().max(hi.y.abs()), h0.abs().max(h1.abs()));
        // s = y − h − bump.
        if hi.y - h0 - b0 < -eps {
            Some(true)
        } else if lo.y - h1 - b1 > eps {
            Some(false)
        } else {
            None
        }
    }

    /// The density at `p` given its column height `h` ([`TerrainField::height`] at `p.x, p.z`):
    /// negative or zero inside. For samplers that compute a column's height once.
    #[inline]
    pub fn density_h(&self, p: DVec3, h: f64) -> f64 {
        let s = self.surface(p, h);
        match self.cave(p) {
            Some(c) => s.max(c),
            None => s,
        }
    }

    /// The density at `p` (grid units): negative or zero inside.
    pub fn density(&self, p: DVec3) -> f64 {
        self.density_h(p, self.height(p.x, p.z))
    }

    /// Whether the node at `p` is solid: exactly what generated chunks store.
    pub fn is_solid(&self, p: DVec3) -> bool {
        self.density(p) <= 0.0
    }

    /// A rounding margin for bounds at height `y` and surface height `h`.
    #[inline]
    fn margin(&self, y: f64, h: f64) -> f64 {
        1e-7 * (1.0 + y.abs() + h.abs() + self.recipe.overhangs.amplitude + self.recipe.caves.strength)
    }

    /// The decision of interval bounds for heights `[y0, y1]` over columns whose heights lie in
    /// `[h0, h1]`: `Some(inside)` when every point is provably one state.
    fn bound(&self, y0: f64, y1: f64, h0: f64, h1: f64) -> Option<bool> {
        let a = self.recipe.overhangs.amplitude;
        let eps = self.margin(y0.abs().max(y1.abs()), h0.abs().max(h1.abs()));
        let (s_min, s_max) = (y0 - h1 - a, y1 - h0 + a);
        let c = &self.recipe.caves;
        let (c_min, c_max) = if c.strength > 0.0 {
            (c.strength * (-1.0 - c.threshold) - self.fade(y0), self.cave_max(y1))
        } else {
            (f64::NEG_INFINITY, f64::NEG_INFINITY)
        };
        if s_min > eps || c_min > eps {
            Some(false)
        } else if s_max < -eps && c_max < -eps {
            Some(true)
        } else {
            None
        }
    }

    /// Heights of the `(n + 1)²` columns of the chunk footprint at `origin` (x-major), from the
    /// thread's cache of the footprints it computed last when this is one of them.
    fn with_columns<R>(&self, origin: I64Vec3, level: Level, f: impl FnOnce(&[f64]) -> R) -> R {
        COLUMNS.with(|cell| {
            let mut cache = cell.borrow_mut();
            let key = (self.id, origin.x, origin.z, level.get());
            let slot = match cache.slots.get(&key) {
                Some(&slot) => slot,
                None => {
                    let slot = if cache.entries.len() < FOOTPRINTS {
                        cache.entries.push((key, Vec::new()));
                        cache.entries.len() - 1
                    } else {
                        let slot = cache.next;
                        cache.next = (slot + 1) % FOOTPRINTS;
                        let old = cache.entries[slot].0;
                        cache.slots.remove(&old);
                        slot
                    };
                    cache.slots.insert(key, slot);
                    let n = level.cells();
                    let sp = level.spacing();
                    let (k, h) = &mut cache.entries[slot];
                    *k = key;
                    h.clear();
                    for z in 0..=n {
                        for x in 0..=n {
                            h.push(self.height(origin.x as f64 + x as f64 * sp, origin.z as f64 + z as f64 * sp));
                        }
                    }
                    slot
                }
            };
            cache.last = Some(slot);
            f(&cache.entries[slot].1)
        })
    }

    /// The height of the column at `(x, z)`: from the footprint the thread asked for last when
    /// the column is one of its (the same value, computed from the same coordinates), else
    /// [`TerrainField::height`].
    fn column_height(&self, x: f64, z: f64) -> f64 {
        let cached = COLUMNS.with(|cell| {
            let cache = cell.try_borrow().ok()?;
            let ((id, ox, oz, level), heights) = &cache.entries[cache.last?];
            if *id != self.id {
                return None;
            }
            let level = Level::new(*level)?;
            let (n, sp) = (level.cells(), level.spacing());
            let (ox, oz) = (*ox as f64, *oz as f64);
            let (i, k) = (((x - ox) / sp).round(), ((z - oz) / sp).round());
            let inside = (0.0..=n as f64).contains(&i) && (0.0..=n as f64).contains(&k);
            let (i, k) = (i as usize, k as usize);
            (inside && ox + i as f64 * sp == x && oz + k as f64 * sp == z).then(|| heights[i + (n + 1) * k])
        });
        cached.unwrap_or_else(|| self.height(x, z))
    }

    /// The material of a solid node at height `y` on column `(x, z)` of the footprint (own
    /// columns: `x, z < n`).
    fn material(&self, y: f64, cols: &[f64], x: usize, z: usize, n: usize, sp: f64) -> MaterialId {
        let m = &self.recipe.materials;
        let at = |x: usize, z: usize| cols[x + (n + 1) * z];
        let h = at(x, z);
        let slope = (at(x + 1, z) - h).abs().max((at(x, z + 1) - h).abs()) / sp;
        let depth = h - y;
        if depth > m.soil_depth || slope > m.steep {
            m.rock
        } else if depth > m.topsoil {
            m.soil
        } else if h < m.sand_below {
            m.sand
        } else if h > m.snow_above {
            m.snow
        } else {
            m.grass
        }
    }
}

impl TerrainField {
    /// The chunk at `origin` decided by the recipe's bounds alone (the whole range of heights,
    /// overhangs and caves), without computing a column: `Some(false)` where it is provably
    /// empty (the sky above anything the terrain can reach, or where the caves alone empty
    /// it), `Some(true)` for rock below every cave. Constant time.
    pub fn decided_by_recipe(&self, origin: I64Vec3) -> Option<bool> {
        let (y0, y1) = (origin.y as f64, (origin.y + CHUNK_CELLS) as f64);
        let h = &self.recipe.heights;
        self.bound(y0, y1, h.base - h.amplitude, h.base + h.amplitude)
    }

    /// The materials of the chunk at `origin` where the recipe's bounds alone prove it solid
    /// rock: solid ([`TerrainField::decided_by_recipe`]) and deeper than the soil under the
    /// lowest height the recipe reaches, so every node is rock (`Some(None)` where rock is
    /// material 0; the canonical form, as the chunk generated at any level has it). `None`
    /// where the bounds do not prove that. Constant time.
    pub fn proven_rock_materials(&self, origin: I64Vec3) -> Option<Option<strata_volume::ChunkMaterials>> {
        if self.decided_by_recipe(origin) != Some(true) {
            return None;
        }
        let h = &self.recipe.heights;
        let m = &self.recipe.materials;
        let top = (origin.y + CHUNK_CELLS) as f64;
        // `material` takes rock where the depth below the column's height exceeds the soil
        // depth; the margin covers rounding in the heights.
        let lowest = h.base - h.amplitude;
        let eps = self.margin(top.abs(), lowest.abs());
        (lowest - top > m.soil_depth + eps)
            .then(|| (m.rock != 0).then_some(strata_volume::ChunkMaterials::Uniform(m.rock)))
    }
}

impl NodeField for TerrainField {
    fn decided(&self, origin: I64Vec3, level: Level) -> Option<bool> {
        if let Some(d) = self.decided_by_recipe(origin) {
            return Some(d);
        }
        let (y0, y1) = (origin.y as f64, (origin.y + CHUNK_CELLS) as f64);
        let (lo, hi) = self.with_columns(origin, level, |cols| {
            cols.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &h| (a.min(h), b.max(h)))
        });
        if let Some(d) = self.bound(y0, y1, lo, hi) {
            return Some(d);
        }
        // Wholly under the surface (below anything the overhangs can lower it to): the caves
        // alone decide, where their range over the chunk does.
        let eps = self.margin(y0.abs().max(y1.abs()), lo.abs().max(hi.abs()));
        if y1 - lo + self.recipe.overhangs.amplitude < -eps {
            let o = origin.as_dvec3();
            return self.caves_in_box(o, o + DVec3::splat(CHUNK_CELLS as f64)).map(|cave| !cave);
        }
        None
    }

    fn node_states(&self, origin: I64Vec3, level: Level, rows: &mut [u128]) {
        let n = level.cells();
        let m = n + 1;
        let sp = level.spacing();
        let a = self.recipe.overhangs.amplitude;
        let o = origin.as_dvec3();
        // Boxes of BOX³ nodes whose surface and caves are decided at once where the noises'
        // ranges allow, found the first time a node of the box needs them.
        let boxes = m.div_ceil(BOX);
        let mut caves = vec![Decision::Unknown; boxes * boxes * boxes];
        let mut surface = caves.clone();
        let corners = |x: usize, y: usize, z: usize| {
            let first = DVec3::new((x / BOX) as f64, (y / BOX) as f64, (z / BOX) as f64) * (BOX as f64 * sp);
            let lo = o + first;
            (lo, (lo + DVec3::splat((BOX - 1) as f64 * sp)).min(o + DVec3::splat(n as f64 * sp)))
        };
        let index = |x: usize, y: usize, z: usize| x / BOX + boxes * (y / BOX + boxes * (z / BOX));
        self.with_columns(origin, level, |cols| {
            // A cave at node (x, y, z), at `p`.
            let mut cave_at = |x: usize, y: usize, z: usize, p: DVec3| -> bool {
                let b = &mut caves[index(x, y, z)];
                if *b == Decision::Unknown {
                    let (lo, hi) = corners(x, y, z);
                    *b = Decision::from(self.caves_in_box(lo, hi));
                }
                b.or_else(|| self.cave(p).is_some_and(|c| c > 0.0))
            };
            // Under the surface at node (x, y, z), at `p` on a column of height `h`.
            let mut under_at = |x: usize, y: usize, z: usize, p: DVec3, h: f64| -> bool {
                let b = &mut surface[index(x, y, z)];
                if *b == Decision::Unknown {
                    let (lo, hi) = corners(x, y, z);
                    let (x0, z0) = ((x / BOX) * BOX, (z / BOX) * BOX);
                    let (mut h0, mut h1) = (f64::INFINITY, f64::NEG_INFINITY);
                    for cz in z0..(z0 + BOX).min(m) {
                        for cx in x0..(x0 + BOX).min(m) {
                            h0 = h0.min(cols[cx + m * cz]);
                            h1 = h1.max(cols[cx + m * cz]);
                        }
                    }
                    *b = Decision::from(self.under_surface_in_box(lo, hi, h0, h1));
                }
                b.or_else(|| self.surface(p, h) <= 0.0)
            };
            for z in 0..m {
                for x in 0..m {
                    let h = cols[x + m * z];
                    let (px, pz) = (o.x + x as f64 * sp, o.z + z as f64 * sp);
                    for y in 0..m {
                        let py = o.y + y as f64 * sp;
                        let eps = self.margin(py, h);
                        if py - h - a > eps {
                            // Above anything the overhangs can lift the surface to.
                            continue;
                        }
                        let p = DVec3::new(px, py, pz);
                        let no_cave = self.cave_max(py) < -eps;
                        // Below the surface (solid unless a cave can be here and is), or in the
                        // overhangs' band.
                        let under = py - h + a < -eps || under_at(x, y, z, p, h);
                        if under && (no_cave || !cave_at(x, y, z, p)) {
                            rows[y + m * z] |= 1 << x;
                        }
                    }
                }
            }
        });
    }

    fn crossing(&self, from: DVec3, axis: Axis, spacing: f64, _from_inside: bool) -> (f64, DVec3) {
        let dir = axis.unit();
        let to = from + dir * spacing;
        // The edge's ends are nodes: their columns' heights are those of the footprint the
        // chunk's states were just found from.
        let h_from = self.column_height(from.x, from.z);
        let h_to = if axis == Axis::Y { h_from } else { self.column_height(to.x, to.z) };
        let (fa, fb) = (self.density_h(from, h_from), self.density_h(to, h_to));
        let secant = |lo: f64, flo: f64, hi: f64, fhi: f64| {
            let t = if flo != fhi { lo + (hi - lo) * flo / (flo - fhi) } else { 0.5 * (lo + hi) };
            t.clamp(lo, hi)
        };
        let t1 = secant(0.0, fa, 1.0, fb);
        let r = from + dir * (t1 * spacing);
        // Along y every point has the edge's column; otherwise `r` has its own, which the
        // normal's step along y shares.
        let h_r = if axis == Axis::Y { h_from } else { self.height(r.x, r.z) };
        let fr = self.density_h(r, h_r);
        let t = if (fr <= 0.0) == (fa <= 0.0) { secant(t1, fr, 1.0, fb) } else { secant(0.0, fa, t1, fr) };
        let e = 0.05 * spacing;
        let grad = DVec3::new(
            (self.density(r + DVec3::X * e) - fr) / e,
            (self.density_h(r + DVec3::Y * e, h_r) - fr) / e,
            (self.density(r + DVec3::Z * e) - fr) / e,
        );
        (t, grad)
    }

    fn materials(&self, origin: I64Vec3, level: Level, own: &[u128], ids: &mut [MaterialId]) {
        let n = level.cells();
        let sp = level.spacing();
        self.with_columns(origin, level, |cols| {
            for z in 0..n {
                for y in 0..n {
                    let mut row = own[y + n * z];
                    let py = origin.y as f64 + y as f64 * sp;
                    while row != 0 {
                        let x = row.trailing_zeros() as usize;
                        row &= row - 1;
                        ids[x + n * (y + n * z)] = self.material(py, cols, x, z, n, sp);
                    }
                }
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The footprint cache answers with the heights themselves, whatever it held before: after
    /// more footprints than it keeps (the first evicted), for a footprint asked again, for two
    /// fields on one thread, at two levels, and for points that are not columns of the last
    /// footprint.
    #[test]
    fn cached_columns_are_the_heights_whatever_the_cache_held() {
        let a = TerrainField::new(&Recipe::with_seed(1)).unwrap();
        let b = TerrainField::new(&Recipe::with_seed(2)).unwrap();
        let check = |field: &TerrainField, origin: I64Vec3, level: Level| {
            let (n, sp) = (level.cells(), level.spacing());
            field.with_columns(origin, level, |cols| {
                for z in 0..=n {
                    for x in 0..=n {
                        let (px, pz) = (origin.x as f64 + x as f64 * sp, origin.z as f64 + z as f64 * sp);
                        assert_eq!(cols[x + (n + 1) * z].to_bits(), field.height(px, pz).to_bits());
                    }
                }
            });
            // The last footprint's columns, and points beside them.
            for (dx, dz) in [(0.0, 0.0), (16.0 * sp, 3.0 * sp), (0.25, 0.0), (-1.0, 2.0), (17.0, 0.0)] {
                let (x, z) = (origin.x as f64 + dx, origin.z as f64 + dz);
                assert_eq!(field.column_height(x, z).to_bits(), field.height(x, z).to_bits(), "({x}, {z})");
            }
        };
        let first = I64Vec3::new(-16, 0, 32);
        check(&a, first, Level::BASE);
        for i in 0..(FOOTPRINTS as i64 + 40) {
            a.with_columns(I64Vec3::new(16 * i, 0, 0), Level::BASE, |_| ());
        }
        check(&a, first, Level::BASE);
        check(&b, first, Level::BASE);
        check(&a, first, Level::BASE);
        check(&a, first, Level::new(1).unwrap());
        check(&b, I64Vec3::new(16 * 3, 0, 0), Level::BASE);
    }
}
