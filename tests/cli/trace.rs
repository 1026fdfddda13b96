//! `primflow trace SCENE --pixel X,Y` on two overlapping triangles (the nearer one drawn
//! first writes Z, the farther one returns at its depth test), a pixel no instance covers,
//! bad pixels; and the evaluator's observer it is built on (`ir::eval::observe`): what it
//! reports for a pixel that returns and one that writes, and that watching changes nothing.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use crate::support::cli;

use primflow::abi::{ArgLayout, ParamSlot, VariantKey};
use primflow::diag::{Diagnostics, SourceMap};
use primflow::ir::eval::{self, Budget, Evaluator, Event, Observer};
use primflow::jit::Jit;
use primflow::runtime::Renderer;

/// Red nearer (z 0.75) drawn first, blue farther (z 0.25) drawn second; pixel (20, 6) is
/// in both, (31, 23) in neither.
const TWO: &str = "\
image 32 24
material Cs 1 0 0
begin screen_triangle
rast_param screen_vertex 4 4 0.75 1  28 4 0.75 1  28 20 0.75 1
end
material Cs 0 0 1
begin screen_triangle
rast_param screen_vertex 2 2 0.25 1  30 2 0.25 1  2 22 0.25 1
end
";

fn scene_file(name: &str, text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("primflow-trace-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// The rendered frame's raw depth at (x, y), rendered here without the trace.
fn rendered_depth(text: &str, x: u32, y: u32) -> u32 {
    let program = crate::support::library();
    let mut sources = SourceMap::new();
    let file = sources.add("two.scene", text);
    let mut r = Renderer::new(program.clone());
    let mut diags = Diagnostics::new();
    primflow::scene::load_into(&sources, file, &mut r, &mut diags);
    assert!(!diags.has_errors(), "{}", diags.render(&sources));
    let mut jit = Jit::new(program).unwrap();
    r.render(&mut jit).frame.depth_at(x, y).unwrap()
}

/// `line:col` of the `return` of the depth test in the library's screen_triangle.
fn depth_test_return() -> String {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/prims/screen_triangle.prim")).unwrap();
    let (n, line) = text
        .lines()
        .enumerate()
        .find(|(_, l)| l.contains("if (triangle_z < Z) return;"))
        .expect("the depth test");
    format!("screen_triangle.prim:{}:{}", n + 1, line.find("return").unwrap() + 1)
}

#[test]
fn trace_shows_the_nearer_triangle_writing_z_and_the_farther_returning_at_its_depth_test() {
    let scene = scene_file("two.scene", TWO);
    let (code, out, err) = cli(&["trace", scene.to_str().unwrap(), "--pixel", "20,6"]);
    assert_eq!(code, 0, "{err}");
    let at = |s: &str| out.find(s).unwrap_or_else(|| panic!("no `{s}` in:\n{out}"));
    let first = at("\ninstance 0: screen_triangle (scene ");
    let second = at("\ninstance 1: screen_triangle (scene ");
    assert!(first < second, "draw order");
    assert!(out.contains("two.scene:3:1, object 1, its instance 1 of 1)"), "{out}");
    assert!(out.contains("two.scene:7:1, object 2, its instance 1 of 1)"), "{out}");
    let (a, b) = (&out[first..second], &out[second..]);
    assert!(a.contains("  bound: x 3.9375 .. 28.0625, y 3.9375 .. 20.0625\n"), "{a}");
    // The statements that ran, with the values the pixel's lane got.
    assert!(a.contains("pixel part, for this pixel:"), "{a}");
    assert!(
        a.contains("  float z = za * X + zb * Y + zc;\n        z = 0.75\n"),
        "{a}"
    );
    assert!(
        a.contains("  retired: finished: the pixel part ran to its end\n"),
        "{a}"
    );
    assert!(
        a.contains("  wrote Z: 0 (raw 0x00000000) -> 0.75 (raw 0xc0000000)\n"),
        "{a}"
    );
    assert!(a.contains("  wrote Cs: 1 0 0\n"), "{a}");
    // The farther one: its depth test is true, and it returns there.
    let ret = depth_test_return();
    assert!(b.contains("        z = 0.25\n"), "{b}");
    assert!(
        b.contains("  if (triangle_z < Z) return;\n        -> true: then\n"),
        "{b}"
    );
    assert!(b.contains("  retired: return at "), "{b}");
    assert!(
        b.contains(&format!("{ret}: the pixel's run ends (outside or hidden)")),
        "{b}"
    );
    assert!(b.contains("  wrote Z: nothing\n"), "{b}");
    assert!(!b.contains("wrote Cs"), "{b}");
    // The Z it reports is the rendered depth buffer's.
    assert_eq!(rendered_depth(TWO, 20, 6), 0xc000_0000);
    assert!(
        out.contains(
            "agrees with the rendered frame: depth, Cs at (20, 6) equal bit for bit (last Z written by instance 0; Z = 0.75 (raw 0xc0000000))"
        ),
        "{out}"
    );
}

#[test]
fn trace_of_a_pixel_no_instance_covers_says_so() {
    let scene = scene_file("none.scene", TWO);
    let (code, out, err) = cli(&["trace", scene.to_str().unwrap(), "--pixel", "31,23"]);
    assert_eq!(code, 0, "{err}");
    assert!(!out.contains("\ninstance "), "{out}");
    assert!(
        out.contains("no instance covers pixel (31, 23): none of the 2 ran its pixel code there"),
        "{out}"
    );
    assert!(
        out.contains("agrees with the rendered frame: depth, Cs at (31, 23)"),
        "{out}"
    );
}

#[test]
fn trace_refuses_a_pixel_outside_the_image_or_not_a_pixel() {
    let scene = scene_file("bad.scene", TWO);
    let s = scene.to_str().unwrap();
    let (code, out, err) = cli(&["trace", s, "--pixel", "32,2"]);
    assert_eq!((code, out.as_str()), (1, ""));
    assert_eq!(
        err.trim_end(),
        "error: pixel (32, 2) is outside the 32x24 image (x in 0..=31, y in 0..=23)"
    );
    for bad in ["3x", "1,2,3", "1,-2", "4"] {
        let (code, _, err) = cli(&["trace", s, "--pixel", bad]);
        assert_eq!(code, 2, "{bad}");
        assert!(
            err.contains(&format!("`{bad}` is not a pixel: expected X,Y")),
            "{bad}: {err}"
        );
    }
}

/// Events of one pixel, as text.
#[derive(Clone, Default)]
struct Log(Arc<Mutex<Vec<String>>>);

impl Observer for Log {
    fn event(&mut self, e: Event<'_>) {
        let line = match e {
            Event::Assign {
                func,
                local,
                words,
                varying,
                ..
            } => format!(
                "{} = {}{}",
                func.locals[local.0 as usize].name,
                f32::from_bits(words[0] as u32),
                if varying { "" } else { " uniform" }
            ),
            Event::Branch { taken } => format!("branch {taken}"),
            Event::Return { .. } => "return".into(),
            Event::PixelStart => "pixel".into(),
            Event::PixelEnd { alive } => format!("end alive={alive}"),
            Event::Depth { before, after } => format!("depth {before} -> {after}"),
            _ => return,
        };
        self.0.lock().unwrap().push(line);
    }
}

const WATCHED: &str = "
primitive watched(float s; varying float X, Y; inout varying float Z)
{
    bound(0, 0, 8, 4);
    float k = s * 2;
    float v = X * k;
    if (X > 4)
        return;
    Z = v / 64;
}
";

#[test]
fn the_observer_reports_the_watched_lane_only_and_changes_nothing() {
    let mut sources = SourceMap::new();
    let file = sources.add("watched.prim", WATCHED);
    let mut diags = Diagnostics::new();
    let program = primflow::compile(&sources, &[file], &mut diags).expect("checks");
    let func = program.find("watched").unwrap();
    let key = VariantKey::default();
    let layout = ArgLayout::new(&program, func, &key);
    let mut args = vec![0u32; layout.words(1)];
    args[0] = 1;
    let ParamSlot::Fixed { offset, .. } = layout.params[0] else {
        panic!("s is fixed")
    };
    args[offset as usize] = 1.5f32.to_bits();
    let evaluator = Evaluator::new(&program, true);
    let run = |pixel: Option<(i32, i32)>| {
        let mut tile = eval::Tile::new(0, 0, 8, 4, 0, 8, 4);
        let log = Log::default();
        let out = match pixel {
            Some(p) => evaluator.run_observed(func, &key, &args, &mut tile, Budget::default(), p, &mut log.clone()),
            None => evaluator.run(func, &key, &args, &mut tile, Budget::default()),
        }
        .unwrap();
        let lines = log.0.lock().unwrap().clone();
        (tile, out, lines)
    };
    let (plain, plain_out, none) = run(None);
    assert!(none.is_empty());
    // (2, 1): X = 2.5, v = 7.5, Z = 7.5 / 64 written.
    let (tile, out, seen) = run(Some((2, 1)));
    assert_eq!((&tile, &out), (&plain, &plain_out));
    let z = (7.5f64 / 64.0 * 4294967296.0) as u32;
    assert_eq!(
        seen,
        [
            "k = 3 uniform",
            "pixel",
            "v = 7.5",
            "branch false",
            "Z = 0.1171875",
            "end alive=true",
            &format!("depth 0 -> {z}"),
        ]
    );
    // (6, 1): the lane returns; nothing is written there.
    let (tile, _, seen) = run(Some((6, 1)));
    assert_eq!(tile, plain);
    assert_eq!(
        seen,
        [
            "k = 3 uniform",
            "pixel",
            "v = 19.5",
            "branch true",
            "return",
            "end alive=false"
        ]
    );
    // Outside the bound's rows: the setup only.
    let (_, _, seen) = run(Some((2, 5)));
    assert_eq!(seen, ["k = 3 uniform"]);
}

/// A quad drawn as a fan of two screen triangles called by `polygon`.
const QUAD: &str = "\
image 24 16
material Cs 0.125 0.25 0.5
begin polygon
vertex 4 4 0.5
vertex 20 4 0.5
vertex 20 12 0.5
vertex 4 12 0.5
end
";

#[test]
fn trace_of_a_primitive_that_calls_others_says_where_each_call_ended() {
    let scene = scene_file("quad.scene", QUAD);
    let (code, out, err) = cli(&["trace", scene.to_str().unwrap(), "--pixel", "10,10"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("\ninstance 0: polygon (scene "), "{out}");
    assert_eq!(
        out.matches("\n    call of screen_triangle (depth 1), its setup:\n")
            .count(),
        2,
        "{out}"
    );
    // The first triangle leaves the pixel out at an edge, the second draws it.
    let first = out.find("\n    retired: return at ").expect(&out);
    let second = out
        .find("\n    retired: finished: the pixel part ran to its end\n")
        .expect(&out);
    assert!(first < second, "{out}");
    assert!(out[first..].contains("screen_triangle.prim:"), "{out}");
    // The polygon's own run ends in its setup once it has made its calls.
    let own = out.find("\n  retired: return at ").expect(&out);
    assert!(own > second, "{out}");
    assert!(
        out[own..].starts_with("\n  retired: return at prims/polygon.prim:"),
        "{out}"
    );
    assert!(
        out[own..].contains(" in setup: no pixel of this kernel runs\n"),
        "{out}"
    );
    assert!(
        out.contains("\n  wrote Z: 0 (raw 0x00000000) -> 0.5 (raw 0x80000000)\n"),
        "{out}"
    );
    assert!(out.contains("\n  wrote Cs: 0.125 0.25 0.5\n"), "{out}");
    assert!(
        out.contains("\nagrees with the rendered frame: depth, Cs at (10, 10)"),
        "{out}"
    );
}

/// A scene with `samples 4`: the trace says it runs one sample at the pixel centre and
/// agrees with that frame; `render --samples` refuses a count outside the allowed set and
/// renders an antialiased image otherwise: pixel (10, 8), whose centre is just below the red
/// triangle's slanted edge (y = 4 + (x - 4) 2/3), is the blue behind it at 1 sample, and at 4
/// samples has two samples above the edge (at (10.375, 8.125) and (10.875, 8.375)) and two
/// below, so half red, half blue.
#[test]
fn trace_runs_one_sample_and_render_takes_samples() {
    let text = format!("samples 4\n{TWO}");
    let scene = scene_file("aa.scene", &text);
    let s = scene.to_str().unwrap();
    let (code, out, err) = cli(&["trace", s, "--pixel", "20,6"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.starts_with(
            "note: the scene's `samples 4` is ignored: the trace runs at the pixel centre, one sample per pixel\n"
        ),
        "{out}"
    );
    assert!(
        out.contains("agrees with the rendered frame: depth, Cs at (20, 6) equal bit for bit"),
        "{out}"
    );
    let refused = scene.with_file_name("refused.png");
    let (code, _, err) = cli(&["render", s, "-o", refused.to_str().unwrap(), "--samples", "3"]);
    assert_eq!(code, 1);
    assert!(
        err.contains("3 samples per pixel is not supported: use 1, 2, 4, 8 or 16"),
        "{err}"
    );
    let dir = scene.parent().unwrap();
    let png = |n: &str| dir.join(format!("aa{n}.png"));
    for n in ["1", "4"] {
        let (code, _, err) = cli(&["render", s, "-o", png(n).to_str().unwrap(), "--samples", n]);
        assert_eq!(code, 0, "{err}");
    }
    let pixel = |n: &str| image::open(png(n)).unwrap().to_rgb8().get_pixel(10, 8).0;
    assert_eq!(pixel("1"), [0, 0, 255]);
    assert_eq!(pixel("4"), [128, 0, 128]);
}
