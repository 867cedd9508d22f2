//! The region primitive: lists → a local signed distance field → lists.
//!
//! [`Volume::read_region`] reads the nodes of a box (in node units of the volume's level) into a
//! [`Region`]: every node's state, and a signed distance to the surface (negative inside) that is
//! a real distance near the surface and beyond it, not a field clamped to a cell. The states and
//! the stored crossings come straight from the chunks' own lines through the box (`read`). Near
//! the surface (within [`BAND`] nodes of a stored crossing) the distance is that to the tangent
//! plane of the crossing whose normal line passes closest, from the stored positions and normals
//! (`band`); farther out it is the distance to the nearest crossing, propagated from the band
//! node by node (grown layer by layer for shallow depths, swept in passes over the box for deep
//! ones). Within a [`Reach`] only the nodes the reach needs get a distance. Its sign is the
//! node's state, so the field and the lists never disagree about inside.
//!
//! An operator then changes `phi` and says where with `weight` (0 leaves a node alone; any
//! positive weight hands the node to the operator: its state becomes the sign of its new `phi`).
//! [`Volume::write_region`] writes the result back as an ordinary edit:
//! - node states are computed once per node from the region, so the x, y and z lists agree on
//!   every node by construction, and chunks agree on the nodes they share;
//! - a cell whose two nodes now differ gets a crossing at the root of the linear interpolation of
//!   `phi` between them, with the normal of `phi`'s gradient there, unless both nodes are
//!   untouched (weight 0, or `phi` unchanged) and the cell held a crossing before: then the old
//!   crossing stays, bit for bit. So wherever the weight is 0 the volume is unchanged exactly;
//! - the report lists the changed chunks and holds an exact [`crate::UndoRecord`].
//!
//! Nodes on the region's outer layer are never handed to the operator (their weight is ignored),
//! so every edge the operator can change has both nodes inside the region.

use glam::{DVec3, I64Vec3, IVec3};
use thiserror::Error;

use crate::axis::Axis;
use crate::coords::{ChunkBox, ChunkKey, Level};
use crate::volume::Volume;

mod band;
mod read;
mod write;

pub(crate) use read::RowSpans;

/// Nodes within this distance (node units) of a stored crossing take their distance from the
/// crossings' tangent planes; the rest is swept out from them.
pub const BAND: f64 = 3.0;

/// A crossing's tangent plane gives a node's distance only if the crossing's normal line passes
/// within this many node steps of the node.
const MAX_LATERAL: f64 = 1.0;

/// Reads within a reach at most this many nodes deeper than the band grow the nearest crossing
/// layer by layer from the band; deeper ones sweep.
const GROW_LAYERS: f64 = 3.0;

/// The most nodes a region may hold (about a 256³ box: 64 MB of fields).
pub const MAX_REGION_NODES: usize = 1 << 24;

/// The distance (node units) a region with no crossing at all reads at every node: farther than
/// any region reaches, yet finite, so that operators' arithmetic (differences, Laplacians,
/// blends) stays exact and never overflows.
pub const FAR: f32 = 1.0e6;

/// The smallest magnitude a read distance takes, so that its sign always says the node's state.
const MIN_DISTANCE: f32 = 1e-4;

/// Why a region could not be read or written.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum RegionError {
    /// A corner that is NaN or infinite, or a box with min above max.
    #[error("the region's box is not finite and ordered")]
    BadBox,
    /// More nodes than [`MAX_REGION_NODES`].
    #[error("the region holds {nodes} nodes, more than the limit of {limit}")]
    TooLarge {
        /// Nodes asked for (saturating).
        nodes: u64,
        /// The limit.
        limit: usize,
    },
    /// The region reaches beyond the chunk key range.
    #[error("the region reaches beyond the volume's chunk key range")]
    OutOfRange,
    /// The region's fields were resized or its volume's level changed since it was read.
    #[error("the region does not match the volume it is written to")]
    Mismatch,
}

/// A box of nodes of a volume with their states and a signed distance field.
#[derive(Clone, Debug)]
pub struct Region {
    /// Node coordinates (level units) of the region's first node.
    pub origin: I64Vec3,
    /// Nodes along x, y and z.
    pub dims: [usize; 3],
    /// Signed distance in node units (negative inside), `x + dims[0] (y + dims[1] z)`; the
    /// operator's output.
    pub phi: Vec<f32>,
    /// Per node, how much the operator owns it (0: untouched). Written by the operator.
    pub weight: Vec<f32>,
    /// The field as read.
    original: Vec<f32>,
    /// The stored crossings the field was read from (the region's box and [`BAND`] nodes
    /// around it).
    crossings: Vec<RegionCrossing>,
    level: Level,
}

/// A stored crossing near a region, as [`Region::crossings`] lists it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RegionCrossing {
    /// The axis of the grid line it lies on.
    pub axis: Axis,
    /// Its point, in node units of the region's level (absolute, not region-local).
    pub point: DVec3,
    /// Its unit outward normal.
    pub normal: DVec3,
}

impl Region {
    /// The index of node `(x, y, z)` (region-local).
    #[inline]
    pub fn index(&self, x: usize, y: usize, z: usize) -> usize {
        x + self.dims[0] * (y + self.dims[1] * z)
    }

    /// The node coordinates (level units) of region-local node `(x, y, z)`.
    pub fn node(&self, x: usize, y: usize, z: usize) -> I64Vec3 {
        self.origin + I64Vec3::new(x as i64, y as i64, z as i64)
    }

    /// The grid position (base cells) of region-local node `(x, y, z)`.
    pub fn grid_point(&self, x: usize, y: usize, z: usize) -> DVec3 {
        self.node(x, y, z).as_dvec3() * self.level.spacing()
    }

    /// Grid units per node step (the level's spacing).
    pub fn spacing(&self) -> f64 {
        self.level.spacing()
    }

    /// The field as read, before any operator.
    pub fn original(&self) -> &[f32] {
        &self.original
    }

    /// The field as read at grid point `p` (grid coordinates), trilinearly interpolated
    /// between the nodes; points outside the region take the nearest point of its box.
    pub fn sample_original(&self, p: DVec3) -> f32 {
        let local = p / self.level.spacing() - self.origin.as_dvec3();
        let mut i0 = [0usize; 3];
        let mut f = [0.0f64; 3];
        for a in 0..3 {
            let top = self.dims[a].saturating_sub(1) as f64;
            let x = local[a].clamp(0.0, top);
            let base = x.floor().min((top - 1.0).max(0.0));
            i0[a] = base as usize;
            f[a] = if self.dims[a] > 1 { x - base } else { 0.0 };
        }
        let at = |dx: usize, dy: usize, dz: usize| {
            let x = (i0[0] + dx).min(self.dims[0] - 1);
            let y = (i0[1] + dy).min(self.dims[1] - 1);
            let z = (i0[2] + dz).min(self.dims[2] - 1);
            self.original[self.index(x, y, z)] as f64
        };
        let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
        let x00 = lerp(at(0, 0, 0), at(1, 0, 0), f[0]);
        let x10 = lerp(at(0, 1, 0), at(1, 1, 0), f[0]);
        let x01 = lerp(at(0, 0, 1), at(1, 0, 1), f[0]);
        let x11 = lerp(at(0, 1, 1), at(1, 1, 1), f[0]);
        lerp(lerp(x00, x10, f[1]), lerp(x01, x11, f[1]), f[2]) as f32
    }

    /// The stored crossings the field was read from: those of the region's box and of
    /// [`BAND`] nodes around it, on all three axes.
    pub fn crossings(&self) -> &[RegionCrossing] {
        &self.crossings
    }

    /// The region with the operator's change at every node scaled by `1 - mask weight` there;
    /// a node the mask protects fully is not handed to the operator (see [`crate::mask`]).
    pub(crate) fn masked(&self, mask: &crate::mask::MaskSampler) -> Region {
        let mut out = self.clone();
        for z in 0..self.dims[2] {
            for y in 0..self.dims[1] {
                for x in 0..self.dims[0] {
                    let i = self.index(x, y, z);
                    if self.weight[i] <= 0.0 {
                        continue;
                    }
                    let m = mask.at(self.grid_point(x, y, z));
                    if m >= 1.0 {
                        out.weight[i] = 0.0;
                        out.phi[i] = self.original[i];
                    } else if m > 0.0 {
                        let o = self.original[i];
                        out.phi[i] = o + ((1.0 - m) as f32) * (self.phi[i] - o);
                    }
                }
            }
        }
        out
    }

    /// Whether the node at index `i` ([`Region::index`]) was inside when read.
    pub fn was_inside(&self, i: usize) -> bool {
        self.original[i] < 0.0
    }
}

/// Where a region's field has to be a distance: the rest of its box reads [`FAR`] with the
/// node's sign (its state stays exact), which saves the distance computation an operator would
/// not look at.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reach {
    /// The whole box.
    Everywhere,
    /// Nodes within `radius` (grid units) of the segment from `a` to `b` (a ball when the ends
    /// coincide), plus the region's apron. Their field is the distance to the surface wherever
    /// that is at most `depth` (grid units, at least [`BAND`] nodes); farther from the surface
    /// it is the distance to the nearest crossing within `radius + depth` of the segment (an
    /// upper bound, never below `depth`).
    Capsule {
        /// One end (grid coordinates).
        a: DVec3,
        /// The other end.
        b: DVec3,
        /// Radius (grid units).
        radius: f64,
        /// How far from the surface the field must be exact (grid units).
        depth: f64,
    },
}

impl Reach {
    /// A ball whose field is exact within `depth` of the surface.
    pub fn ball(center: DVec3, radius: f64, depth: f64) -> Self {
        Reach::Capsule { a: center, b: center, radius, depth }
    }

    /// The reach in node units (scaled by `inv_sp`, nodes per grid unit), its radius widened by
    /// `apron` nodes and its depth at least [`BAND`]; `None` for everywhere.
    fn in_nodes(&self, inv_sp: f64, apron: f64) -> Option<Reach> {
        match *self {
            Reach::Everywhere => None,
            Reach::Capsule { a, b, radius, depth } => Some(Reach::Capsule {
                a: a * inv_sp,
                b: b * inv_sp,
                radius: radius * inv_sp + apron,
                depth: (depth * inv_sp).max(BAND),
            }),
        }
    }

    fn is_finite(&self) -> bool {
        match *self {
            Reach::Everywhere => true,
            Reach::Capsule { a, b, radius, depth } => {
                a.is_finite() && b.is_finite() && radius.is_finite() && depth.is_finite()
            }
        }
    }
}

/// How far around a region's box [`Volume::level_near`] looks for finer chunks (grid units): the
/// apron and the band of any tool's region.
const LEVEL_MARGIN: f64 = 8.0;

impl Volume {
    /// The level a region over the box `[min, max]` is read at: the finest among the list chunks
    /// within a few cells of the box, and the volume's own (so a tool works at the finest
    /// resolution it touches and writes each chunk back at the chunk's own level).
    pub fn level_near(&self, min: DVec3, max: DVec3) -> Level {
        if self.single_level() || !(min.is_finite() && max.is_finite()) {
            return self.level;
        }
        let lo = ChunkKey::containing(min - DVec3::splat(LEVEL_MARGIN));
        let hi = ChunkKey::containing(max + DVec3::splat(LEVEL_MARGIN));
        let (Some(lo), Some(hi)) = (lo, hi) else { return self.level };
        let span = (hi.0 - lo.0 + IVec3::ONE).as_i64vec3();
        if span.x * span.y * span.z > 4096 {
            // A huge box: the finest level anywhere.
            let counts = self.level_counts();
            let top = counts.iter().rposition(|&c| c > 0).unwrap_or(0);
            return self.level.max(Level::ALL[top]);
        }
        ChunkBox::between(lo, hi).keys().filter_map(|k| self.stored_level(k)).fold(self.level, Level::max)
    }
}
