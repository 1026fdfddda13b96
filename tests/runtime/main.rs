//! The runtime: the primitive API, value encoding and camera helpers, the registry, instances and
//! expansion, binning and parallel tiles, thread pools and the tier-up gate, the frame's buffers
//! and images, the shading pass and the scene format. `support::kernels` drives it with
//! hand-written ABI kernels, without the JIT.
//!
//! One test binary per layer keeps the suite to a handful of links; one module per concern.

mod antialiasing;
mod api;
mod api_example;
mod binning;
mod camera_matrices;
mod e2e;
mod error_counts;
mod expand;
mod frame_budget;
mod frame_images;
mod frame_layout;
mod fuel;
mod kernels;
mod live_planes;
mod plane_layout;
mod pool_pinning;
mod registry_loading;
mod render;
mod render_into;
mod render_triangles;
mod scene_format;
mod scene_library_subset;
mod scene_tokens;
mod shading_builds;
mod shading_fast;
mod shading_fast_maths;
mod shading_lanes;
mod shading_language;
mod shading_lighting;
mod shading_phong;
mod shading_reference;
mod shading_rows;
mod silent_mistakes;
#[path = "../support/mod.rs"]
mod support;
mod texture;
mod tier_gate;
mod tier_gate_jobs;
mod value_encoding;
