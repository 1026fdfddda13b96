//! Tiered compilation (src/jit/mod.rs): tier-0 kernels (single-pass register allocation,
//! opt_level none, no block culling) and tier-1 kernels must write the same buffers bit for
//! bit, and a tiered JIT must hand out tier 0 first and tier 1 once its background compile
//! is done. The scenes are the example scenes (triangles with every interpolation kind,
//! spheres, NURB patches, the geometry pipeline) and the benchmark's fill and small-triangle
//! workloads.

use crate::support;

use std::sync::Arc;
use support::{example_scene, library_and_sources};

use primflow::diag::SourceMap;
use primflow::ir::Program;
use primflow::jit::{Jit, Tier};
use primflow::runtime::{Frame, KernelSource, Renderer};
use primflow::workload::{fill_scene, same_frame, small_scene};

fn render(r: &Renderer, source: &mut dyn KernelSource) -> Frame {
    let out = r.render(source);
    assert!(!out.diags.has_errors(), "{:?}", out.diags.items);
    out.frame
}

fn written_depths(f: &Frame) -> usize {
    f.depth_values().iter().filter(|&&d| d != 0).count()
}

fn scenes(sources: &mut SourceMap, program: &Arc<Program>) -> Vec<(String, Renderer)> {
    let mut out = vec![];
    for name in [
        "triangles.scene",
        "interpolators.scene",
        "spheres.scene",
        "nurb_surface.scene",
        "geometry.scene",
    ] {
        out.push((name.to_string(), example_scene(sources, program, name)));
    }
    for kind in [Some("perspective_linear"), Some("linear"), None] {
        out.push((format!("fill {kind:?}"), fill_scene(program, 96, 4, kind, 4)));
    }
    out.push(("small".into(), small_scene(program, 96, 300, 4)));
    out
}

#[test]
fn tier_0_and_tier_1_kernels_write_identical_frames() {
    let (mut sources, program) = library_and_sources();
    for (name, r) in scenes(&mut sources, &program) {
        let mut fast = Jit::at_tier(program.clone(), Tier::Fast).unwrap();
        let mut optimised = Jit::new(program.clone()).unwrap();
        let a = render(&r, &mut fast);
        let b = render(&r, &mut optimised);
        assert!(written_depths(&b) > 0, "{name}: the scene draws something");
        assert!(same_frame(&a, &b), "{name}: tier 0 and tier 1 frames differ");
        assert_eq!(a.is_shaded(), b.is_shaded());
        if let (Some(x), Some(y)) = (a.color_values(), b.color_values()) {
            assert!(
                x.iter()
                    .flatten()
                    .zip(y.iter().flatten())
                    .all(|(p, q)| p.to_bits() == q.to_bits()),
                "{name}: shaded colours differ"
            );
        }
    }
}

#[test]
fn a_tiered_jit_hands_out_tier_1_once_its_background_compile_is_done() {
    let (mut sources, program) = library_and_sources();
    for (name, r) in scenes(&mut sources, &program).into_iter().take(4) {
        let mut jit = Jit::tiered(program.clone()).unwrap();
        let first = render(&r, &mut jit);
        jit.wait_for_tier_up();
        let inst = &r.instances()[0];
        let tier1 = jit
            .tier_up_kernel(inst.func, &inst.key)
            .unwrap_or_else(|| panic!("{name}: no tier-1 kernel after waiting"));
        let handed = jit.kernel(inst.func, &inst.key).unwrap();
        assert_eq!(
            handed.entry as usize, tier1.entry as usize,
            "{name}: the JIT hands out the tier-1 kernel"
        );
        let second = render(&r, &mut jit);
        assert!(written_depths(&first) > 0, "{name}: the scene draws something");
        assert!(same_frame(&first, &second), "{name}: tier-0 and tier-1 frames differ");
    }
}

#[test]
fn tier_0_compiles_a_different_kernel_than_tier_1() {
    // Guards the test above against both tiers silently being the same configuration.
    let (_sources, program) = library_and_sources();
    let r = fill_scene(&program, 32, 1, Some("perspective_linear"), 4);
    let inst = &r.instances()[0];
    let fast = Jit::at_tier(program.clone(), Tier::Fast).unwrap();
    let optimised = Jit::new(program.clone()).unwrap();
    let a = fast.clif(inst.func, &inst.key).unwrap();
    let b = optimised.clif(inst.func, &inst.key).unwrap();
    assert!(
        a.lines().count() < b.lines().count(),
        "tier 0 has no block-culling variant, so less CLIF"
    );
}

/// Hands out the kernels it was given: a tiered JIT's tier-0 kernels, kept after their
/// tier-1 twins exist.
struct Kernels(
    std::collections::HashMap<(primflow::ir::FuncId, primflow::abi::VariantKey), Arc<primflow::abi::Kernel>>,
);

impl KernelSource for Kernels {
    fn kernel(
        &mut self,
        func: primflow::ir::FuncId,
        key: &primflow::abi::VariantKey,
    ) -> Result<Arc<primflow::abi::Kernel>, primflow::abi::KernelError> {
        self.0
            .get(&(func, key.clone()))
            .cloned()
            .ok_or_else(|| primflow::abi::KernelError {
                message: "not handed in".into(),
            })
    }
}

#[test]
fn tier_0_kernels_forward_to_their_tier_1_twins_once_compiled() {
    // A frame in flight when the worker finishes keeps calling the tier-0 entries it was
    // given (binned draws, expanded calls, direct calls between primitives); they must run
    // the tier-1 code from then on and still write the same frame.
    let (mut sources, program) = library_and_sources();
    let func = |name: &str| primflow::ir::FuncId(program.functions.iter().position(|f| f.name == name).unwrap() as u32);
    for (name, r) in scenes(&mut sources, &program) {
        let mut jit = Jit::tiered(program.clone()).unwrap();
        let mut tier0 = Kernels(Default::default());
        for inst in r.instances() {
            let ck = (inst.func, inst.key.clone());
            if !tier0.0.contains_key(&ck) {
                // The call that compiles a kernel returns its tier-0 build.
                tier0.0.insert(ck, jit.kernel(inst.func, &inst.key).unwrap());
            }
        }
        jit.wait_for_tier_up();
        for ((f, key), k) in &tier0.0 {
            let tier1 = jit.tier_up_kernel(*f, key).unwrap();
            assert_ne!(k.entry as usize, tier1.entry as usize, "{name}: two builds");
            assert_eq!(
                jit.tier0_forwards_to(*f, key).map(|e| e as usize),
                Some(tier1.entry as usize),
                "{name}: the tier-0 kernel forwards to the tier-1 one"
            );
            // The primitives it calls, compiled in its batch, forward too.
            if program.func(*f).name == "nurb_surface" {
                for callee in ["polygon", "screen_triangle"] {
                    assert!(jit.tier0_forwards_to(func(callee), key).is_some(), "{name}: {callee}");
                }
            }
        }
        let forwarded = render(&r, &mut tier0);
        let optimised = render(&r, &mut Jit::new(program.clone()).unwrap());
        assert!(written_depths(&optimised) > 0, "{name}: the scene draws something");
        assert!(same_frame(&forwarded, &optimised), "{name}: forwarded frame differs");
    }
}

#[test]
fn only_a_tiered_jits_tier_0_kernels_check_for_a_successor() {
    let (_sources, program) = library_and_sources();
    let r = fill_scene(&program, 32, 1, Some("perspective_linear"), 4);
    let inst = &r.instances()[0];
    let tiered = Jit::tiered(program.clone())
        .unwrap()
        .clif(inst.func, &inst.key)
        .unwrap();
    let fast = Jit::at_tier(program.clone(), Tier::Fast)
        .unwrap()
        .clif(inst.func, &inst.key)
        .unwrap();
    let optimised = Jit::new(program.clone()).unwrap().clif(inst.func, &inst.key).unwrap();
    assert!(
        tiered.contains("atomic_load") && tiered.contains("call_indirect"),
        "{tiered}"
    );
    for clif in [&fast, &optimised] {
        assert!(!clif.contains("atomic_load") && !clif.contains("call_indirect"));
    }
    // The check is all that differs: a few lines, not a second kernel.
    let extra = tiered.lines().count() as i64 - fast.lines().count() as i64;
    assert!((6..=16).contains(&extra), "{extra} more lines");
}
