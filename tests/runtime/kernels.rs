//! Which kernels the renderer asks for: one per distinct (primitive, key) of the instances,
//! in first-use order, once per render, whatever order the instances come in (keys are
//! interned as instances are added, not compared or hashed per instance per frame).

use crate::support::kernels::*;
use primflow::abi::{BindingKind, VariantKey};
use primflow::diag::SourceMap;
use primflow::runtime::{Renderer, Value};

fn setup() -> (SourceMap, Renderer) {
    let mut sources = SourceMap::new();
    let mut r = Renderer::new(program(&mut sources));
    r.set_image_size(48, 16).unwrap();
    r.set_tile_size(16).unwrap();
    r.material("Cs", &[0.0, 0.0, 0.0].into()).unwrap();
    (sources, r)
}

/// Switch `Cs` between a constant and the shared `cyl` interpolator: two keys of `rect`.
fn use_cylinder(r: &mut Renderer, on: bool) {
    if on {
        let args = vec![("cylinder_end".to_string(), Value::from(2.0))];
        r.material_interp("Cs", "cyl", &args).unwrap();
    } else {
        r.material_interp("Cs", "constant", &[]).unwrap();
    }
}

fn kind_of(key: &VariantKey) -> BindingKind {
    key.bindings[0].kind.clone()
}

#[test]
fn instances_alternating_between_two_keys_get_their_own_kernels_once_each() {
    let (_s, mut r) = setup();
    // Six 8-pixel-wide rects side by side, keys alternating constant / cyl / constant ...
    for i in 0..6 {
        use_cylinder(&mut r, i % 2 == 1);
        let x = 8.0 * i as f32;
        let shade = (i + 1) as f32 / 8.0;
        rect(&mut r, [x, 0.0, x + 8.0, 16.0], 0.5, [shade, 0.0, 1.0 - shade]);
    }
    let keys: Vec<BindingKind> = r.instances().iter().map(|i| kind_of(&i.key)).collect();
    assert_eq!(keys[0], BindingKind::Constant);
    assert_eq!(keys[1], BindingKind::Shared("cyl".into()));
    assert_eq!(keys[2], keys[0]);

    let mut kernels = TestKernels::new(r.program().clone());
    let out = r.render(&mut kernels);
    assert!(out.diags.items.is_empty(), "{:?}", out.diags.items);
    // One request per distinct key, in first-use order.
    let asked: Vec<BindingKind> = kernels.requests.iter().map(|(_, k)| kind_of(k)).collect();
    assert_eq!(asked, vec![BindingKind::Constant, BindingKind::Shared("cyl".into())]);
    assert_eq!(out.stats.kernels_compiled, 2);
    assert_eq!(out.kernels.len(), 2);
    assert_eq!(out.kernels[0].key, "constant:3");
    assert_eq!(out.kernels[1].key, "cyl:3");
    // Every instance drew with its own kernel and arguments: each rect shows its colour.
    for i in 0..6u32 {
        let shade = (i + 1) as f32 / 8.0;
        for x in [8 * i, 8 * i + 7] {
            assert_eq!(
                out.frame.param_at("Cs", x, 9),
                Some(vec![shade, 0.0, 1.0 - shade]),
                "rect {i} at x = {x}"
            );
        }
    }
}

#[test]
fn every_render_asks_once_per_variant_and_count_writes_is_the_renderers() {
    let (_s, mut r) = setup();
    for i in 0..5 {
        use_cylinder(&mut r, i >= 2);
        rect(&mut r, [0.0, 0.0, 48.0, 16.0], 0.1 * (i + 1) as f32, [0.5; 3]);
    }
    let mut kernels = TestKernels::new(r.program().clone());
    let first = r.render(&mut kernels);
    let second = r.render(&mut kernels);
    assert_eq!(
        kernels.requests.len(),
        4,
        "two variants, asked again by the second render"
    );
    assert_eq!(kernels.requests[0], kernels.requests[2]);
    assert_eq!(kernels.requests[1], kernels.requests[3]);
    assert!(kernels.requests.iter().all(|(_, k)| !k.count_writes));
    assert_eq!(first.frame.depth_values(), second.frame.depth_values());

    r.options.count_writes = true;
    let mut counting = TestKernels::new(r.program().clone());
    let out = r.render(&mut counting);
    assert_eq!(counting.requests.len(), 2);
    assert!(counting.requests.iter().all(|(_, k)| k.count_writes));
    // All five rects cover every pixel: five depth writes each (nearer each time).
    assert_eq!(out.frame.write_count_at(0, 0), Some(5));
    assert_eq!(out.frame.write_count_at(47, 15), Some(5));
    assert_eq!(out.frame.depth_values(), first.frame.depth_values());
}

#[test]
fn a_key_that_comes_back_after_others_reuses_its_kernel() {
    let (_s, mut r) = setup();
    // constant, cyl x3, constant, then a third key (a new shading parameter), constant again
    // is no longer possible (every later key lists the new parameter): two rects with it.
    use_cylinder(&mut r, false);
    rect(&mut r, [0.0, 0.0, 8.0, 16.0], 0.5, [1.0, 0.0, 0.0]);
    use_cylinder(&mut r, true);
    for i in 1..4 {
        let x = 8.0 * i as f32;
        rect(&mut r, [x, 0.0, x + 8.0, 16.0], 0.5, [0.0, 1.0, 0.0]);
    }
    use_cylinder(&mut r, false);
    rect(&mut r, [32.0, 0.0, 40.0, 16.0], 0.5, [0.0, 0.0, 1.0]);
    r.material("extra", &[0.25].into()).unwrap();
    rect(&mut r, [40.0, 0.0, 44.0, 16.0], 0.5, [1.0, 1.0, 0.0]);
    rect(&mut r, [44.0, 0.0, 48.0, 16.0], 0.5, [0.0, 1.0, 1.0]);

    let mut kernels = TestKernels::new(r.program().clone());
    let out = r.render(&mut kernels);
    assert!(out.diags.items.is_empty(), "{:?}", out.diags.items);
    assert_eq!(kernels.requests.len(), 3, "{:?}", out.kernels);
    assert_eq!(out.kernels[2].key, "constant:3,constant:1");
    let cs = |x: u32| out.frame.param_at("Cs", x, 3).unwrap();
    assert_eq!(cs(4), vec![1.0, 0.0, 0.0]);
    assert_eq!(cs(20), vec![0.0, 1.0, 0.0]);
    assert_eq!(cs(36), vec![0.0, 0.0, 1.0]);
    assert_eq!(cs(42), vec![1.0, 1.0, 0.0]);
    assert_eq!(cs(46), vec![0.0, 1.0, 1.0]);
}
