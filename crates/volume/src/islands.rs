//! Solid islands: the connected pieces of the solid, found from the node states, and the removal
//! of those smaller than a given volume (stray nodes left by a conversion or a scan).
//!
//! A piece is a connected component of inside nodes joined along grid edges (each node to its six
//! neighbours along x, y and z): two nodes that touch only diagonally share no cell edge, hold no
//! crossing between them and are separate pieces. Each inside node stands for one cell of its
//! level, so a piece's volume is its node count times the cube of the node spacing, in cells³ of
//! the base grid. Pieces are found from runs of inside nodes along the x lines (two crossings
//! bound a run), joined where runs of neighbouring lines overlap, so the work follows the
//! crossings, not the volume the solid fills.
//!
//! [`Volume::remove_islands`] subtracts each small piece with a brush that is inside exactly on
//! the piece's nodes (the union of the nodes' cubes, whose faces lie halfway between nodes). An
//! island's neighbours along every grid line are outside, so the subtraction leaves no crossing
//! behind and changes no other node or crossing: every remaining crossing is still strictly
//! inside the one cell edge whose two nodes differ.

use std::collections::HashMap;
use std::collections::HashSet;

use glam::{DVec3, I64Vec3};
use thiserror::Error;

use crate::brush::{Aabb, Brush, Span, unit_axis};
use crate::chunk::ChunkView;
use crate::coords::edge_of;
use crate::{Axis, Chunk, EditError, EditReport, Level, Volume};

/// Why islands were not removed.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum IslandError {
    /// The threshold is not a finite volume `>= 0`.
    #[error("the island threshold must be a finite number of cells³ >= 0, not {0}")]
    BadThreshold(f64),
    /// Pieces are found on one node lattice: every list chunk must be at the volume's level.
    #[error("islands are found in volumes whose chunks are all at one resolution level; this one mixes levels")]
    MixedLevels,
    /// Subtracting an island was refused.
    #[error(transparent)]
    Edit(#[from] EditError),
}

/// What [`Volume::remove_islands`] removed and kept.
#[derive(Debug, Default)]
pub struct IslandRemoval {
    /// Pieces removed.
    pub removed: usize,
    /// Inside nodes they held.
    pub removed_nodes: u64,
    /// Their volume, in cells³ of the base grid (nodes times the node spacing cubed).
    pub removed_volume: f64,
    /// Pieces kept.
    pub kept: usize,
    /// The edit: the chunks changed, and the undo record that gives back the islands.
    pub edit: EditReport,
}

/// A run of inside nodes along x: nodes `x0..=x1` of the x line `(y, z)` (node units of the
/// volume's level).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Run {
    y: i64,
    z: i64,
    x0: i64,
    x1: i64,
}

impl Run {
    fn len(&self) -> u64 {
        (self.x1 - self.x0 + 1) as u64
    }
}

/// The pieces of the solid: every run of inside nodes along x and, for each, its piece.
struct Pieces {
    runs: Vec<Run>,
    piece: Vec<u32>,
    count: usize,
}

/// Union-find over run indices.
struct Union(Vec<u32>);

impl Union {
    fn find(&mut self, mut i: u32) -> u32 {
        while self.0[i as usize] != i {
            let next = self.0[self.0[i as usize] as usize];
            self.0[i as usize] = next;
            i = next;
        }
        i
    }

    fn join(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            self.0[ra.max(rb) as usize] = ra.min(rb);
        }
    }
}

/// The runs of inside nodes of every x line of the volume, merged across chunk borders, sorted
/// by `(z, y, x0)`.
fn runs(volume: &Volume) -> Vec<Run> {
    let n = volume.level().cells();
    let ni = n as i64;
    // Chunk rows along x: (y, z) of the chunk key, then the chunks of the row by x.
    let mut rows: HashMap<(i32, i32), Vec<(i32, &Chunk)>> = HashMap::new();
    for (key, chunk) in volume.chunks() {
        rows.entry((key.0.y, key.0.z)).or_default().push((key.0.x, chunk));
    }
    let mut order: Vec<(i32, i32)> = rows.keys().copied().collect();
    order.sort_unstable_by_key(|&(y, z)| (z, y));
    let mut out = Vec::new();
    // Per line of a chunk row (index y + n z): its runs so far.
    let mut lines: Vec<Vec<(i64, i64)>> = vec![Vec::new(); n * n];
    for (cy, cz) in order {
        let mut chunks = rows.remove(&(cy, cz)).unwrap_or_default();
        chunks.sort_unstable_by_key(|c| c.0);
        lines.iter_mut().for_each(Vec::clear);
        for (cx, chunk) in chunks {
            let x0 = cx as i64 * ni;
            let push = |line: &mut Vec<(i64, i64)>, a: usize, b: usize| {
                let (a, b) = (x0 + a as i64, x0 + b as i64);
                match line.last_mut() {
                    Some(last) if last.1 + 1 == a => last.1 = b,
                    _ => line.push((a, b)),
                }
            };
            match ChunkView::of(Some(chunk)) {
                ChunkView::Uniform(false) => {}
                ChunkView::Uniform(true) => lines.iter_mut().for_each(|l| push(l, 0, n - 1)),
                ChunkView::Lists(l) => {
                    let level = l.level();
                    let mut cursor = l.cursor(Axis::X, 0);
                    for line in lines.iter_mut() {
                        let stored = cursor.next_line();
                        let mut inside = stored.start_inside;
                        let mut start = 0usize;
                        for q in stored.positions() {
                            // The crossing lies between nodes `e` and `e + 1`.
                            let e = edge_of(q, level);
                            if inside {
                                push(line, start, e);
                            } else {
                                start = e + 1;
                            }
                            inside = !inside;
                        }
                        // Node n is the next chunk's node 0: runs end at n - 1 here.
                        if inside && start < n {
                            push(line, start, n - 1);
                        }
                    }
                }
            }
        }
        for z in 0..n {
            for y in 0..n {
                let (gy, gz) = (cy as i64 * ni + y as i64, cz as i64 * ni + z as i64);
                out.extend(lines[y + n * z].iter().map(|&(x0, x1)| Run { y: gy, z: gz, x0, x1 }));
            }
        }
    }
    out.sort_unstable_by_key(|r| (r.z, r.y, r.x0));
    out
}

/// Joins the overlapping runs of two lines (each sorted by `x0`, `a` and `b` their first
/// indices in the run list).
fn join_lines(u: &mut Union, a: (&[Run], u32), b: (&[Run], u32)) {
    let (mut i, mut j) = (0, 0);
    while i < a.0.len() && j < b.0.len() {
        let (p, q) = (a.0[i], b.0[j]);
        if p.x0 <= q.x1 && q.x0 <= p.x1 {
            u.join(a.1 + i as u32, b.1 + j as u32);
        }
        if p.x1 < q.x1 {
            i += 1;
        } else {
            j += 1;
        }
    }
}

fn pieces(volume: &Volume) -> Pieces {
    let runs = runs(volume);
    // Where each line's runs begin in `runs`.
    let mut line_at: HashMap<(i64, i64), (u32, u32)> = HashMap::new();
    let mut i = 0;
    while i < runs.len() {
        let (y, z) = (runs[i].y, runs[i].z);
        let mut j = i;
        while j < runs.len() && runs[j].y == y && runs[j].z == z {
            j += 1;
        }
        line_at.insert((y, z), (i as u32, j as u32));
        i = j;
    }
    let mut u = Union((0..runs.len() as u32).collect());
    for (&(y, z), &(a0, a1)) in &line_at {
        for next in [(y + 1, z), (y, z + 1)] {
            if let Some(&(b0, b1)) = line_at.get(&next) {
                join_lines(&mut u, (&runs[a0 as usize..a1 as usize], a0), (&runs[b0 as usize..b1 as usize], b0));
            }
        }
    }
    let mut number: HashMap<u32, u32> = HashMap::new();
    let piece = (0..runs.len() as u32)
        .map(|r| {
            let root = u.find(r);
            let next = number.len() as u32;
            *number.entry(root).or_insert(next)
        })
        .collect();
    Pieces { runs, piece, count: number.len() }
}

impl Volume {
    /// The pieces of the solid (see the module docs) as their sizes in inside nodes, largest
    /// first; `None` when the chunks mix levels.
    pub fn piece_sizes(&self) -> Option<Vec<u64>> {
        if !self.single_level() {
            return None;
        }
        let p = pieces(self);
        let mut sizes = vec![0u64; p.count];
        for (r, &k) in p.runs.iter().zip(&p.piece) {
            sizes[k as usize] += r.len();
        }
        sizes.sort_unstable_by(|a, b| b.cmp(a));
        Some(sizes)
    }

    /// Removes the pieces of the solid smaller than `min_volume` cells³ of the base grid (see
    /// the module docs), keeping always the largest piece (every piece of the largest size), so
    /// a small solid is never removed whole. Threshold 0 removes nothing. The edit is one undoable report; a threshold that is
    /// NaN, infinite or negative, or a volume whose chunks mix levels, is refused and nothing
    /// changes.
    pub fn remove_islands(&mut self, min_volume: f64) -> Result<IslandRemoval, IslandError> {
        if !(min_volume.is_finite() && min_volume >= 0.0) {
            return Err(IslandError::BadThreshold(min_volume));
        }
        if !self.single_level() {
            return Err(IslandError::MixedLevels);
        }
        let level = self.level();
        let cell = level.spacing().powi(3);
        let p = pieces(self);
        let mut sizes = vec![0u64; p.count];
        for (r, &k) in p.runs.iter().zip(&p.piece) {
            sizes[k as usize] += r.len();
        }
        let largest = sizes.iter().copied().max().unwrap_or(0);
        let small: Vec<bool> = sizes.iter().map(|&s| s < largest && (s as f64) * cell < min_volume).collect();
        let mut islands: Vec<Vec<Run>> = vec![Vec::new(); p.count];
        for (r, &k) in p.runs.iter().zip(&p.piece) {
            if small[k as usize] {
                islands[k as usize].push(*r);
            }
        }
        let mut out = IslandRemoval::default();
        for k in 0..p.count {
            if !small[k] {
                out.kept += 1;
                continue;
            }
            let brush = NodeCubes::new(&islands[k], level);
            let edit = self.subtract(&brush)?;
            out.edit = std::mem::take(&mut out.edit).then(edit);
            out.removed += 1;
            out.removed_nodes += sizes[k];
        }
        out.removed_volume = out.removed_nodes as f64 * cell;
        Ok(out)
    }
}

/// Runs of nodes along the lines of one axis family: for each line (its node coordinates across
/// the axis, in [`Axis::across`] order), the sorted, merged runs `(first, last)` along it.
type LineRuns = HashMap<(i64, i64), Vec<(i64, i64)>>;

/// The union of the cubes of a set of nodes of `level` (side one node spacing, centred on the
/// nodes): inside exactly at those nodes, with its faces halfway between nodes.
struct NodeCubes {
    spacing: f64,
    nodes: HashSet<I64Vec3>,
    /// Per axis, the runs of the nodes along its lines.
    lines: [LineRuns; 3],
    /// The x runs, for the field.
    boxes: Vec<Run>,
    bounds: Aabb,
}

impl NodeCubes {
    fn new(runs: &[Run], level: Level) -> Self {
        let spacing = level.spacing();
        let mut nodes = HashSet::new();
        for r in runs {
            nodes.extend((r.x0..=r.x1).map(|x| I64Vec3::new(x, r.y, r.z)));
        }
        let mut lines: [HashMap<(i64, i64), Vec<i64>>; 3] = Default::default();
        for &node in &nodes {
            for axis in Axis::ALL {
                let (ua, va) = axis.across();
                lines[axis.index()].entry((node[ua.index()], node[va.index()])).or_default().push(node[axis.index()]);
            }
        }
        let lines = lines.map(|family| {
            family
                .into_iter()
                .map(|(key, mut along)| {
                    along.sort_unstable();
                    let mut merged: Vec<(i64, i64)> = Vec::new();
                    for a in along {
                        match merged.last_mut() {
                            Some(last) if last.1 + 1 == a => last.1 = a,
                            _ => merged.push((a, a)),
                        }
                    }
                    (key, merged)
                })
                .collect()
        });
        let lo = runs.iter().map(|r| I64Vec3::new(r.x0, r.y, r.z)).reduce(I64Vec3::min);
        let hi = runs.iter().map(|r| I64Vec3::new(r.x1, r.y, r.z)).reduce(I64Vec3::max);
        let half = DVec3::splat(spacing / 2.0);
        let bounds = match (lo, hi) {
            (Some(lo), Some(hi)) => Aabb::new(lo.as_dvec3() * spacing - half, hi.as_dvec3() * spacing + half),
            _ => Aabb::new(DVec3::ZERO, DVec3::ZERO),
        };
        NodeCubes { spacing, nodes, lines, boxes: runs.to_vec(), bounds }
    }

    /// The node whose cube holds the grid point `p` (cubes are half-open: `[k - ½, k + ½)`).
    fn node_at(&self, p: DVec3) -> I64Vec3 {
        (p / self.spacing + DVec3::splat(0.5)).floor().as_i64vec3()
    }
}

impl Brush for NodeCubes {
    fn bounds(&self) -> Aabb {
        self.bounds
    }

    fn field(&self, origin: DVec3, p: DVec3) -> f64 {
        // The distance to the nearest box of a run: exact outside the union, a 1-Lipschitz
        // bound of the right sign inside.
        let q = origin + p;
        let h = self.spacing / 2.0;
        self.boxes
            .iter()
            .map(|r| {
                let lo = DVec3::new(r.x0 as f64, r.y as f64, r.z as f64) * self.spacing - DVec3::splat(h);
                let hi = DVec3::new(r.x1 as f64, r.y as f64, r.z as f64) * self.spacing + DVec3::splat(h);
                let (c, e) = ((lo + hi) / 2.0, (hi - lo) / 2.0);
                let d = (q - c).abs() - e;
                d.max(DVec3::ZERO).length() + d.max_element().min(0.0)
            })
            .fold(f64::INFINITY, f64::min)
    }

    fn contains(&self, origin: DVec3, p: DVec3) -> bool {
        self.nodes.contains(&self.node_at(origin + p))
    }

    fn spans(&self, origin: DVec3, start: DVec3, dir: DVec3, out: &mut Vec<Span>) -> bool {
        let Some(a) = unit_axis(dir) else { return false };
        out.clear();
        let axis = Axis::ALL[a];
        let (ua, va) = axis.across();
        let at = origin + start;
        let node = self.node_at(at);
        let Some(runs) = self.lines[a].get(&(node[ua.index()], node[va.index()])) else { return true };
        let h = self.spacing / 2.0;
        let (unit, along) = (axis.unit(), at[a]);
        out.extend(runs.iter().map(|&(a0, a1)| Span {
            enter: a0 as f64 * self.spacing - h - along,
            exit: a1 as f64 * self.spacing + h - along,
            enter_normal: -unit,
            exit_normal: unit,
        }));
        true
    }
}
