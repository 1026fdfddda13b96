//! The geometry pipeline: transforms, clip codes and clipping, V = GQE factoring, lighting
//! coordinates, face determination, and whole renders through it.
//!
//! One test binary per layer keeps the suite to a handful of links; one module per concern.

mod clip;
mod face;
mod factor;
mod geometry_explain;
mod geometry_render;
mod lighting;
mod lines;
#[path = "../support/mod.rs"]
mod support;
mod transform;
