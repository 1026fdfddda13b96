//! The IR evaluator (`primflow::ir::eval`) as the JIT's differential oracle: the same
//! program, variant key, argument block and tile, run by a tier-0 kernel, a tier-1 kernel
//! and the evaluator, must leave the same depth buffer, depth-write counts and G-buffer
//! planes (bit for bit; any NaN equals any NaN) and the same run-time error counts per
//! site, the same setup fuel left, and when the first error comes from setup code, the
//! same first error.
//!
//! Cases: every instance of the example scenes and of `prims/tests` (the library's
//! primitives through the runtime's own argument blocks and keys, shared interpolators and
//! constants included), re-sized to a small image and run in every 16 x 8 tile; the
//! primitives of `tests/check/ok` and of [`SOURCE`] (loops, fixed point, varying control
//! flow, index errors, fuel, calls, interpolation arms) with argument blocks drawn by
//! `Lcg`; and programs from a seeded generator of valid sources. Each family asserts that
//! it compared drawn pixels, nonzero plane values and nonzero error counts, so an
//! evaluator that drew nothing or counted nothing would fail it.

use std::sync::Arc;

use crate::support;
use crate::support::jit::{Tile, H, W};
use crate::support::Lcg;

use primflow::abi::{
    count_slots, ArgLayout, Binding, BindingKind, Kernel, ParamSlot, VariantKey, DEFAULT_GROUP_FUEL_FLOOR, MODE_RENDER,
};
use primflow::diag::{Diagnostics, SourceMap};
use primflow::ir::eval::{self, Budget};
use primflow::ir::{Elem, FuncId, FuncKind, Program, Scalar};
use primflow::jit::{Jit, JitOptions, Tier};
use primflow::runtime::Renderer;

/// Primitives for what the library does not exercise much: index errors in setup and
/// pixel code (uniform and varying indices, guarded ones), fuel in both parts, varying
/// loops with break and continue, fixed-point arithmetic, a call, interpolation arms.
const SOURCE: &str = r#"
primitive oracle_index(int i, j; float s; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(0, 0, 40, 24);
    float a[4] = {0.125, 0.25, 0.375, 0.5};
    float u = a[i];
    int k = int(X * s) - j;
    float v = a[k];
    float w = k > 0 && k < 4 ? a[k] : a[i + 1];
    if (v + w + u > 0.7)
        return;
    Z = (v + w + u) / 4;
    interpolation {
        linear:
            interpolator_return(v * X + w);
    }
}

primitive oracle_loops(int n, m; float s; varying float X, Y; inout varying float Z)
{
    bound(1, 1, 37, 22);
    int setup_trips = 0;
    for (int t = 0; t < n; t++)
        setup_trips += t % 3;
    float acc = 0;
    int trips = 0;
    while (acc < X * s) {
        trips++;
        if (trips > m)
            break;
        if (trips % 2 == 0)
            continue;
        acc += 1.5 + setup_trips;
    }
    if (trips == 3)
        return;
    Z = 1 / (1 + acc + trips);
    interpolation {
        linear:
            interpolator_return(acc);
        default:
            interpolator_return;
    }
}

primitive oracle_fixed(float s, t; int sh; varying fixed<32,8> X, Y; inout varying fixed<32,32> Z)
{
    fixed<16,8> a = s;
    fixed<32,8> b = X * a - Y;
    fixed<12,4> c = b / (t + 0);
    fixed<32,16> d = c % 3 + X * Y;
    fixed<8,8> e = s * 0.0625;
    if (d < 0 || b > 200)
        return;
    Z = e + d / 65536;
    interpolation {
        perspective_linear:
            interpolator_return(float(c) + float(d) + int(b) + sh);
        default:
            interpolator_return;
    }
}

primitive oracle_call(int i; float s; varying float X, Y; inout varying fixed<32,32> Z)
{
    oracle_index(i, 1, s, X, Y, Z);
    bound(8, 4, 30, 20);
    if (X + Y > 30)
        return;
    Z = 0.25 + i / 16.0;
}

primitive oracle_round(float s; varying float X, Y; inout varying float Z)
{
    bound(0, 0, 40, 24);
    fixed<16,0> column = X;                 // X = n + 0.5: ties, rounded to even
    fixed<8,4> tie = s * 0.03125 + 0.03125;
    fixed<32,32> depth = Y / 64;
    Z = depth + column / 4096.0;
    interpolation {
        linear:
            interpolator_return(column + tie);
    }
}

primitive oracle_spin(int n; varying float X, Y; inout varying float Z)
{
    bound(0, 0, 20, 12);
    int t = 0;
    while (t < n * 5000)
        t = t + 1;
    float x = X;
    while (x > -1)
        x = x + 0.0;
    Z = 0.5 + t / 1e9;
}
"#;

/// A run to compare: a primitive, its key and argument block, in a viewport of `size`.
pub(crate) struct Case {
    what: String,
    func: FuncId,
    key: VariantKey,
    args: Vec<u32>,
    size: (u32, u32),
    planes: usize,
    budget: Budget,
}

/// What the comparisons saw, so a family can show it compared something.
#[derive(Default, Debug)]
pub(crate) struct Seen {
    pub runs: usize,
    pub drawn: u64,
    pub nonzero_planes: u64,
    pub errors: u64,
    pub fuel_errors: u64,
    pub setup_fuel_out: u64,
    pub unsupported: usize,
}

/// Both tiers' JITs for `program`.
pub(crate) fn tiers(program: &Arc<Program>, unroll_loops: bool) -> Vec<(Tier, Jit)> {
    [Tier::Fast, Tier::Optimised]
        .into_iter()
        .map(|tier| {
            let options = JitOptions { tier, unroll_loops };
            (tier, Jit::with_options(program.clone(), options).expect("host ISA"))
        })
        .collect()
}

/// 32 random bits.
fn bits(rng: &mut Lcg) -> u32 {
    (rng.next() * 4294967296.0) as u32
}

fn same_float(a: f32, b: f32) -> bool {
    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
}

/// The tile's starting depth and planes: a pattern that makes depth tests go both ways and
/// shows every plane write.
fn start_buffers(rng: &mut Lcg, planes: usize) -> (Vec<u32>, Vec<f32>) {
    let depth = (0..W * H)
        .map(|_| if bits(rng).is_multiple_of(3) { 0 } else { bits(rng) })
        .collect();
    let gbuf = (0..W * H * planes.max(1)).map(|i| -(i as f32) - 0.5).collect();
    (depth, gbuf)
}

/// Run `case` in the tile at (x0, y0) with every kernel of `kernels` and with the
/// evaluator; assert they agree.
fn compare_tile(
    program: &Program,
    evaluator: &eval::Evaluator,
    case: &Case,
    kernels: &[(Tier, Arc<Kernel>)],
    x0: i32,
    y0: i32,
    seen: &mut Seen,
) {
    let slots = count_slots(program);
    let mut rng = Lcg(((x0 as u64) << 32) ^ (y0 as u64) ^ 0x5eed);
    let (depth, gbuf) = start_buffers(&mut rng, case.planes);
    let mut t = eval::Tile::new(x0, y0, W, H, case.planes, case.size.0, case.size.1);
    t.depth.clone_from(&depth);
    t.planes = gbuf[..W * H * case.planes].to_vec();
    let out = match evaluator.run(case.func, &case.key, &case.args, &mut t, case.budget) {
        Ok(out) => out,
        Err(eval::EvalError::Unsupported(m)) => {
            seen.unsupported += 1;
            eprintln!("{}: unsupported: {m}", case.what);
            return;
        }
        Err(e) => panic!("{}: the evaluator refused a checked program: {e}", case.what),
    };
    seen.runs += 1;
    seen.drawn += t.writes.iter().filter(|&&n| n != 0).count() as u64;
    seen.nonzero_planes += t
        .planes
        .iter()
        .zip(&gbuf)
        .filter(|(a, b)| a.to_bits() != b.to_bits() && **a != 0.0)
        .count() as u64;
    let want_errors: Vec<u64> = (0..slots)
        .map(|i| out.setup_counts[i].wrapping_add(out.pixel_counts[i]))
        .collect();
    seen.errors += want_errors.iter().sum::<u64>();
    seen.fuel_errors += want_errors
        .iter()
        .skip(2)
        .step_by(2)
        .take(program.sites.len())
        .sum::<u64>();
    seen.setup_fuel_out += u64::from(primflow::abi::setup_fuel_ran_out(out.fuel).is_some());
    for (tier, k) in kernels {
        let at = format!("{} {tier:?} tile ({x0}, {y0})", case.what);
        let mut tile = Tile::new(case.planes);
        tile.x0 = x0;
        tile.y0 = y0;
        tile.depth.clone_from(&depth);
        tile.gbuf.clone_from(&gbuf);
        tile.pixel_fuel = case.budget.pixel_fuel;
        tile.group_fuel_floor = case.budget.group_fuel_floor;
        let mut ctx = tile.ctx(MODE_RENDER, case.budget.setup_fuel);
        ctx.width = case.size.0;
        ctx.height = case.size.1;
        assert!(case.args.len() >= k.layout.words(case.args[0]), "{at}: short block");
        // SAFETY: the context points at this tile's live buffers (16 x 8, `planes` planes,
        // error counts for every slot of the program), the block is as long as the layout.
        unsafe { (k.entry)(&mut ctx, case.args.as_ptr()) };
        let (error, site, fuel) = (ctx.error, ctx.error_site, ctx.fuel);
        assert_eq!(tile.depth, t.depth, "{at}: depth");
        assert_eq!(tile.counts, t.writes, "{at}: depth writes");
        for (i, (a, b)) in tile.gbuf[..W * H * case.planes].iter().zip(&t.planes).enumerate() {
            assert!(
                same_float(*a, *b),
                "{at}: plane {} pixel {}: JIT {a} evaluator {b}",
                i / (W * H),
                i % (W * H)
            );
        }
        assert_eq!(fuel, out.fuel, "{at}: setup fuel left");
        assert_eq!(&tile.errors[..slots], &want_errors[..], "{at}: error counts");
        match out.first_error {
            Some((code, s)) if out.first_error_in_setup => assert_eq!((error, site), (code, s), "{at}: first error"),
            None => assert_eq!(error, 0, "{at}: an error the evaluator did not see"),
            Some(_) => {}
        }
    }
}

/// Compare `case` in every `step`-th tile of its viewport; the evaluator unrolls loops as
/// the JITs do (`unroll_loops`).
fn compare(program: &Arc<Program>, jits: &mut [(Tier, Jit)], case: &Case, step: usize, seen: &mut Seen) {
    let unroll = jits.first().is_none_or(|(_, j)| j.options().unroll_loops);
    let mut key = case.key.clone();
    key.count_writes = true;
    let kernels: Vec<(Tier, Arc<Kernel>)> = jits
        .iter_mut()
        .map(|(tier, jit)| match jit.kernel(case.func, &key) {
            Ok(k) => (*tier, k),
            Err(e) => panic!("{}: {tier:?} JIT refused it: {e}", case.what),
        })
        .collect();
    let case = Case {
        key,
        ..clone_case(case)
    };
    let evaluator = eval::Evaluator::new(program, unroll);
    let (tw, th) = (case.size.0.div_ceil(W as u32), case.size.1.div_ceil(H as u32));
    for (n, (tx, ty)) in (0..th).flat_map(|ty| (0..tw).map(move |tx| (tx, ty))).enumerate() {
        if n % step == 0 {
            compare_tile(
                program,
                &evaluator,
                &case,
                &kernels,
                (tx as usize * W) as i32,
                (ty as usize * H) as i32,
                seen,
            );
        }
    }
}

fn clone_case(c: &Case) -> Case {
    Case {
        what: c.what.clone(),
        func: c.func,
        key: c.key.clone(),
        args: c.args.clone(),
        size: c.size,
        planes: c.planes,
        budget: c.budget,
    }
}

/// Every instance `r` holds, as cases in a `size` viewport.
fn instance_cases(r: &Renderer, what: &str, size: (u32, u32)) -> Vec<Case> {
    let planes = r.num_planes() as usize;
    r.instances()
        .iter()
        .enumerate()
        .map(|(i, inst)| Case {
            what: format!("{what} instance {i} ({})", r.program().func(inst.func).name),
            func: inst.func,
            key: inst.key.clone(),
            args: inst.args.clone(),
            size,
            planes,
            budget: Budget::default(),
        })
        .collect()
}

/// `text` with its `image` line made `size` (its instances' geometry follows).
fn resized(text: &str, size: (u32, u32)) -> String {
    text.lines()
        .map(|l| {
            if l.trim_start().starts_with("image ") {
                format!("image {} {}", size.0, size.1)
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn library_scenes_match_the_evaluator_at_both_tiers() {
    let (sources, program) = support::library_and_sources();
    let mut jits = tiers(&program, true);
    let mut seen = Seen::default();
    let size = (64, 40);
    let mut scenes = support::read_dir("examples", "scene");
    scenes.extend(support::read_dir("prims/tests", "scene"));
    let mut cases = 0;
    for (name, text) in &scenes {
        let mut sources = sources.clone();
        let file = sources.add(name.clone(), resized(text, size));
        let mut r = Renderer::new(program.clone());
        let mut diags = Diagnostics::new();
        primflow::scene::load_into(&sources, file, &mut r, &mut diags);
        if diags.has_errors() {
            // A scene that needs primitives of its own directory (prims/tests/prims).
            continue;
        }
        for case in instance_cases(&r, name, size) {
            compare(&program, &mut jits, &case, 1, &mut seen);
            cases += 1;
        }
    }
    assert!(cases >= 10, "{cases} instances");
    assert!(seen.drawn > 1000 && seen.nonzero_planes > 1000, "{seen:?}");
    assert_eq!(seen.unsupported, 0, "{seen:?}");
}

/// An argument block for `func` under `key`, its values drawn from `rng`: floats mostly in
/// the viewport's range, ints small (some out of any array's range), `n_seq` sequence
/// points.
fn random_args(program: &Program, func: FuncId, key: &VariantKey, n_seq: u32, rng: &mut Lcg) -> Vec<u32> {
    let f = program.func(func);
    let layout = ArgLayout::new(program, func, key);
    let mut args = vec![0u32; layout.words(n_seq)];
    args[0] = n_seq;
    for g in 0..key.total_components() {
        args[(layout.plane_table + g) as usize] = g;
    }
    for (bi, b) in key.bindings.iter().enumerate() {
        if let (BindingKind::Constant, Some(at)) = (&b.kind, layout.binding_data[bi]) {
            for c in 0..b.components {
                args[(at + c) as usize] = (rng.range(-2.0, 2.0) as f32).to_bits();
            }
        }
    }
    for (p, slot) in f.params.iter().zip(&layout.params) {
        let (start, words) = match slot {
            ParamSlot::Pixel => continue,
            ParamSlot::Fixed { offset, words } => (*offset, *words),
            ParamSlot::Seq { seq_offset, words } => {
                (layout.fixed_words + n_seq.max(1) * seq_offset, words * n_seq.max(1))
            }
        };
        let ty = &f.local(p.local).ty;
        for w in 0..words {
            let sc = match ty.elem {
                Elem::Scalar(s) => s,
                Elem::Interp => Scalar::Float,
            };
            args[(start + w) as usize] = match sc {
                Scalar::Float => (match bits(rng) % 8 {
                    0 => 0.0,
                    1 => rng.range(-3.0, 3.0),
                    _ => rng.range(-4.0, 44.0),
                } as f32)
                    .to_bits(),
                Scalar::Int => ((bits(rng) % 9) as i32 - 2) as u32,
                Scalar::Bool => bits(rng) % 2,
                Scalar::Fixed(fmt) => {
                    let (lo, hi) = fmt.raw_range();
                    (lo + (bits(rng) as i64).rem_euclid(hi - lo + 1)) as u32
                }
            };
        }
    }
    args
}

/// Keys to try: none, a linear 3-component parameter with a constant, two kinds.
fn keys() -> Vec<VariantKey> {
    let kind = |k: &str, n| Binding {
        kind: BindingKind::Kind(k.into()),
        components: n,
    };
    vec![
        VariantKey::default(),
        VariantKey {
            bindings: vec![
                kind("linear", 3),
                Binding {
                    kind: BindingKind::Constant,
                    components: 1,
                },
            ],
            ..VariantKey::default()
        },
        VariantKey {
            bindings: vec![kind("perspective_linear", 2), kind("linear", 1)],
            trivial_accept: true,
            ..VariantKey::default()
        },
    ]
}

/// Every primitive of `program` defined in `names` (all when empty), with random argument
/// blocks under each of [`keys`], compared in every other tile of a 40 x 24 viewport.
pub(crate) fn random_arg_cases(
    program: &Arc<Program>,
    names: &[&str],
    seeds: u64,
    budget: Budget,
    unroll_loops: bool,
    seen: &mut Seen,
) {
    let mut jits = tiers(program, unroll_loops);
    for (i, f) in program.functions.iter().enumerate() {
        if f.kind != FuncKind::Primitive || !(names.is_empty() || names.contains(&f.name.as_str())) {
            continue;
        }
        for key in keys() {
            for seed in 0..seeds {
                let mut rng = Lcg(seed * 7919 + i as u64);
                let n_seq = 1 + bits(&mut rng) % 5;
                let args = random_args(program, FuncId(i as u32), &key, n_seq, &mut rng);
                let case = Case {
                    what: format!("{} key {:?} seed {seed}", f.name, key.bindings),
                    func: FuncId(i as u32),
                    planes: key.total_components() as usize,
                    key: key.clone(),
                    args,
                    size: (40, 24),
                    budget,
                };
                compare(program, &mut jits, &case, 2, seen);
            }
        }
    }
}

/// Budgets small enough that endless loops end fast, at both tiers and in the evaluator.
pub(crate) fn small_budget() -> Budget {
    Budget {
        setup_fuel: 1 << 14,
        pixel_fuel: 1 << 12,
        group_fuel_floor: DEFAULT_GROUP_FUEL_FLOOR / 16,
    }
}

#[test]
fn test_sources_with_random_arguments_match_the_evaluator() {
    let mut user: Vec<(String, String)> = support::read_dir("tests/check/ok", "prim");
    user.push(("oracle.prim".into(), SOURCE.into()));
    let library = support::library();
    let mut seen = Seen::default();
    // One program per file: the files may define the same names.
    for (name, text) in &user {
        // Alone (some redefine library primitives), or with the library it calls.
        let mut sources = SourceMap::new();
        let file = sources.add(name.clone(), text.clone());
        let mut diags = Diagnostics::new();
        let program = match primflow::compile(&sources, &[file], &mut diags) {
            Some(p) if !diags.has_errors() => Arc::new(p),
            _ => support::library_with(&mut SourceMap::new(), &[(name.as_str(), text.as_str())]),
        };
        let names: Vec<&str> = program
            .functions
            .iter()
            .filter(|f| library.find(&f.name).is_none() || program.functions.len() < library.functions.len())
            .map(|f| f.name.as_str())
            .collect();
        random_arg_cases(&program, &names, 6, small_budget(), true, &mut seen);
    }
    assert!(seen.drawn > 500 && seen.nonzero_planes > 100, "{seen:?}");
    assert!(
        seen.errors > 50 && seen.fuel_errors > 10 && seen.setup_fuel_out > 0,
        "{seen:?}"
    );
    assert_eq!(seen.unsupported, 0, "{seen:?}");
}

#[test]
fn library_primitives_with_random_arguments_match_the_evaluator() {
    let program = support::library();
    let mut seen = Seen::default();
    random_arg_cases(&program, &[], 3, small_budget(), true, &mut seen);
    assert!(seen.runs > 100, "{seen:?}");
    assert_eq!(seen.unsupported, 0, "{seen:?}");
}

#[test]
fn the_evaluator_refuses_a_short_argument_block_or_a_bad_tile_without_panicking() {
    let program = support::library();
    let evaluator = eval::Evaluator::new(&program, true);
    let tri = program.find("screen_triangle").expect("screen_triangle");
    let key = VariantKey::default();
    let full = ArgLayout::new(&program, tri, &key).words(3);
    let mut tile = eval::Tile::new(0, 0, W, H, 0, 64, 32);
    for words in [0, 1, full - 1] {
        let mut args = vec![0u32; words];
        if let Some(n) = args.first_mut() {
            *n = 3;
        }
        let got = evaluator.run(tri, &key, &args, &mut tile, Budget::default());
        assert!(
            matches!(got, Err(eval::EvalError::Malformed(_))),
            "{words} words: {got:?}"
        );
    }
    // A stride that is not a whole number of groups, and buffers shorter than the tile.
    let args = vec![3u32; full];
    let mut odd = eval::Tile::new(0, 0, W, H, 0, 64, 32);
    odd.stride = 6;
    assert!(evaluator.run(tri, &key, &args, &mut odd, Budget::default()).is_err());
    let mut short = eval::Tile::new(0, 0, W, H, 2, 64, 32);
    short.planes.truncate(10);
    assert!(evaluator.run(tri, &key, &args, &mut short, Budget::default()).is_err());
    // An interpolator is not a kernel of its own.
    let interp = program.find("solid_interpolation").expect("solid_interpolation");
    assert!(evaluator
        .run(interp, &key, &args, &mut tile, Budget::default())
        .is_err());
}

/// Every lane leaves the loop at its first trip; the statement after the `break` then runs
/// for no lane, and its uniform index `u` is out of range. The same index after the loop
/// runs for every lane.
const LANELESS: &str = r#"
primitive laneless(int u; varying float X, Y; inout varying float Z)
{
    float a[2] = {0.25, 0.5};
    float s = 0;
    while (X > 0) {
        if (X > -1)
            break;
        s = a[u];
    }
    Z = s + 0.125 + a[u];
}
"#;

#[test]
fn a_uniform_index_no_lane_runs_fails_for_no_pixel() {
    let mut sources = SourceMap::new();
    let file = sources.add("laneless.prim", LANELESS);
    let mut diags = Diagnostics::new();
    let program = Arc::new(primflow::compile(&sources, &[file], &mut diags).expect("checks"));
    let func = program.find("laneless").expect("laneless");
    let key = VariantKey {
        count_writes: true,
        ..VariantKey::default()
    };
    let layout = ArgLayout::new(&program, func, &key);
    let mut args = vec![0u32; layout.words(1)];
    args[0] = 1;
    let ParamSlot::Fixed { offset, .. } = layout.params[0] else {
        panic!("u is a per-primitive parameter")
    };
    args[offset as usize] = 5;
    let evaluator = eval::Evaluator::new(&program, true);
    let mut t = eval::Tile::new(0, 0, W, H, 0, 64, 32);
    let out = evaluator
        .run(func, &key, &args, &mut t, Budget::default())
        .expect("runs");
    assert!(t.writes.iter().all(|&n| n == 1), "every pixel draws");
    assert!(
        t.depth.iter().all(|&z| z == support::raw_depth(0.625)),
        "Z = 0 + 0.125 + a[1]"
    );
    let counts: Vec<u64> = (0..count_slots(&program))
        .map(|i| out.setup_counts[i] + out.pixel_counts[i])
        .collect();
    // One count per group of the tile (4 groups a row, 8 rows), from the access after the
    // loop only: the one after the `break` fails for no pixel.
    assert_eq!(counts.iter().sum::<u64>(), 32, "{counts:?}");
    for tier in [Tier::Optimised, Tier::Fast] {
        for unroll_loops in [true, false] {
            let mut jit = Jit::with_options(program.clone(), JitOptions { tier, unroll_loops }).expect("host ISA");
            let k = jit.kernel(func, &key).expect("kernel");
            let mut tile = Tile::new(0);
            tile.run(&k, &args, MODE_RENDER, primflow::abi::DEFAULT_FUEL);
            assert_eq!(tile.depth, t.depth, "{tier:?} unroll {unroll_loops}: depth");
            assert_eq!(
                &tile.errors[..counts.len()],
                &counts[..],
                "{tier:?} unroll {unroll_loops}: counts"
            );
        }
    }
}

/// A helper inlined after the group's loop ran out of fuel: lanes with `X` past the sum
/// spin in the `while` until the fuel is gone. `scale` has a `return`, so its body is
/// compiled as a loop that cannot repeat; it spends no fuel, so it runs, and Z is 1 for
/// every drawn pixel. (Tier 0 ran it while the evaluator left it at its empty fuel check and
/// read its unassigned result, which found this with loop unrolling off.)
const HELPER_AFTER_FUEL: &str = r#"
float scale(float a, b) { return a * b + 1; }
primitive gen(float p0, p1, p2, p3; int n0, n1; float fa[5]; int ia[3];
              varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(p0 - 4, p1 - 4, p0 + p2 + 30, p1 + p3 + 20);
    int i0 = n0 + 1, i1 = 0;
    while (true) {
        if ((fa[n0 * 0 + n0] + fa[n0 * 0 + n1]) < (X - 0.5)) continue;
        i1 = i1 + 1;
        if (i1 > 40) break;
    }
    i0 = 5 % ia[n0 * 0 + i1];
    Z = scale(0.0, -(float(i0)));
}
"#;

#[test]
fn a_helper_after_the_group_ran_out_of_fuel_runs_at_both_tiers_and_in_the_evaluator() {
    let mut sources = SourceMap::new();
    let file = sources.add("helper_after_fuel.prim", HELPER_AFTER_FUEL);
    let mut diags = Diagnostics::new();
    let program = primflow::compile(&sources, &[file], &mut diags).expect("checks");
    let program = Arc::new(program);
    let mut seen = Seen::default();
    for unroll in [false, true] {
        random_arg_cases(&program, &["gen"], 2, small_budget(), unroll, &mut seen);
    }
    assert!(seen.fuel_errors > 0 && seen.drawn > 500, "{seen:?}");
}

/// A case running the `__shade` primitive of a linked shader group on random arguments,
/// its output planes from `out_plane`, over a G-buffer of `planes` random planes.
fn shade_case(linked_program: &Program, what: String, out_plane: u32, planes: usize, rng: &mut Lcg) -> Case {
    use primflow::link;
    let func = linked_program.find(link::SHADE).expect("__shade");
    let key = VariantKey {
        bindings: vec![Binding {
            kind: BindingKind::Kind(link::OUT_KIND.into()),
            components: 3,
        }],
        ..VariantKey::default()
    };
    let mut args = random_args(linked_program, func, &key, 0, rng);
    let layout = ArgLayout::new(linked_program, func, &key);
    for c in 0..3 {
        args[layout.plane_table as usize + c] = out_plane + c as u32;
    }
    Case {
        what,
        func,
        key,
        args,
        size: (32, 16),
        planes,
        budget: Budget::default(),
    }
}

#[test]
fn linked_shader_groups_match_the_evaluator_at_both_tiers() {
    // The library's surfaces with every light shader and fog, linked against a G-buffer of
    // Cs, N and st (output planes after them), on random arguments: `__gbuffer` reads and
    // the unrolled lights agree bit for bit.
    use primflow::link::{self, Group, PlaneParam};
    use primflow::syntax::ast::ItemKind;
    let (_, program) = support::library_and_sources();
    let find = |kind: ItemKind, name: &str| {
        program
            .shading_items
            .iter()
            .find(|i| i.kind == kind && i.name.name == name)
            .unwrap_or_else(|| panic!("no {name}"))
    };
    let lights: Vec<_> = ["ambientlight", "pointlight", "distantlight", "spotlight"]
        .iter()
        .map(|n| find(ItemKind::Light, n))
        .collect();
    let planes = [("Cs", 0, 3), ("N", 3, 3), ("st", 6, 2)].map(|(n, first, c)| PlaneParam {
        name: n.into(),
        first_plane: first,
        components: c,
    });
    let mut seen = Seen::default();
    let mut rng = Lcg(36);
    for surface in [
        "matte",
        "plastic",
        "checker",
        "filtered_checker",
        "marble",
        "fixed_phong",
    ] {
        let surface_item = find(ItemKind::Surface, surface);
        let group = Group {
            surface: surface_item,
            lights: lights.clone(),
            atmosphere: Some(find(ItemKind::Atmosphere, "fog")),
            planes: &planes,
            material: None,
            surface_text: &[],
            out_plane: 8,
            // `filtered_checker` takes derivatives: its lanes are a quad, its pixel centres
            // read from planes 11 and 12 (random here, like the rest of the G-buffer).
            quads: link::takes_derivatives(surface_item),
        };
        let linked = link::link(&group).expect("links");
        let mut diags = Diagnostics::new();
        let linked_program = Arc::new(primflow::check::check_linked(&program, &linked.items, &mut diags));
        assert!(!diags.has_errors(), "{surface}: {diags:?}");
        let case = shade_case(&linked_program, format!("linked `{surface}`"), 8, 13, &mut rng);
        let mut jits = tiers(&linked_program, true);
        compare(&linked_program, &mut jits, &case, 1, &mut seen);
    }
    assert_eq!(seen.unsupported, 0, "{seen:?}");
    assert!(seen.nonzero_planes > 1000, "{seen:?}");
}

#[test]
fn texture_lookups_on_quads_match_the_evaluator_at_both_tiers() {
    // A surface sampling a generated texture at derivatives-selected levels, in every wrap
    // mode, on random G-buffer contents (so random quads of shaded lanes): the kernels'
    // `primflow_texture` calls and the evaluator's `sample` give the same bits.
    use primflow::runtime::texture::{TextureSet, TEXTURE_MEMORY_LIMIT};
    let (_, program) = support::library_and_sources();
    let source = "surface textured() {
    Ci = texture(\"a.png\", s * 3, t * 5) + texture(\"b.png\", t, s, \"wrap\", \"mirror\")
        + texture(\"a.png\", s * 40, -t, \"wrap\", \"black\") * {1, 0.5, 0.25};
}";
    let mut linked_program = support::link_quad_surface(&program, source);
    assert_eq!(linked_program.textures.names, ["a.png", "b.png"]);
    let mut set = TextureSet::new();
    let mut rng = Lcg(38);
    for (name, (w, h)) in [("a.png", (16, 8)), ("b.png", (5, 3))] {
        let texels = (0..w * h)
            .map(|_| [0, 1, 2].map(|_| (bits(&mut rng) >> 8) as f32 / (1 << 24) as f32))
            .collect();
        set.insert(name, w, h, texels, TEXTURE_MEMORY_LIMIT).expect("fits");
    }
    linked_program.textures.loaded = Some((Arc::new(set), vec![0, 1]));
    let linked_program = Arc::new(linked_program);
    let case = shade_case(&linked_program, "linked `textured`".into(), 2, 7, &mut rng);
    let mut seen = Seen::default();
    let mut jits = tiers(&linked_program, true);
    compare(&linked_program, &mut jits, &case, 1, &mut seen);
    assert_eq!(seen.unsupported, 0, "{seen:?}");
    assert!(seen.nonzero_planes > 100, "{seen:?}");
}
