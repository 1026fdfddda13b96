#!/usr/bin/env bash
# Renders the README's gallery (docs/gallery/*.png) from the example scenes, with the
# binary built from this tree. Run from anywhere: bash scripts/gallery.sh
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --quiet
out=docs/gallery
mkdir -p "$out"
for scene in triangles geometry shaders spheres nurb_surface interpolators lines; do
    target/debug/primflow render "examples/$scene.scene" -o "$out/$scene.png" > /dev/null
    echo "$out/$scene.png"
done
# The same scenes antialiased: 16 samples per pixel, box resolve (docs/antialiasing.md).
for scene in shaders lines; do
    target/debug/primflow render "examples/$scene.scene" -o "$out/$scene-16x.png" --samples 16 > /dev/null
    echo "$out/$scene-16x.png"
done
