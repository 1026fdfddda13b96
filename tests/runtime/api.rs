//! The primitive API: argument blocks laid out per `abi::ArgLayout`, value conversion,
//! sequence points, bindings, and the errors and warnings of bad calls.

use crate::support::kernels::*;
use glam::{Mat4, Vec3};
use primflow::abi::{ArgLayout, Binding, BindingKind, ParamSlot};
use primflow::diag::SourceMap;
use primflow::runtime::{Renderer, Target, Value};

fn renderer() -> Renderer {
    let mut sources = SourceMap::new();
    Renderer::new(program(&mut sources))
}

fn codes(issues: &[primflow::runtime::ApiIssue]) -> Vec<&'static str> {
    issues.iter().map(|i| i.code).collect()
}

#[test]
fn arg_block_of_linear_and_constant_bindings_follows_the_layout() {
    let mut r = renderer();
    r.set_transform(Mat4::from_translation(Vec3::new(100.0, 200.0, 0.0)));
    r.material_interp("Cs", "linear", &[]).unwrap();
    r.material("alpha", &0.25.into()).unwrap();
    r.material("Cs", &[1.0, 0.0, 0.0].into()).unwrap();
    r.begin("tri").unwrap();
    r.rast_param("scale", &1.5.into()).unwrap();
    r.vertex(1.0, 2.0, 0.5, 1.0).unwrap();
    r.material("Cs", &[0.0, 1.0, 0.0].into()).unwrap();
    r.vertex(3.0, 4.0, 0.5, 1.0).unwrap();
    r.material("Cs", &[0.0, 0.0, 1.0].into()).unwrap();
    r.material("alpha", &0.75.into()).unwrap();
    r.vertex(5.0, 6.0, 0.5, 1.0).unwrap();
    r.end().unwrap();
    assert!(r.take_warnings().is_empty());

    let inst = &r.instances()[0];
    // Bindings in first-`material` order: alpha (constant), then Cs (linear).
    assert_eq!(
        inst.key.bindings,
        vec![
            Binding {
                kind: BindingKind::Constant,
                components: 1
            },
            Binding {
                kind: BindingKind::Kind("linear".into()),
                components: 3
            },
        ]
    );
    let layout = ArgLayout::new(r.program(), inst.func, &inst.key);
    assert_eq!(inst.args.len(), layout.words(3));
    let a = &inst.args;
    assert_eq!(a[0], 3, "n_seq");
    assert_eq!(&a[1..5], &[0, 1, 2, 3], "plane table: alpha's plane, then Cs's three");
    // The constant takes its value current at `end`.
    assert_eq!(f32::from_bits(a[layout.binding_data[0].unwrap() as usize]), 0.75);
    assert_eq!(layout.binding_data[1], None);
    let ParamSlot::Fixed { offset, .. } = layout.params[3] else {
        panic!()
    };
    assert_eq!(a[offset as usize], 0x0001_8000, "fixed<32,16> 1.5");
    let ParamSlot::Fixed { offset, .. } = layout.params[4] else {
        panic!()
    };
    assert_eq!(a[offset as usize], 7, "int default");
    // vertex: per sequence point, transformed by device_from_object, w kept.
    let ParamSlot::Seq { seq_offset, words } = layout.params[0] else {
        panic!()
    };
    let base = layout.fixed_words as usize + 3 * seq_offset as usize;
    assert_eq!(words, 4);
    assert_eq!(
        floats(&a[base..base + 12]),
        vec![101.0, 202.0, 0.5, 1.0, 103.0, 204.0, 0.5, 1.0, 105.0, 206.0, 0.5, 1.0]
    );
    // interp_data[]: each sequence point's Cs (the only Kind binding).
    let ParamSlot::Seq { seq_offset, words } = layout.params[1] else {
        panic!()
    };
    assert_eq!(words, 3);
    let base = layout.fixed_words as usize + 3 * seq_offset as usize;
    assert_eq!(
        floats(&a[base..base + 9]),
        vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    );
    // corners[3]: the first three sequence points, at a fixed offset.
    let ParamSlot::Fixed { offset, words } = layout.params[2] else {
        panic!()
    };
    assert_eq!(words, 9);
    assert_eq!(
        floats(&a[offset as usize..offset as usize + 9]),
        vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    );
}

#[test]
fn sized_interp_data_with_too_few_sequence_points_is_zero_filled_with_a_warning() {
    let mut r = renderer();
    r.material_interp("Cs", "perspective_linear", &[]).unwrap();
    r.material("Cs", &[0.5, 0.5, 0.5].into()).unwrap();
    r.begin("tri").unwrap();
    r.rast_param("scale", &1.0.into()).unwrap();
    r.vertex(0.0, 0.0, 0.5, 1.0).unwrap();
    r.vertex(1.0, 0.0, 0.5, 1.0).unwrap();
    r.end().unwrap();
    let warnings = r.take_warnings();
    assert_eq!(codes(&warnings), vec!["W0701"]);
    assert!(warnings[0].message.contains("corners"), "{}", warnings[0].message);
    let inst = &r.instances()[0];
    let layout = ArgLayout::new(r.program(), inst.func, &inst.key);
    let ParamSlot::Fixed { offset, .. } = layout.params[2] else {
        panic!()
    };
    let o = offset as usize;
    assert_eq!(
        floats(&inst.args[o..o + 9]),
        vec![0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.0, 0.0, 0.0]
    );
}

#[test]
fn missing_parameters_take_defaults_or_zero_with_a_warning() {
    let mut r = renderer();
    r.begin("tri").unwrap();
    r.end().unwrap();
    let warnings = r.take_warnings();
    // scale has no default; vertex and interp_data have no sequence points (one warning).
    assert_eq!(codes(&warnings), vec!["W0701", "W0701"]);
    assert!(warnings[0].message.contains("`scale`"), "{}", warnings[0].message);
    assert!(
        warnings[1].message.contains("`vertex`, `interp_data`"),
        "{}",
        warnings[1].message
    );
    let inst = &r.instances()[0];
    assert_eq!(inst.args[0], 0, "n_seq");
    let layout = ArgLayout::new(r.program(), inst.func, &inst.key);
    assert_eq!(
        inst.args.len(),
        layout.words(0),
        "one zero element per per-seq parameter"
    );
}

#[test]
fn shared_interpolator_arguments_fill_binding_data_with_defaults() {
    let mut r = renderer();
    let args = vec![("cylinder_end".to_string(), Value::from(2.0))];
    r.material_interp("uv", "cyl", &args).unwrap();
    r.material("uv", &[0.0, 0.0].into()).unwrap();
    r.begin("rect").unwrap();
    r.rast_param("rect", &[0.0, 0.0, 1.0, 1.0].into()).unwrap();
    r.rast_param("color", &[0.0, 0.0, 0.0].into()).unwrap();
    r.end().unwrap();
    let inst = &r.instances()[0];
    assert_eq!(inst.key.bindings[0].kind, BindingKind::Shared("cyl".into()));
    let layout = ArgLayout::new(r.program(), inst.func, &inst.key);
    let o = layout.binding_data[0].unwrap() as usize;
    assert_eq!(floats(&inst.args[o..o + 2]), vec![0.0, 2.0]);

    let bad = vec![("radius".to_string(), Value::from(1.0))];
    let err = r.material_interp("uv", "cyl", &bad).unwrap_err();
    assert_eq!((err.code, err.target), ("E0707", Target::Arg(0)));
    let err = r.material_interp("uv", "linear", &args).unwrap_err();
    assert_eq!((err.code, err.target), ("E0707", Target::Arg(0)));
    let err = r.material_interp("uv", "rect", &[]).unwrap_err();
    assert_eq!(err.code, "E0707");
}

#[test]
fn space_matrices_are_written_for_primitives_that_use_them() {
    let mut r = renderer();
    let device_from_object = Mat4::from_scale(Vec3::new(2.0, 4.0, 1.0));
    r.set_transform(device_from_object);
    r.begin("spacey").unwrap();
    r.rast_param("k", &1.0.into()).unwrap();
    r.end().unwrap();
    let inst = &r.instances()[0];
    let layout = ArgLayout::new(r.program(), inst.func, &inst.key);
    let s = layout.spaces.unwrap() as usize;
    let m = floats(&inst.args[s..s + 96]);
    // device_from_object, row-major.
    assert_eq!(m[0], 2.0);
    assert_eq!(m[5], 4.0);
    assert_eq!(m[15], 1.0);
    // object_from_device (the 4th matrix) is its inverse.
    assert_eq!(m[48], 0.5);
    assert_eq!(m[48 + 5], 0.25);
}

#[test]
fn bad_calls_are_errors_naming_the_argument() {
    let mut r = renderer();
    let e = |res: Result<(), primflow::runtime::ApiIssue>| {
        let e = res.unwrap_err();
        (e.code, e.target)
    };
    assert_eq!(e(r.vertex(0.0, 0.0, 0.0, 1.0)), ("E0704", Target::Call));
    assert_eq!(e(r.end()), ("E0704", Target::Call));
    assert_eq!(e(r.rast_param("rect", &1.0.into())), ("E0704", Target::Call));
    assert_eq!(e(r.begin("nosuch")), ("E0701", Target::Name));
    // The unknown primitive's block swallows its calls quietly and is dropped at end.
    r.rast_param("whatever", &1.0.into()).unwrap();
    r.end().unwrap();
    assert!(r.instances().is_empty());
    assert_eq!(e(r.begin("cyl")), ("E0701", Target::Name));
    r.end().unwrap();

    r.begin("rect").unwrap();
    assert_eq!(e(r.begin("rect")), ("E0705", Target::Call));
    assert_eq!(e(r.rast_param("nosuch", &1.0.into())), ("E0702", Target::Name));
    assert_eq!(e(r.rast_param("rect", &[1.0, 2.0].into())), ("E0703", Target::Values));
    assert_eq!(e(r.rast_param("X", &1.0.into())), ("E0706", Target::Name));
    // No `vertex` parameter: a sequence point with a warning (once per primitive).
    r.vertex(0.0, 0.0, 0.0, 1.0).unwrap();
    r.vertex(0.0, 0.0, 0.0, 1.0).unwrap();
    assert_eq!(codes(&r.take_warnings()), vec!["W0703"]);
    r.end().unwrap();

    r.material("Cs", &[1.0, 1.0, 1.0].into()).unwrap();
    assert_eq!(e(r.material("Cs", &1.0.into())), ("E0703", Target::Values));
    assert_eq!(e(r.material("empty", &Value(vec![]))), ("E0703", Target::Values));
    assert_eq!(e(r.set_image_size(0, 10)), ("E0708", Target::Values));
    assert_eq!(e(r.set_tile_size(0)), ("E0708", Target::Values));
}

#[test]
fn interp_data_param_cannot_be_set_and_nan_values_pass_through() {
    let mut r = renderer();
    r.begin("tri").unwrap();
    let err = r.rast_param("interp_data", &1.0.into()).unwrap_err();
    assert_eq!((err.code, err.target), ("E0706", Target::Name));
    r.rast_param("scale", &f32::NAN.into()).unwrap();
    r.vertex(f32::NAN, f32::INFINITY, -0.0, 1.0).unwrap();
    r.end().unwrap();
    let inst = &r.instances()[0];
    let layout = ArgLayout::new(r.program(), inst.func, &inst.key);
    let ParamSlot::Fixed { offset, .. } = layout.params[3] else {
        panic!()
    };
    assert_eq!(inst.args[offset as usize], 0, "NaN to fixed is 0");
    let base = layout.fixed_words as usize;
    let v = floats(&inst.args[base..base + 4]);
    assert!(v[0].is_nan());
    assert_eq!(v[1], f32::INFINITY);
}
