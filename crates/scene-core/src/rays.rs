//! Rays: closest-hit and occlusion queries over a CWBVH ([`ray`]), the ground-truth path
//! tracer built on them ([`reference`]), and the sampling it uses ([`sampling`]).

pub mod ray;
pub mod reference;
pub mod sampling;
