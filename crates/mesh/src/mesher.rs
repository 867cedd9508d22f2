//! The choice of mesher, one name for it everywhere (viewport, export, CLI, bench).

use std::fmt;
use std::str::FromStr;

use strata_volume::Volume;
use thiserror::Error;

use crate::islands::{IslandError, IslandReport, remove_islands};
use crate::simplify::{Simplify, SimplifyError, simplify};
use crate::{BlockMesher, DualCache, LevelCap, Mesh};

/// A surface extractor.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Mesher {
    /// Marching cubes: vertices on the stored crossings, closed and edge-manifold, many slivers.
    #[default]
    MarchingCubes,
    /// Manifold dual contouring: one QEF vertex per surface component of a cell, sharp features,
    /// closed and edge-manifold.
    DualContouring,
    /// The first wave's dual contouring: one vertex per cell, whatever its components (two
    /// sheets in a cell share a vertex; a few edges are non-manifold). For comparison.
    SingleVertexDualContouring,
    /// Marching tetrahedra on the simple-cubic lattice, without clustering.
    Tetrahedra,
    /// Regularised marching tetrahedra: with the integrated vertex clustering.
    ClusteredTetrahedra,
}

impl Mesher {
    /// Every mesher, in the order menus list them.
    pub const ALL: [Mesher; 5] = [
        Mesher::MarchingCubes,
        Mesher::DualContouring,
        Mesher::ClusteredTetrahedra,
        Mesher::Tetrahedra,
        Mesher::SingleVertexDualContouring,
    ];

    /// A name for people.
    pub fn name(self) -> &'static str {
        match self {
            Mesher::MarchingCubes => "marching cubes",
            Mesher::DualContouring => "dual contouring",
            Mesher::SingleVertexDualContouring => "dual contouring, one vertex a cell",
            Mesher::Tetrahedra => "marching tetrahedra",
            Mesher::ClusteredTetrahedra => "regularised tetrahedra",
        }
    }

    /// What it makes, in a line (for tooltips).
    pub fn summary(self) -> &'static str {
        match self {
            Mesher::MarchingCubes => "Vertices on the stored crossings: closed and manifold, fast, many slivers",
            Mesher::DualContouring => {
                "A vertex per surface piece of a cell: sharp edges and corners, closed and manifold"
            }
            Mesher::SingleVertexDualContouring => "One vertex a cell (the first wave's): a few edges are not manifold",
            Mesher::Tetrahedra => "Marching tetrahedra on the cubic lattice, without clustering",
            Mesher::ClusteredTetrahedra => "Marching tetrahedra with vertex clustering: fewer, better-shaped triangles",
        }
    }

    /// The short name the CLI and the bench take (`mc`, `dc`, `dc1`, `mt`, `rmt`).
    pub fn key(self) -> &'static str {
        match self {
            Mesher::MarchingCubes => "mc",
            Mesher::DualContouring => "dc",
            Mesher::SingleVertexDualContouring => "dc1",
            Mesher::Tetrahedra => "mt",
            Mesher::ClusteredTetrahedra => "rmt",
        }
    }

    /// The per-block mesher, for meshers that mesh each chunk from its voxel block alone.
    pub fn block(self) -> Option<BlockMesher> {
        match self {
            Mesher::MarchingCubes => Some(BlockMesher::MarchingCubes),
            Mesher::Tetrahedra => Some(BlockMesher::Tetrahedra),
            Mesher::ClusteredTetrahedra => Some(BlockMesher::ClusteredTetrahedra),
            Mesher::DualContouring | Mesher::SingleVertexDualContouring => None,
        }
    }
}

impl fmt::Display for Mesher {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A mesher name that is none of [`Mesher::key`]'s.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
#[error("unknown mesher {0:?} (mc, dc, dc1, mt or rmt)")]
pub struct UnknownMesher(pub String);

impl FromStr for Mesher {
    type Err = UnknownMesher;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Mesher::ALL.into_iter().find(|m| m.key() == s).ok_or_else(|| UnknownMesher(s.to_string()))
    }
}

/// Why a volume was not meshed as asked.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum MesherError {
    /// Tetrahedra do not patch the seams between chunks of different levels.
    #[error(
        "{0} needs every chunk at one resolution level; this volume mixes levels (use marching cubes or dual contouring, or bring the detail back to the base level)"
    )]
    MixedLevels(Mesher),
    /// Chunk-by-chunk simplification (the viewport's) is done for the meshers that mesh chunk by
    /// chunk from blocks (marching cubes, tetrahedra); dual contouring is simplified whole, on
    /// export.
    #[error("the viewport simplifies chunk meshes of marching cubes and tetrahedra only; {0} is simplified on export")]
    ChunkSimplify(Mesher),
    /// Level-of-detail caps are for marching cubes, which patches the seams between levels.
    #[error("level-of-detail caps are for marching cubes; {0} meshes every chunk at its stored level")]
    CapsNeedMarchingCubes(Mesher),
    /// Simplification refused its input.
    #[error(transparent)]
    Simplify(#[from] SimplifyError),
    /// Island removal refused its threshold.
    #[error(transparent)]
    Islands(#[from] IslandError),
    /// A crease angle that is NaN, infinite or outside 0 to 180 degrees.
    #[error("the crease angle must be a finite number of degrees from 0 to 180, got {0}")]
    BadCrease(f32),
}

/// A mesher, an optional island removal and an optional simplification: what an export asks
/// for.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MeshOptions {
    /// The mesher.
    pub mesher: Mesher,
    /// Simplify the welded mesh with this error (grid units), or not at all.
    pub simplify: Option<f32>,
    /// Remove the pieces of the mesh that enclose less than this many cells³ (grid units cubed),
    /// before simplifying ([`crate::islands`]: the largest piece and cavity walls are kept), or
    /// keep every piece. [`crate::islands::DEFAULT_MIN_ISLAND_CELLS`] removes stray nodes. For
    /// whole meshes (export); the viewport meshes chunk by chunk and shows every piece.
    pub remove_islands: Option<f32>,
}

impl MeshOptions {
    /// `mesher`, without island removal or simplification.
    pub const fn new(mesher: Mesher) -> Self {
        MeshOptions { mesher, simplify: None, remove_islands: None }
    }
}

/// The door to whole-volume meshing: one welded mesh of the whole volume (grid units,
/// absolute) by `options` (the mesher, island removal, simplification). Marching cubes and dual
/// contouring mesh every volume; tetrahedra refuse one whose chunks mix levels.
pub fn mesh_volume_with(volume: &Volume, options: MeshOptions) -> Result<Mesh, MesherError> {
    mesh_volume_reported(volume, options, None).map(|(mesh, _)| mesh)
}

/// [`mesh_volume_with`], also saying what island removal removed (an empty report when
/// `options.remove_islands` is `None`), and with marching cubes meshing every chunk `k` no finer
/// than `caps(k)` where given (level of detail: coarser blocks sampled from the stored lists,
/// seams between levels patched, so the mesh is closed for any caps; other meshers refuse
/// caps). Every option is checked before meshing starts.
pub fn mesh_volume_reported(
    volume: &Volume,
    options: MeshOptions,
    caps: Option<LevelCap<'_>>,
) -> Result<(Mesh, IslandReport), MesherError> {
    if caps.is_some() && options.mesher != Mesher::MarchingCubes {
        return Err(MesherError::CapsNeedMarchingCubes(options.mesher));
    }
    if let Some(e) = options.simplify
        && !(e.is_finite() && e >= 0.0)
    {
        return Err(SimplifyError::BadError(e).into());
    }
    if let Some(min) = options.remove_islands
        && !(min.is_finite() && min >= 0.0)
    {
        return Err(IslandError::BadThreshold(min).into());
    }
    let mut mesh = match options.mesher {
        Mesher::MarchingCubes => match caps {
            Some(cap) => crate::marching::mesh_volume_capped(volume, cap),
            None => crate::marching::mesh_volume(volume),
        },
        Mesher::DualContouring => DualCache::build(volume).welded(),
        Mesher::SingleVertexDualContouring => DualCache::build_single_vertex(volume).welded(),
        m @ (Mesher::Tetrahedra | Mesher::ClusteredTetrahedra) => {
            crate::tetra::tetra_volume(volume, m == Mesher::ClusteredTetrahedra).ok_or(MesherError::MixedLevels(m))?
        }
    };
    let islands = match options.remove_islands {
        Some(min) => remove_islands(&mut mesh, min)?,
        None => IslandReport::default(),
    };
    let mesh = match options.simplify {
        Some(e) => simplify(&mesh, Simplify::export(e))?,
        None => mesh,
    };
    Ok((mesh, islands))
}

/// [`mesh_volume_reported`] with shading normals for export: creased at `crease_degrees`
/// ([`crate::normals::crease_normals`]), except for dual contouring, which places its own
/// normals at sharp features, and simplified meshes: at their triangle sizes the faces around
/// nearly every vertex differ by more than the crease angle, and splitting there doubled the
/// vertices (1,028 for 514 positions, the bunny at 48 cells within 0.3 cells), so they keep the
/// mesher's normals (the surface's, from the stored crossings) and are welded (vertices equal in
/// position, normal and material merged). Plain marching cubes is meshed and creased chunk by
/// chunk ([`crate::mesh_volume_creased`]), without a second whole mesh in memory.
pub fn mesh_volume_shaded(
    volume: &Volume,
    options: MeshOptions,
    crease_degrees: f32,
) -> Result<(Mesh, IslandReport), MesherError> {
    if !(crease_degrees.is_finite() && (0.0..=180.0).contains(&crease_degrees)) {
        return Err(MesherError::BadCrease(crease_degrees));
    }
    if options == MeshOptions::new(Mesher::MarchingCubes) {
        return Ok((crate::mesh_volume_creased(volume, crease_degrees), IslandReport::default()));
    }
    let (mesh, islands) = mesh_volume_reported(volume, options, None)?;
    let mesh = match options.mesher {
        _ if options.simplify.is_some() => mesh.welded(),
        Mesher::DualContouring | Mesher::SingleVertexDualContouring => mesh,
        _ => crate::normals::crease_normals(&mesh, crease_degrees),
    };
    Ok((mesh, islands))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_ones_are_refused() {
        for m in Mesher::ALL {
            assert_eq!(m.key().parse::<Mesher>(), Ok(m));
        }
        assert_eq!("marching".parse::<Mesher>(), Err(UnknownMesher("marching".into())));
    }
}
