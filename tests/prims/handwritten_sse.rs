//! The hand-written kernels' SSE4.1 forms, legacy and VEX encoded, draw bit for bit what
//! their scalar forms do (which `handwritten_twins` and `handwritten_shapes` hold to the JIT),
//! whatever form the runtime would pick on this CPU: screen_triangle on one tile with
//! wide, narrow and huge triangles, the sphere through the renderer.

use std::sync::Arc;

use primflow::abi::{Kernel, KernelError, KernelFn, TileCtx, VariantKey, MODE_RENDER};
use primflow::handwritten::screen_triangle as st;
use primflow::handwritten::sphere::entry_for;
use primflow::handwritten::{isa, Flavor, Handwritten};
use primflow::ir::FuncId;
use primflow::runtime::{KernelSource, Renderer, Value};

use crate::support;

/// Buffers of one tile after drawing `tris` (argument blocks) with `kernel`.
fn draw(kernel: KernelFn, tris: &[Vec<u32>]) -> (Vec<u32>, Vec<u32>, Vec<f32>) {
    // A tile that starts off the group grid of the screen and is not whole groups wide.
    let (x0, y0, x1, y1) = (66, 3, 111, 40);
    let stride = 48u32;
    let len = (stride * (y1 - y0) as u32) as usize;
    let planes = 3u32;
    let mut depth = vec![0u32; len];
    let mut counts = vec![0u32; len];
    let mut gbuf = vec![0f32; len * planes as usize];
    for args in tris {
        let mut ctx = TileCtx {
            x0,
            y0,
            x1,
            y1,
            stride,
            depth: depth.as_mut_ptr(),
            gbuf: gbuf.as_mut_ptr(),
            plane_stride: len as u32,
            num_planes: planes,
            write_count: counts.as_mut_ptr(),
            ..TileCtx::new(MODE_RENDER, 200, 100)
        };
        // SAFETY: the context's buffers are `len` (x planes) long with the stride given,
        // and `args` is a screen_triangle block for 2 + 2 components.
        unsafe { kernel(&mut ctx, args.as_ptr()) };
    }
    (depth, counts, gbuf)
}

/// The legacy-encoded and VEX-encoded SSE kernels draw exactly what the scalar one
/// does (which tests/prims/handwritten_twins.rs holds to the JIT) on one tile, with a plane
/// the frame lacks (index 7 of 3), wide, narrow and huge (float edge) triangles.
#[test]
fn sse_forms_match_scalar_on_a_tile() {
    let mut seed = 12345u64;
    let mut next = move |lo: f32, hi: f32| {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        lo + (hi - lo) * ((seed >> 40) as f32 / (1u64 << 24) as f32)
    };
    let mut tris = vec![];
    for k in 0..400 {
        let size = [2.0, 10.0, 60.0, 3000.0][k % 4];
        let (cx, cy) = (next(50.0, 130.0), next(-10.0, 50.0));
        let mut args = vec![1u32, 0, 1, 7, 2];
        for _ in 0..3 {
            let (x, y) = (next(cx - size, cx + size), next(cy - size, cy + size));
            // Every other triangle on the 1/16 grid: exact edge ties.
            let snap = |v: f32| if k % 2 == 0 { (v * 16.0).round() / 16.0 } else { v };
            for v in [snap(x), snap(y), next(-0.2, 1.2), next(0.3, 3.0)] {
                args.push(v.to_bits());
            }
        }
        args.extend((0..12).map(|_| next(-2.0, 2.0).to_bits()));
        tris.push(args);
    }
    let reference = draw(st::scalar::<2, 2, 4, true>, &tris);
    assert!(reference.0.iter().filter(|&&d| d != 0).count() > 1000);
    let mut forms: Vec<(&str, KernelFn)> = vec![];
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("sse4.1") {
            forms.push(("sse41", st::sse41::<2, 2, 4, true>));
        }
        if std::arch::is_x86_feature_detected!("sse4.1") && std::arch::is_x86_feature_detected!("avx") {
            forms.push(("sse41_vex", st::sse41_vex::<2, 2, 4, true>));
        }
    }
    for (name, kernel) in forms {
        let (depth, counts, gbuf) = draw(kernel, &tris);
        assert!(depth == reference.0, "{name}: depth differs");
        assert!(counts == reference.1, "{name}: write counts differ");
        let differing = gbuf
            .iter()
            .zip(&reference.2)
            .filter(|(a, b)| a.to_bits() != b.to_bits())
            .count();
        assert_eq!(differing, 0, "{name}: {differing} G-buffer values differ");
    }
}

/// The hand-written sphere in form `isa` (an `isa::*` constant), whatever the CPU (the
/// runtime picks the VEX form on a CPU with AVX; this reaches the legacy one).
struct Form {
    hand: Handwritten,
    isa: u8,
}

impl KernelSource for Form {
    fn kernel(&mut self, func: FuncId, key: &VariantKey) -> Result<Arc<Kernel>, KernelError> {
        let k = self.hand.kernel(func, key)?;
        let entry = entry_for(&k.layout, key, self.isa).map_err(|message| KernelError { message })?;
        Ok(Arc::new(Kernel {
            func: k.func,
            key: k.key.clone(),
            entry,
            layout: k.layout.clone(),
            compile_micros: 0,
            warnings: vec![],
        }))
    }
}

/// Both SSE4.1 encodings draw exactly what the scalar kernel does (which
/// tests/prims/handwritten_shapes.rs holds to the JIT): a viewport that is not whole groups
/// wide with small tiles, overlapping spheres of several sizes (one narrower than a
/// group), one cut by the hither plane; with the normal and write counts, and without
/// either.
#[cfg(target_arch = "x86_64")]
#[test]
fn sse_forms_match_scalar() {
    if !std::arch::is_x86_feature_detected!("sse4.1") {
        return;
    }
    let program = support::library();
    let mut forms = vec![("sse41", isa::SSE41)];
    if std::arch::is_x86_feature_detected!("avx") {
        forms.push(("sse41_vex", isa::SSE41_VEX));
    }
    for (normal, count_writes) in [(true, true), (false, false)] {
        let mut r = Renderer::new(program.clone());
        r.set_image_size(45, 37).unwrap();
        r.set_tile_size(16).unwrap();
        r.options.count_writes = count_writes;
        r.perspective(60.0, 1.0, 50.0);
        if normal {
            r.material_interp("N", "implicit", &[]).unwrap();
            r.material("N", &Value(vec![0.0, 0.0, 1.0])).unwrap();
        }
        for (c, radius) in [
            ([0.0, 0.0, -6.0], 1.5),
            ([1.2, -0.6, -5.0], 0.7),
            ([-1.5, 1.0, -7.0], 0.05),
            ([0.3, 0.2, -1.3], 0.6),
            ([-0.8, -0.9, -4.0], 1.1),
        ] {
            r.begin("sphere").unwrap();
            r.rast_param("center", &Value(c.to_vec())).unwrap();
            r.rast_param("radius", &Value(vec![radius])).unwrap();
            r.end().unwrap();
        }
        let mut scalar = Handwritten::new(program.clone(), Flavor::Scalar);
        let reference = r.render(&mut scalar);
        assert!(reference.diags.items.is_empty(), "{:?}", reference.diags.items);
        let drawn = reference.frame.depth_values().iter().filter(|&&d| d != 0).count();
        assert!(drawn > 45 * 37 / 3, "only {drawn} pixels drawn");
        for &(name, isa) in &forms {
            let mut source = Form {
                hand: Handwritten::new(program.clone(), Flavor::Scalar),
                isa,
            };
            let out = r.render(&mut source);
            assert!(out.diags.items.is_empty(), "{name}: {:?}", out.diags.items);
            assert!(
                primflow::workload::same_frame(&reference.frame, &out.frame),
                "{name}, normal {normal}: the frame differs from the scalar kernel's"
            );
            assert_eq!(
                reference.frame.write_count_values(),
                out.frame.write_count_values(),
                "{name}: write counts differ"
            );
        }
    }
}
