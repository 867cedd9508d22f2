//! Tools beyond CSG, built on one primitive: a [`Region`] of the solid read into a local signed
//! distance field ([`crate::Volume::read_region`]), changed by an operator, and written back as
//! an ordinary edit ([`crate::Volume::write_region`]). The operators so far: [`inflate`],
//! [`smooth`] (Laplacian or volume-preserving) and [`flatten`], each applied as a [`Dab`].

mod ops;
mod region;

pub use ops::{Dab, Smoothing, ToolError, falloff, flatten, inflate, smooth};
pub use region::{BAND, MAX_REGION_NODES, Region, RegionError};
