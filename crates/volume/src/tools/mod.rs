//! Tools beyond CSG, built on one primitive: a [`Region`] of the solid read into a local signed
//! distance field ([`crate::Volume::read_region`]), changed by an operator, and written back as
//! an ordinary edit ([`crate::Volume::write_region`]). The operators, each applied as a [`Dab`]:
//! [`clay`] (filleted add and erase), [`inflate`], [`smooth`] (volume-preserving, Laplacian, or
//! the paper's Eq. 1 on the crossings), [`flatten`], and the deformations [`grab`] and
//! [`pinch`], which move the surface with a displacement field in sub-steps of at most
//! [`MAX_STEP`] nodes; and [`stamp`], which raises or carves a grey-scale image.

mod deform;
mod endpoints;
mod falloff;
mod mask;
mod ops;
mod paint;
mod region;
mod stamp;

pub use deform::{MAX_STEP, MAX_STEPS, grab, pinch};
pub use falloff::{Falloff, FalloffCurve, FalloffError, MAX_CURVE_POINTS};
pub use mask::{MaskStroke, mask};
pub use ops::{Dab, Smoothing, ToolError, clay, falloff, flatten, inflate, smooth};
pub use paint::paint;
pub use region::{BAND, FAR, MAX_REGION_NODES, Reach, Region, RegionCrossing, RegionError};
pub use stamp::{
    BUILTIN_SIDE, BuiltinStamp, STAMP_MAX_SIDE, StampError, StampFrame, StampImage, StampPlacement, stamp,
};
