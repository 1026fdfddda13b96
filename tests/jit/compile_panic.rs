//! A panic while compiling (a bug of the JIT or of Cranelift, injected here through
//! `primflow::jit::PANIC_AT_TIER_1`) is an error for that kernel, not the end of the render,
//! and a tiered JIT's tier-1 worker lives on with tier 0's kernel in place.

use std::sync::Arc;

use primflow::abi::{TierUpActivity, VariantKey};
use primflow::diag::{Diagnostics, SourceMap};
use primflow::ir::FuncId;
use primflow::jit::{Jit, Tier, PANIC_AT_TIER_1};

/// A primitive whose tier-1 compile panics (through [`PANIC_AT_TIER_1`]).
const PANICS_AT_TIER_1: &str = "panics_at_tier_1";

#[test]
fn a_panic_while_compiling_is_an_error_and_the_tier_1_worker_lives_on() {
    PANIC_AT_TIER_1.get_or_init(|| PANICS_AT_TIER_1.to_string());
    let source = format!(
        "primitive {PANICS_AT_TIER_1}(float rect[4]; varying float X, Y; inout varying fixed<32,32> Z)\n\
         {{\n    bound(rect[0], rect[1], rect[2], rect[3]);\n    Z = 0.5;\n}}\n"
    );
    let mut sources = SourceMap::new();
    let file = sources.add("panics.prim", source);
    let mut diags = Diagnostics::new();
    let program = Arc::new(primflow::compile(&sources, &[file], &mut diags).expect("checks"));
    let func = FuncId(0);
    let key = VariantKey::default();

    let mut tier1 = Jit::at_tier(program.clone(), Tier::Optimised).unwrap();
    let err = tier1.kernel(func, &key).err().expect("the panic is an error");
    assert!(
        err.message.contains("internal compiler error") && err.message.contains(PANICS_AT_TIER_1),
        "{}",
        err.message
    );
    assert!(tier1.kernel(func, &key).is_err(), "and stays one");

    // Tiered: tier 0 compiles; the worker's compile fails instead of killing it.
    let mut tiered = Jit::tiered(program).unwrap();
    let tier0 = tiered.kernel(func, &key).expect("tier 0");
    let watch = tiered.tier_up_watch().expect("a tiered JIT has a worker");
    assert!(
        !watch.wait(std::time::Duration::from_secs(120)),
        "the failed compile is no longer pending"
    );
    assert_eq!(watch.activity(), TierUpActivity::Idle);
    assert!(tiered.tier_up_kernel(func, &key).is_none());
    assert_eq!(tiered.kernel(func, &key).unwrap().entry as usize, tier0.entry as usize);
}
