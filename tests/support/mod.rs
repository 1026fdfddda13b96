//! The one support module every test binary includes (`#[path = "../support/mod.rs"]`):
//! the library, a renderer, screen triangles, an exact 64-bit integer reference rasterizer,
//! the depth conversion and the generator here; [`jit`] builds IR by hand and runs kernels
//! on a real tile context; [`kernels`] holds hand-written ABI kernels that drive the runtime
//! without the JIT.
#![allow(dead_code)]

pub mod jit;
pub mod kernels;

use std::sync::Arc;

use primflow::diag::{Diagnostics, SourceMap};
use primflow::ir::Program;
use primflow::jit::{Jit, JitOptions, Tier};
use primflow::runtime::{Frame, Registry, RenderOptions, Renderer, Value};

/// Start `command` with its stdout and stderr piped, and forward their lines to one channel
/// as they come (stderr's prefixed `err: `): a long-running command (`watch`, `serve`) read
/// line by line without blocking on either pipe.
pub fn spawn_with_lines(
    command: &mut std::process::Command,
) -> (std::process::Child, std::sync::mpsc::Receiver<String>) {
    use std::io::{BufRead, BufReader};
    use std::process::Stdio;
    let mut child = command.stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    let (tx, lines) = std::sync::mpsc::channel();
    let stdout = child.stdout.take().unwrap();
    let stderr = child.stderr.take().unwrap();
    let tx2 = tx.clone();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            let _ = tx2.send(format!("err: {line}"));
        }
    });
    (child, lines)
}

/// Run the command line in-process: (exit code, stdout, stderr).
pub fn cli(args: &[&str]) -> (i32, String, String) {
    let mut out = vec![];
    let mut err = vec![];
    let mut argv = vec!["primflow"];
    argv.extend_from_slice(args);
    let code = primflow::cli::run(argv, &mut out, &mut err);
    (code, String::from_utf8(out).unwrap(), String::from_utf8(err).unwrap())
}

/// The built-in primitive library, compiled (panics with the rendered diagnostics if not).
pub fn library() -> Arc<Program> {
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    match Registry::load(&mut sources, &[], &[], &mut diags) {
        Some(reg) => reg.program,
        None => panic!("library does not compile:\n{}", diags.render(&sources)),
    }
}

/// The built-in library plus the user primitive sources `(file name, text)`, compiled into
/// one program (panics with the rendered diagnostics if it does not compile). The sources
/// land in `sources`, so a test can render warnings against them.
pub fn library_with(sources: &mut SourceMap, user: &[(&str, &str)]) -> Arc<Program> {
    let mut diags = Diagnostics::new();
    let (mut files, _) = Registry::load_sources(sources, &[], &[], &mut diags);
    files.extend(user.iter().map(|&(name, text)| sources.add(name, text)));
    match Registry::compile(sources, files, &mut diags) {
        Some(reg) if !diags.has_errors() => reg.program,
        _ => panic!("user prims do not compile:\n{}", diags.render(sources)),
    }
}

/// Sixteen operands that tell exact float arithmetic from nearly exact: signed zeros,
/// subnormals, the smallest normal, the largest finite values, infinities and NaN.
pub fn special_floats() -> [f32; 16] {
    [
        0.0,
        -0.0,
        1.0,
        -7.0,
        123.456,
        f32::from_bits(1),
        -f32::from_bits(0x0000_0123),
        f32::MIN_POSITIVE,
        1e-40,
        f32::MAX,
        -3e38,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NAN,
        0.1,
        6e-39,
    ]
}

/// A JIT of each tier, named, for tests that render the same scene through both.
pub fn jits(program: &Arc<Program>) -> Vec<(&'static str, Jit)> {
    vec![
        ("tier 1", Jit::new(program.clone()).unwrap()),
        ("tier 0", Jit::at_tier(program.clone(), Tier::Fast).unwrap()),
    ]
}

/// Render `r` with a fresh JIT of every tier, with loop unrolling on and off, and assert no
/// diagnostics and the depth `expected(x, y)` at every pixel (`what` names the case in a
/// failure).
pub fn assert_depth_in_every_jit(r: &Renderer, what: &str, expected: impl Fn(u32, u32) -> u32) {
    for unroll_loops in [false, true] {
        for tier in [Tier::Fast, Tier::Optimised] {
            let mut jit = Jit::with_options(r.program().clone(), JitOptions { tier, unroll_loops }).unwrap();
            let out = r.render(&mut jit);
            assert!(out.diags.items.is_empty(), "{what}: {:?}", out.diags.items);
            for y in 0..out.frame.height {
                for x in 0..out.frame.width {
                    assert_eq!(
                        out.frame.depth_at(x, y),
                        Some(expected(x, y)),
                        "{what} unroll={unroll_loops} {tier:?} at ({x}, {y})"
                    );
                }
            }
        }
    }
}

/// The default render options at `width` x `height` in tiles of `tile_size` pixels.
pub fn render_options(width: u32, height: u32, tile_size: u32) -> RenderOptions {
    RenderOptions {
        width,
        height,
        tile_size,
        ..RenderOptions::default()
    }
}

pub fn renderer(program: &Arc<Program>, width: u32, height: u32, count_writes: bool) -> Renderer {
    let mut r = Renderer::new(program.clone());
    r.set_image_size(width, height).unwrap();
    r.options.count_writes = count_writes;
    r
}

/// Render with `threads` worker threads and a JIT of its own; asserts no errors or warnings.
pub fn render(r: &Renderer, threads: usize) -> Frame {
    let mut jit = Jit::new(r.program().clone()).unwrap();
    render_with(r, &mut jit, threads)
}

pub fn render_with(r: &Renderer, jit: &mut Jit, threads: usize) -> Frame {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    let out = pool.install(|| r.render(jit));
    assert!(out.diags.items.is_empty(), "render diagnostics: {:?}", out.diags.items);
    out.frame
}

/// Submit one `screen_triangle`: vertices (x, y, z, w) and, per shading parameter, its value
/// at each vertex.
pub fn screen_triangle(r: &mut Renderer, v: [[f32; 4]; 3], params: &[(&str, [Vec<f32>; 3])]) {
    r.begin("screen_triangle").unwrap();
    r.rast_param("screen_vertex", &Value(v.iter().flatten().copied().collect()))
        .unwrap();
    for i in 0..3 {
        for (name, values) in params {
            r.material(name, &Value(values[i].clone())).unwrap();
        }
        r.sequence_point().unwrap();
    }
    r.end().unwrap();
    assert!(r.take_warnings().is_empty());
}

/// Exact coverage of a triangle by pixel centres, with the top-left rule, in 64-bit integers
/// on the 1/16 pixel grid (vertices are rounded to it). Independent of the float code paths:
/// the reference for "zero differing pixels".
pub fn reference_coverage(v: [[f64; 2]; 3], width: u32, height: u32) -> Vec<bool> {
    let p: Vec<(i64, i64)> = v
        .iter()
        .map(|q| ((q[0] * 16.0).round() as i64, (q[1] * 16.0).round() as i64))
        .collect();
    let det = (p[1].0 - p[0].0) * (p[2].1 - p[0].1) - (p[2].0 - p[0].0) * (p[1].1 - p[0].1);
    let mut out = vec![false; (width * height) as usize];
    if det == 0 {
        return out;
    }
    let orient = det.signum();
    for py in 0..height as i64 {
        for px in 0..width as i64 {
            let (x, y) = (16 * px + 8, 16 * py + 8);
            let inside = (0..3).all(|i| {
                let j = (i + 1) % 3;
                let a = -orient * (p[j].1 - p[i].1);
                let b = orient * (p[j].0 - p[i].0);
                let top_left = a > 0 || (a == 0 && b < 0);
                let e = a * (x - p[i].0) + b * (y - p[i].1);
                e > 0 || (e == 0 && top_left)
            });
            out[(py * width as i64 + px) as usize] = inside;
        }
    }
    out
}

/// Screen-space barycentric coordinates of (x, y) in f64.
pub fn barycentric(v: [[f64; 2]; 3], x: f64, y: f64) -> [f64; 3] {
    let det = (v[1][0] - v[0][0]) * (v[2][1] - v[0][1]) - (v[2][0] - v[0][0]) * (v[1][1] - v[0][1]);
    let l1 = ((x - v[0][0]) * (v[2][1] - v[0][1]) - (v[2][0] - v[0][0]) * (y - v[0][1])) / det;
    let l2 = ((v[1][0] - v[0][0]) * (y - v[0][1]) - (x - v[0][0]) * (v[1][1] - v[0][1])) / det;
    [1.0 - l1 - l2, l1, l2]
}

/// The tests' deterministic generator is the workloads' (tests must not depend on a
/// seed-less RNG).
pub use primflow::workload::Lcg;

/// splitmix64: the clipper tests' generator (64-bit integers for bit patterns, and floats),
/// shared by the pipeline binary and the hard-case suite.
pub struct SplitMix(pub u64);
impl SplitMix {
    pub fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    pub fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
}

/// A value of `rng` on the 1/16 grid in [lo, hi).
pub fn grid(rng: &mut Lcg, lo: f64, hi: f64) -> f64 {
    (rng.range(lo, hi) * 16.0).floor() / 16.0
}

/// The control points of two 4 x 4 bicubic patches side by side sharing their curved middle
/// column (the same points along it; different interiors).
pub fn shared_column_patches() -> [Vec<[f64; 3]>; 2] {
    let shared = [(0.1, 0.0), (-0.3, 0.4), (0.4, -0.2), (0.0, 0.1)];
    let (mut left, mut right) = (vec![], vec![]);
    for (j, &(dx, dz)) in shared.iter().enumerate() {
        let y = -1.5 + j as f64;
        for i in 0..4 {
            let t = i as f64 / 3.0;
            let bump = if i == 1 || i == 2 { 0.6 * (j as f64 - 1.5) } else { 0.0 };
            left.push([-3.0 + (3.0 + dx) * t, y, -8.0 + dz * t + bump]);
            right.push([dx + (3.0 - dx) * t, y, -8.0 + dz * (1.0 - t) - 0.5 * bump]);
        }
    }
    [left, right]
}

/// Render `r` with tier 0, tier 1 and tier 1 with loops kept (not unrolled): frames
/// bit-identical, no diagnostics; the tier-0 frame.
pub fn all_tiers(program: &Arc<Program>, r: &Renderer, what: &str) -> Frame {
    let mut frames = vec![];
    for (tier, unroll_loops) in [(Tier::Fast, true), (Tier::Optimised, true), (Tier::Optimised, false)] {
        let mut jit = Jit::with_options(program.clone(), JitOptions { tier, unroll_loops }).unwrap();
        let out = r.render(&mut jit);
        assert!(out.diags.items.is_empty(), "{what}: {:?}", out.diags.items);
        frames.push(out.frame);
    }
    for f in &frames[1..] {
        assert!(primflow::workload::same_frame(&frames[0], f), "{what}: tiers differ");
    }
    frames.swap_remove(0)
}

/// A 24x16 frame in 16-pixel tiles with one instance of `prim` (a test primitive taking a
/// `rect` of the pixels it covers, here (2, 2)-(20, 12)) and the float parameters given.
pub fn rect_scene(program: &Arc<Program>, prim: &str, params: &[(&str, f32)]) -> Renderer {
    let mut r = Renderer::new(program.clone());
    r.set_image_size(24, 16).unwrap();
    r.set_tile_size(16).unwrap();
    r.begin(prim).unwrap();
    r.rast_param("rect", &Value(vec![2.0, 2.0, 20.0, 12.0])).unwrap();
    for (name, v) in params {
        r.rast_param(name, &Value(vec![*v])).unwrap();
    }
    r.end().unwrap();
    r
}

/// Render `r` at `tier`: the depth at (8, 5), inside [`rect_scene`]'s rectangle, and the
/// run-time diagnostics as `code@line:col`.
pub fn rect_depth_and_codes(
    program: &Arc<Program>,
    sources: &SourceMap,
    r: &Renderer,
    tier: Tier,
) -> (u32, Vec<String>) {
    let mut jit = Jit::at_tier(program.clone(), tier).unwrap();
    let out = r.render(&mut jit);
    assert!(!out.diags.has_errors(), "{:?}", out.diags.items);
    let mut codes = out.diags.codes_at(sources);
    codes.dedup();
    (out.frame.depth_at(8, 5).unwrap(), codes)
}

/// The built-in library with the sources it was read from (for scenes parsed against it).
pub fn library_and_sources() -> (SourceMap, Arc<Program>) {
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    let registry = Registry::load(&mut sources, &[], &[], &mut diags)
        .unwrap_or_else(|| panic!("library does not compile:\n{}", diags.render(&sources)));
    (sources, registry.program)
}

/// The surface in `source` linked, against `library`, as the `__shade` primitive of a frame
/// shading on quads with no lights: `s` and `t` in planes 0 and 1, `Ci` into planes 2 to 4,
/// the pixel centres in planes 5 and 6.
pub fn link_quad_surface(library: &Program, source: &str) -> Program {
    use primflow::link::{self, Group, PlaneParam};
    let mut diags = Diagnostics::new();
    let module = primflow::syntax::parse(0, source, &mut diags);
    assert!(!diags.has_errors(), "{diags:?}");
    let planes = [PlaneParam {
        name: "st".into(),
        first_plane: 0,
        components: 2,
    }];
    let group = Group {
        surface: &module.items[0],
        lights: vec![],
        atmosphere: None,
        planes: &planes,
        material: None,
        surface_text: &[],
        out_plane: 2,
        quads: true,
    };
    let linked = link::link(&group).expect("links");
    let program = primflow::check::check_linked(library, &linked.items, &mut diags);
    assert!(!diags.has_errors(), "{diags:?}");
    program
}

/// `examples/NAME` loaded into a renderer for `program` (panics on scene errors).
pub fn example_scene(sources: &mut SourceMap, program: &Arc<Program>, name: &str) -> Renderer {
    let path = format!("{}/examples/{name}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let file = sources.add(name, text);
    let mut r = Renderer::new(program.clone());
    let mut diags = Diagnostics::new();
    primflow::scene::load_into(sources, file, &mut r, &mut diags);
    assert!(!diags.has_errors(), "{name}: {}", diags.render(sources));
    r
}

/// The depth buffer's raw value (`fixed<32,32>`, larger is nearer) of a depth in [0, 1]:
/// round(z * 2^32), saturated.
pub fn raw_depth(z: f64) -> u32 {
    (z * 4294967296.0).round().clamp(0.0, 4294967295.0) as u32
}

/// Every file of `dir` (relative to the crate root) whose extension is `ext`, sorted by
/// path: (path, contents).
pub fn read_dir(dir: &str, ext: &str) -> Vec<(String, String)> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(dir);
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .expect("directory")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == ext))
        .collect();
    files.sort();
    files
        .into_iter()
        .map(|p| (p.display().to_string(), std::fs::read_to_string(&p).expect("readable")))
        .collect()
}
