//! Rays: closest-hit and occlusion queries over a four-wide BVH ([`ray`]), the ground-truth path
//! tracer built on them ([`reference`](mod@reference)), the sampling it uses ([`sampling`]), and the
//! default view of a scene without a camera ([`framing`]).

#[cfg(feature = "rays")]
mod bvh4;
#[cfg(feature = "rays")]
pub mod framing;
#[cfg(feature = "rays")]
pub mod ray;
pub mod reference;
pub mod sampling;
