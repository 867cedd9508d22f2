//! Tools beyond CSG, built on one primitive: a [`Region`] of the solid read into a local signed
//! distance field ([`crate::Volume::read_region`]), changed by an operator, and written back as
//! an ordinary edit ([`crate::Volume::write_region`]).

mod region;

pub use region::{Region, RegionError};
