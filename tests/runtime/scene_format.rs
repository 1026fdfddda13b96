//! The scene format: parsing, error locations, calls made on the renderer, and a property
//! test that mutated scenes never panic the reader or the renderer.

use crate::support::kernels::*;
use crate::support::raw_depth;
use primflow::abi::BindingKind;
use primflow::diag::{Diagnostics, SourceMap};
use primflow::runtime::{Renderer, Value};
use primflow::scene::{self, CommandKind};
use proptest::prelude::*;

/// Parse and apply `text` against the test program; returns the renderer and diagnostics
/// as `code@line:col`.
fn load(text: &str) -> (Renderer, Vec<String>, SourceMap, Diagnostics) {
    let mut sources = SourceMap::new();
    let program = program(&mut sources);
    let file = sources.add("test.scene", text);
    let mut r = Renderer::new(program);
    let mut diags = Diagnostics::new();
    scene::load_into(&sources, file, &mut r, &mut diags);
    let codes = diags.codes_at(&sources);
    (r, codes, sources, diags)
}

const RECTS: &str = "\
# two rects, the second nearer
image 32 16
tile 8
background 0 0 0.5
material Cs 0 0 0
begin rect
rast_param rect 0 0 20 16
rast_param depth 0.25
rast_param color 1 0 0
end
begin rect   # nearer
rast_param rect 10 0 32 16
rast_param depth 0.75
rast_param color 0 1 0
end
";

#[test]
fn a_scene_of_rects_renders() {
    let (r, codes, _s, _d) = load(RECTS);
    assert!(codes.is_empty(), "{codes:?}");
    assert_eq!((r.options.width, r.options.height, r.options.tile_size), (32, 16, 8));
    let mut kernels = TestKernels::new(r.program().clone());
    let out = r.render(&mut kernels);
    let f = &out.frame;
    assert_eq!(f.color_at(5, 5), [1.0, 0.0, 0.0]);
    assert_eq!(f.color_at(15, 5), [0.0, 1.0, 0.0]);
    assert_eq!(f.color_at(25, 5), [0.0, 1.0, 0.0]);
    assert_eq!(f.depth_at(5, 5), Some(raw_depth(f64::from(0.25f32))));
}

#[test]
fn errors_name_line_and_column_and_reading_goes_on() {
    let text = "\
image 32 x
imgae 3 3
background 1 2
vertex 1 2 3
begin nosuch
rast_param whatever 1
end
end
begin rect
rast_param rect 1 2 3
rast_param nosuch 1
rast_param depth 1 2
vertex 1 2
material_interp Cs cyl radius=2
material_interp Cs cyl 3
begin rect
";
    let (r, codes, sources, diags) = load(text);
    // Syntax errors first (the parse step), then the calls' errors in line order.
    let expected = [
        "E0603@1:10",  // bad number
        "E0601@2:1",   // unknown command (with a suggestion)
        "E0602@3:12",  // wrong arity: the arguments underlined
        "E0602@13:8",  // vertex with 2 numbers
        "E0604@15:24", // a bare number before any name=value
        "E0704@4:1",   // vertex outside begin/end
        "E0701@5:7",   // unknown primitive: its name underlined (its block is skipped quietly)
        "E0704@8:1",   // end without begin
        "E0703@10:17", // rect takes 4 components: the values underlined
        "E0702@11:12", // unknown parameter
        "E0703@12:18", // depth takes 1
        "E0707@14:24", // unknown interpolator argument
        "E0705@16:1",  // begin inside begin
        "E0605@9:1",   // never closed
    ];
    assert_eq!(codes, expected);
    assert!(r.instances().is_empty());
    let rendered = diags.render(&sources);
    assert!(rendered.contains("test.scene:5:7"), "{rendered}");
    assert!(rendered.contains("did you mean `image`?"), "{rendered}");
}

#[test]
fn material_interp_arguments_and_vertex_w() {
    let text = "\
material_interp uv cyl cylinder_start=0.5 cylinder_end= 2
material uv 0 0
material_interp Cs linear
material Cs 1 1 1
begin tri
rast_param scale 2
vertex 1 2 0.5
vertex 1 2 0.5 2
vertex 0 0 0
end
";
    let (r, codes, _s, _d) = load(text);
    assert!(codes.is_empty(), "{codes:?}");
    let inst = &r.instances()[0];
    assert_eq!(inst.key.bindings[0].kind, BindingKind::Shared("cyl".into()));
    assert_eq!(inst.key.bindings[1].kind, BindingKind::Kind("linear".into()));
    let layout = primflow::abi::ArgLayout::new(r.program(), inst.func, &inst.key);
    let o = layout.binding_data[0].unwrap() as usize;
    assert_eq!(floats(&inst.args[o..o + 2]), vec![0.5, 2.0]);
    let base = layout.fixed_words as usize;
    assert_eq!(
        floats(&inst.args[base..base + 8]),
        vec![1.0, 2.0, 0.5, 1.0, 1.0, 2.0, 0.5, 2.0]
    );
}

#[test]
fn parsed_commands_keep_their_values() {
    let mut sources = SourceMap::new();
    let file = sources.add(
        "p.scene",
        "prims extra\nmaterial Cs 1 0.5 nan\ntransform 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\n",
    );
    let mut diags = Diagnostics::new();
    let s = scene::parse(&sources, file, &mut diags);
    assert!(diags.items.is_empty());
    assert_eq!(
        s.prim_dirs(std::path::Path::new("/scenes")),
        vec![std::path::PathBuf::from("/scenes/extra")]
    );
    match &s.commands[1].kind {
        CommandKind::Material { name, value } => {
            assert_eq!(name, "Cs");
            assert_eq!(&value.0[..2], &[1.0, 0.5]);
            assert!(value.0[2].is_nan());
        }
        other => panic!("{other:?}"),
    }
    let _ = Value::default();
}

/// A token-level mutation of a scene.
#[derive(Clone, Debug)]
enum Mutation {
    Delete(usize),
    Insert(usize, String),
    Garbage(usize, Vec<u8>),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let token = prop_oneof![
        Just("begin".to_string()),
        Just("end".to_string()),
        Just("rect".to_string()),
        Just("vertex".to_string()),
        Just("material".to_string()),
        Just("rast_param".to_string()),
        Just("image".to_string()),
        Just("tile".to_string()),
        Just("Cs".to_string()),
        Just("\n".to_string()),
        Just("nan".to_string()),
        Just("-inf".to_string()),
        Just("1e38".to_string()),
        Just("0".to_string()),
        Just("=".to_string()),
        Just("#".to_string()),
        "-?[0-9]{1,3}(\\.[0-9])?",
    ];
    prop_oneof![
        (0usize..200).prop_map(Mutation::Delete),
        ((0usize..200), token).prop_map(|(i, t)| Mutation::Insert(i, t)),
        ((0usize..400), proptest::collection::vec(any::<u8>(), 1..4)).prop_map(|(i, b)| Mutation::Garbage(i, b)),
    ]
}

fn mutate(text: &str, mutations: &[Mutation]) -> String {
    let mut tokens: Vec<String> = text.split_inclusive(['\n', ' ']).map(String::from).collect();
    for m in mutations {
        match m {
            Mutation::Delete(i) if !tokens.is_empty() => {
                let i = i % tokens.len();
                tokens.remove(i);
            }
            Mutation::Insert(i, t) => {
                let i = i % (tokens.len() + 1);
                tokens.insert(i, format!("{t} "));
            }
            Mutation::Garbage(i, bytes) => {
                let mut s: Vec<u8> = tokens.concat().into_bytes();
                let i = i % (s.len() + 1);
                s.splice(i..i, bytes.iter().copied());
                tokens = vec![String::from_utf8_lossy(&s).into_owned()];
            }
            _ => {}
        }
    }
    tokens.concat()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]
    #[test]
    fn mutated_scenes_never_panic(mutations in proptest::collection::vec(mutation(), 1..8)) {
        let text = mutate(RECTS, &mutations);
        let (mut r, _codes, sources, diags) = load(&text);
        // Keep the frame tiny whatever the mutated `image` line said.
        r.options.width = r.options.width.min(24);
        r.options.height = r.options.height.min(24);
        let mut kernels = TestKernels::new(r.program().clone());
        let out = r.render(&mut kernels);
        prop_assert_eq!(out.frame.depth_values().len(), (r.options.width * r.options.height) as usize);
        // Every diagnostic renders (spans inside the text).
        let _ = diags.render(&sources);
    }
}

#[test]
fn camera_lines_transform_the_points_that_follow() {
    let text = "\
image 200 100
ortho -1 1 -1 1 1 3
begin tri
rast_param scale 1
vertex -1 1 -1
vertex 1 -1 -3
vertex 0 0 -2
end
perspective 90 1 10
begin tri
rast_param scale 1
vertex 0 0 -10
end
";
    let (r, codes, _s, _d) = load(text);
    assert!(codes.is_empty(), "{codes:?}");
    let device = |inst: &primflow::runtime::Instance, i: usize| {
        let layout = primflow::abi::ArgLayout::new(r.program(), inst.func, &inst.key);
        let base = layout.fixed_words as usize + 4 * i;
        let p = floats(&inst.args[base..base + 4]);
        [p[0] / p[3], p[1] / p[3], p[2] / p[3]]
    };
    let ortho = &r.instances()[0];
    assert_eq!(device(ortho, 0), [0.0, 0.0, 1.0], "top-left corner, near plane");
    assert_eq!(device(ortho, 1), [200.0, 100.0, 0.0], "bottom-right corner, far plane");
    assert_eq!(device(ortho, 2), [100.0, 50.0, 0.5]);
    let far_centre = device(&r.instances()[1], 0);
    assert!((far_centre[0] - 100.0).abs() < 1e-4 && (far_centre[1] - 50.0).abs() < 1e-4);
    assert!(far_centre[2].abs() < 1e-6, "the far plane is depth 0: {far_centre:?}");
}
