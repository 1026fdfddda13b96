//! Golden files of the compiler's stages for a few kernels: the checked IR and the CLIF of
//! screen_triangle with four perspective-correct parameters (the bench's `fill
//! perspective_linear K=4`) at both tiers, the sphere with its implicit normal, and the
//! documentation's user-written disc. A codegen change shows as a diff of these snapshots
//! (`tests/jit/snapshots/`); review it with `cargo insta review` or by reading the diff, and
//! accept it with `INSTA_UPDATE=always cargo test --test jit golden`.
//!
//! The CLIF printed does not depend on the host's CPU features (the lowering chooses no
//! instruction by ISA flag; Cranelift's instruction selection comes after it), so the same
//! snapshots hold on every x86-64 host.

use std::sync::Arc;

use primflow::diag::SourceMap;
use primflow::ir::Program;
use primflow::jit::{Jit, Tier};

use crate::support;

/// docs/language.md's first example, as a user would write it.
const DISC: &str = "primitive disc(float cx, cy, r; float depth = 0.5;
               varying float X, Y;
               inout varying fixed<32,32> Z)
{
    bound(cx - r, cy - r, cx + r, cy + r);
    float dx = X - cx, dy = Y - cy;
    if (dx * dx + dy * dy > r * r)
        return;
    if (depth < Z)
        return;
    Z = depth;
    interpolator_return;
}
";

/// The IR of `name`, then its CLIF for `key` (a `--key` spec) at `tier`.
fn stages(program: &Arc<Program>, name: &str, key: &str, tier: Tier) -> String {
    let func = program.find(name).unwrap();
    let key = primflow::cli::parse_key(key, program).unwrap();
    let jit = Jit::at_tier(program.clone(), tier).unwrap();
    let clif = jit.clif(func, &key).unwrap();
    format!("; IR\n{}\n; CLIF, {tier:?}\n{clif}", program.functions[func.0 as usize])
}

const K4: &str = "perspective_linear:1,perspective_linear:1,perspective_linear:1,perspective_linear:1";

#[test]
fn screen_triangle_k4_tier0() {
    let text = stages(&support::library(), "screen_triangle", K4, Tier::Fast);
    insta::assert_snapshot!("screen_triangle_k4_tier0", text);
}

#[test]
fn screen_triangle_k4_tier1() {
    let text = stages(&support::library(), "screen_triangle", K4, Tier::Optimised);
    insta::assert_snapshot!("screen_triangle_k4_tier1", text);
}

#[test]
fn sphere_implicit_normal_tier1() {
    let text = stages(&support::library(), "sphere", "implicit:3", Tier::Optimised);
    insta::assert_snapshot!("sphere_implicit_tier1", text);
}

#[test]
fn user_disc_tier0_and_tier1() {
    let mut sources = SourceMap::new();
    let program = support::library_with(&mut sources, &[("disc.prim", DISC)]);
    let text = format!(
        "{}\n{}",
        stages(&program, "disc", "", Tier::Fast),
        stages(&program, "disc", "", Tier::Optimised)
    );
    insta::assert_snapshot!("disc_tier0_tier1", text);
}
