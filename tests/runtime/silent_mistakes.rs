//! Primitives that check and render but do not do what they look like they do: the checker's
//! W0003 (never writes `Z`), W0004 (no `bound`), W0005 (an arm that stores nothing) and
//! W0006 (a constant that saturates converting to fixed point), the renderer's W0802 (a
//! parameter the primitive leaves unwritten) and W0803 (what a missing bound cost), each at
//! its place in the source, and the pixels that show what the warning says.

use std::sync::Arc;

use primflow::diag::{Diagnostics, SourceMap};
use primflow::ir::Program;
use primflow::jit::Jit;
use primflow::runtime::{Registry, RenderOutput, Renderer, Value};

const SOURCE: &str = r#"
primitive fill(float rect[4]; float depth; interpolation_data interp_data[];
               varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    if (X < rect[0] || X > rect[2] || Y < rect[1] || Y > rect[3] || depth < Z)
        return;
    Z = depth;
    interpolation {
        linear:
            interpolator_return(interp_data[0]);
        default:
            interpolator_return;
    }
}

primitive forgetful(float rect[4]; float depth; interpolation_data interp_data[];
                    varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    if (X < rect[0] || X > rect[2] || Y < rect[1] || Y > rect[3] || depth < Z)
        return;
    Z = depth;
    interpolation {
        linear:
            Z = depth;
        default:
            interpolator_return;
    }
}

primitive shadow(float rect[4]; interpolation_data interp_data[];
                 varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    if (X < rect[0] || X > rect[2] || Y < rect[1] || Y > rect[3])
        return;
    interpolation {
        linear:
            interpolator_return(interp_data[0]);
    }
}

primitive loose(float cx, cy, r; varying float X, Y; inout varying fixed<32,32> Z)
{
    if ((X - cx) * (X - cx) + (Y - cy) * (Y - cy) > r * r)
        return;
    Z = 0.5;
}

primitive halving(varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(0, 0, 8, 1);
    fixed<8,4> d = X;
    Z = d / 16;
}
"#;

/// `code@line:col` of the first `text` at or after the line declaring `primitive`.
fn at(code: &str, primitive: &str, text: &str) -> String {
    let lines: Vec<&str> = SOURCE.lines().collect();
    let start = lines
        .iter()
        .position(|l| l.starts_with(&format!("primitive {primitive}(")))
        .unwrap();
    let (n, line) = lines
        .iter()
        .enumerate()
        .skip(start)
        .find(|(_, l)| l.contains(text))
        .unwrap();
    format!("{code}@{}:{}", n + 1, line.find(text).unwrap() + 1)
}

/// The library and `SOURCE`, with the checker's diagnostics.
fn compile(sources: &mut SourceMap) -> (Arc<Program>, Diagnostics) {
    let mut diags = Diagnostics::new();
    let (mut files, _) = Registry::load_sources(sources, &[], &[], &mut diags);
    files.push(sources.add("mistakes.prim", SOURCE));
    let registry = Registry::compile(sources, files, &mut diags);
    assert!(!diags.has_errors(), "{}", diags.render(sources));
    (registry.expect("compiled").program, diags)
}

/// One instance of `prim` over `rect` (one sequence point, carrying the current `Cs`).
fn draw(r: &mut Renderer, prim: &str, rect: [f32; 4], depth: Option<f32>) {
    r.begin(prim).unwrap();
    r.rast_param("rect", &Value(rect.to_vec())).unwrap();
    if let Some(d) = depth {
        r.rast_param("depth", &Value(vec![d])).unwrap();
    }
    r.sequence_point().unwrap();
    r.end().unwrap();
}

const RED: [f32; 3] = [1.0, 0.0, 0.0];
const GREEN: [f32; 3] = [0.0, 1.0, 0.0];

/// An 8x8 frame: `fill` in red over `fill_rect` at depth 0.25, then `second` in green over
/// the whole frame at depth 0.5 (`Cs` linear).
fn render_over_fill(program: Arc<Program>, fill_rect: [f32; 4], second: &str, depth: Option<f32>) -> RenderOutput {
    let mut r = Renderer::new(program);
    r.set_image_size(8, 8).unwrap();
    r.material("Cs", &Value(RED.to_vec())).unwrap();
    r.material_interp("Cs", "linear", &[]).unwrap();
    draw(&mut r, "fill", fill_rect, Some(0.25));
    r.material("Cs", &Value(GREEN.to_vec())).unwrap();
    draw(&mut r, second, [0.0, 0.0, 8.0, 8.0], depth);
    let mut jit = Jit::new(r.program().clone()).unwrap();
    r.render(&mut jit)
}

#[test]
fn check_warns_at_the_arm_that_stores_nothing_and_the_primitive_that_draws_nothing() {
    let mut sources = SourceMap::new();
    let (_, diags) = compile(&mut sources);
    // The library gives none.
    assert_eq!(
        diags.codes_at(&sources),
        [
            at("W0005", "forgetful", "linear:"),
            at("W0003", "shadow", "shadow"),
            at("W0004", "loose", "loose"),
            at("W0006", "halving", "16")
        ],
        "{}",
        diags.render(&sources)
    );
}

#[test]
fn w0802_names_the_parameter_an_arm_leaves_unwritten_and_locates_the_arm() {
    let mut sources = SourceMap::new();
    let (program, _) = compile(&mut sources);
    let out = render_over_fill(program, [0.0, 0.0, 8.0, 8.0], "forgetful", Some(0.5));
    assert_eq!(out.diags.codes_at(&sources), [at("W0802", "forgetful", "linear:")]);
    assert_eq!(
        out.diags.items[0].message,
        "`forgetful` never writes shading parameter `Cs`, bound to kind `linear`: its `linear:` arm stores no value; its pixels keep the value drawn there before"
    );
    // `forgetful` is nearer everywhere: its depth, `fill`'s colour.
    for (x, y) in [(0, 0), (5, 3), (7, 7)] {
        assert_eq!(out.frame.depth_f32_at(x, y), Some(0.5), "({x}, {y})");
        assert_eq!(out.frame.param_at("Cs", x, y), Some(RED.to_vec()), "({x}, {y})");
    }
}

#[test]
fn a_primitive_that_never_writes_z_draws_no_pixel_but_overwrites_shading_values() {
    let mut sources = SourceMap::new();
    let (program, _) = compile(&mut sources);
    // `fill` covers the right half only.
    let out = render_over_fill(program, [4.0, 0.0, 8.0, 8.0], "shadow", None);
    assert!(out.diags.items.is_empty(), "{}", out.diags.render(&sources));
    for y in 0..8 {
        for x in 0..4 {
            assert!(!out.frame.written(x, y), "({x}, {y}) is drawn");
        }
        for x in 4..8 {
            assert_eq!(out.frame.depth_f32_at(x, y), Some(0.25), "({x}, {y})");
            assert_eq!(out.frame.param_at("Cs", x, y), Some(GREEN.to_vec()), "({x}, {y})");
        }
    }
}

#[test]
fn a_constant_that_saturates_divides_by_the_largest_value_of_the_format() {
    let mut sources = SourceMap::new();
    let (program, diags) = compile(&mut sources);
    let w = diags.items.iter().find(|d| d.code == "W0006").expect("W0006");
    assert_eq!(w.message, "the constant 16 saturates to 7.9375 as fixed<8,4>");
    let mut r = Renderer::new(program);
    r.set_image_size(8, 1).unwrap();
    r.begin("halving").unwrap();
    r.end().unwrap();
    let mut jit = Jit::new(r.program().clone()).unwrap();
    let out = r.render(&mut jit);
    assert!(out.diags.items.is_empty(), "{}", out.diags.render(&sources));
    // X = 7.5 at the last pixel: 7.5 / 7.9375 = 0.9449 is 0.9375 in fixed<8,4>, where
    // 7.5 / 16 would be 0.46875.
    assert_eq!(out.frame.depth_f32_at(7, 0), Some(0.9375));
}

#[test]
fn w0803_counts_the_instances_without_bound_and_the_pixels_they_ran_over() {
    let mut sources = SourceMap::new();
    let (program, _) = compile(&mut sources);
    let mut r = Renderer::new(program);
    r.set_image_size(24, 8).unwrap();
    r.set_tile_size(8).unwrap();
    for cx in [4.0f32, 12.0, 20.0] {
        r.begin("loose").unwrap();
        r.rast_param("cx", &Value(vec![cx])).unwrap();
        r.rast_param("cy", &Value(vec![4.0])).unwrap();
        r.rast_param("r", &Value(vec![2.0])).unwrap();
        r.end().unwrap();
    }
    let mut jit = Jit::new(r.program().clone()).unwrap();
    let out = r.render(&mut jit);
    assert_eq!(out.diags.codes_at(&sources), [at("W0803", "loose", "loose")]);
    assert_eq!(
        out.diags.items[0].message,
        "`loose` has no `bound`: its 3 instance(s) ran their per-pixel code over 576 pixels, 192 each on average (the viewport has 192)"
    );
    // Each disc is drawn in its own tile all the same.
    let drawn: Vec<u32> = (0..24).filter(|&x| out.frame.written(x, 4)).collect();
    assert_eq!(drawn, [2, 3, 4, 5, 10, 11, 12, 13, 18, 19, 20, 21]);
}
