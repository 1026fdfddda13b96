//! The runtime: the primitive API, instances and expansion, binning and parallel tiles, the frame's
//! buffers, the shading pass and the scene format. `support::kernels` drives it with hand-written
//! ABI kernels, without the JIT.
//!
//! One test binary per layer keeps the suite to a handful of links; one module per concern.

mod api;
mod e2e;
mod error_counts;
mod expand;
mod frame_budget;
mod fuel;
mod kernels;
mod plane_layout;
mod render;
mod render_into;
mod render_triangles;
mod scene_format;
mod scene_library_subset;
mod shading_builds;
mod shading_fast;
mod shading_lighting;
mod shading_rows;
#[path = "../support/mod.rs"]
mod support;
mod tier_gate;
