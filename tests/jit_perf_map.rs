//! Kernels are named for profilers (src/jit/mod.rs `declare_kernel`): with `PERF_BUILDID_DIR`
//! set, cranelift-jit writes `/tmp/perf-<pid>.map`, and `perf report` shows each kernel as
//! `pf_<primitive>_t<tier>_<n>`: the root kernel of a batch and its callees alike, tier 0 and
//! tier 1 told apart, and a tier-0 kernel's outlined pixel loops as `<kernel>_pixels`. One test in its own binary: it sets an environment variable for the
//! whole process.

mod support;

use primflow::abi::VariantKey;
use primflow::jit::{Jit, Tier};

#[test]
fn perf_map_names_each_kernel_by_primitive_and_tier() {
    // Set before any JIT module exists, in a process that runs only this test.
    std::env::set_var("PERF_BUILDID_DIR", std::env::temp_dir());
    let map = std::path::PathBuf::from(format!("/tmp/perf-{}.map", std::process::id()));
    let _ = std::fs::remove_file(&map);

    let program = support::library();
    let polygon = program.find("polygon").unwrap();
    let key = VariantKey::default();
    for tier in [Tier::Fast, Tier::Optimised] {
        let mut jit = Jit::at_tier(program.clone(), tier).unwrap();
        jit.kernel(polygon, &key).unwrap();
    }

    let text = std::fs::read_to_string(&map).expect("cranelift-jit wrote no perf map");
    let names: Vec<&str> = text.lines().filter_map(|l| l.split_whitespace().nth(2)).collect();
    // polygon's batch is polygon and the screen_triangle it calls, at each tier.
    for prefix in [
        "pf_polygon_t0_",
        "pf_screen_triangle_t0_",
        "pf_polygon_t1_",
        "pf_screen_triangle_t1_",
    ] {
        assert_eq!(
            names
                .iter()
                .filter(|n| n.starts_with(prefix) && !n.ends_with("_pixels"))
                .count(),
            1,
            "{prefix} in {names:?}"
        );
    }
    // Tier 0 compiles screen_triangle's pixel loops as a function of their own, named after
    // its kernel (polygon has no pixel loops; tier 1 keeps one function).
    let triangle = names
        .iter()
        .find(|n| n.starts_with("pf_screen_triangle_t0_") && !n.ends_with("_pixels"))
        .unwrap();
    let pixels: Vec<_> = names.iter().filter(|n| n.ends_with("_pixels")).collect();
    assert_eq!(pixels, [&format!("{triangle}_pixels")], "{names:?}");
    let _ = std::fs::remove_file(&map);
}
