//! The runtime: primitive registry, instances, tiles, depth and G-buffers, shading, output.
