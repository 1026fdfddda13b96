//! `Jit::disassembly`: a kernel's machine code after register allocation, with its count of
//! spill and reload instructions (the measure of tier 0's single-pass allocator in
//! docs/performance.md, `compile_probe disasm=FILE`). The count must separate the
//! allocator's spill slots from the kernel's own stack slots (the uniform frame, the
//! argument blocks of calls), which print alike.

use crate::support;

use primflow::jit::{Jit, Tier};
use primflow::runtime::{Renderer, Value};

/// A primitive whose pixel code reads two uniform locals: they go to the uniform frame (an
/// explicit stack slot), written with typed stores in the setup.
const FRAMED: &str = r#"
primitive framed(
    float rect[4];
    float k;
    varying float X, Y;
    inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float a = k * 0.5;
    float b = k + 0.25;
    Z = (a * X + b * Y) * 0.001;
}
"#;

/// Stack-slot lines by kind: (the register allocator's own full-register moves, `movq` and
/// `movdqu`; typed accesses, which only the kernel's explicit slots get).
fn slot_lines(text: &str) -> (usize, usize) {
    let slot = text.lines().filter(|l| l.contains("<offset:1>"));
    let moves = |l: &&str| matches!(l.split_whitespace().next(), Some("movq" | "movdqu"));
    let n_moves = slot.clone().filter(moves).count();
    (n_moves, slot.count() - n_moves)
}

#[test]
fn frame_slot_accesses_are_not_counted_as_spills() {
    let mut sources = primflow::diag::SourceMap::new();
    let program = support::library_with(&mut sources, &[("framed.prim", FRAMED)]);
    let mut r = Renderer::new(program.clone());
    r.set_image_size(40, 24).unwrap();
    r.begin("framed").unwrap();
    r.rast_param("rect", &Value(vec![2.0, 3.0, 30.0, 20.0])).unwrap();
    r.rast_param("k", &Value(vec![1.5])).unwrap();
    r.end().unwrap();
    let inst = &r.instances()[0];
    for tier in [Tier::Fast, Tier::Optimised] {
        let d = Jit::at_tier(program.clone(), tier)
            .unwrap()
            .disassembly(inst.func, &inst.key)
            .unwrap();
        let (moves, typed) = slot_lines(&d.text);
        // The frame's typed stores (`vmovss`, `vmovups`) and its address (`leaq`) are
        // there and not counted; what is counted are register moves to or from a slot.
        assert!(typed >= 3, "{tier:?}: frame accesses missing in:\n{}", d.text);
        assert!(
            d.spill_lines <= moves,
            "{tier:?}: {} counted of\n{}",
            d.spill_lines,
            d.text
        );
        assert!(d.spill_lines > 0, "{tier:?}: block boundaries in the row loops spill");
    }
}

#[test]
fn tier_0_screen_triangle_spills_and_every_spill_line_is_an_instruction() {
    let program = support::library();
    let scene = primflow::workload::fill_scene(&program, 64, 1, Some("perspective_linear"), 4);
    let inst = &scene.instances()[0];
    for tier in [Tier::Fast, Tier::Optimised] {
        let jit = Jit::at_tier(program.clone(), tier).unwrap();
        let d = jit.disassembly(inst.func, &inst.key).unwrap();
        let listed = d
            .text
            .lines()
            .map(str::trim)
            .filter(|l| !l.is_empty() && !l.ends_with(':') && !l.starts_with("unwind "))
            .count();
        assert_eq!(d.inst_lines, listed, "{tier:?}");
        // Every counted line is a register move to or from a slot; the setup's typed
        // uniform frame stores (one per frame word, 39 here) are not among them.
        let (moves, typed) = slot_lines(&d.text);
        assert!(d.spill_lines <= moves, "{tier:?}");
        assert!(typed >= 39, "{tier:?}: {typed} typed slot accesses");
        assert!(d.spill_lines < d.inst_lines, "{tier:?}");
        if tier == Tier::Fast {
            // The single-pass allocator spills values of the long setup block
            // (docs/performance.md, `sink`): hundreds of lines for this kernel.
            assert!(d.spill_lines > 100, "tier 0 spill lines: {}", d.spill_lines);
        }
    }
}
