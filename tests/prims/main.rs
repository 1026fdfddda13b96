//! The primitive library (prims/*.prim) rendered through the JIT against analytic and f64
//! references, and the hand-written baseline kernels checked against the JIT (their SSE forms
//! against their scalar ones, `handwritten_sse`).
//!
//! One test binary per layer keeps the suite to a handful of links; one module per concern.

mod handwritten_shapes;
mod handwritten_sse;
mod handwritten_twins;
mod hard_cases;
mod interpolators;
mod library;
mod lines;
mod nurb;
mod points;
mod polygon;
mod sphere;
#[path = "../support/mod.rs"]
mod support;
