//! The pixel debugger behind `primflow trace SCENE --pixel X,Y`: why a pixel came out as
//! it did. For every instance that reaches the pixel, in draw order, it prints the
//! statements that ran for the pixel with the values assigned, where the pixel's run ended
//! and what it wrote, then whether that agrees with the rendered frame.
//!
//! How: the scene is rendered with the JIT's tier-1 kernels (`Jit::new`), then every
//! instance is run again, in draw order, by the IR evaluator ([`crate::ir::eval`], the
//! JIT's bit-for-bit oracle in f32) over the row of the pixel's tile, with an observer
//! watching the pixel ([`crate::ir::eval::observe`]). The evaluator's tile starts as a
//! render tile does (depth 0, planes 0) and spans the same columns, so every pixel group,
//! its lanes and its fuel are the kernels' own. The values printed are the evaluator's;
//! the final depth and shading parameters at the pixel are then compared with the frame's,
//! and the trace says whether they agree (or warns that they do not, for the values it
//! differs in).
//!
//! Invariants: an instance is listed when its pixel code ran for the pixel (the pixel lies
//! in its pass rectangle, in this kernel or a primitive it calls), or when its setup ended
//! early (`return`, fuel) without calling a primitive and without a bound that leaves the
//! pixel out. Statement, branch and
//! assignment lines are capped per instance ([`MAX_LINES`]); where the pixel retired and
//! what it wrote are always printed. Nothing here panics on a scene the renderer accepts:
//! an instance the evaluator refuses is reported and the comparison says it is incomplete.

use std::fmt::Write as _;
use std::io::Write;

use crate::diag::{SourceMap, Span};
use crate::ir::eval::{self, Budget, Evaluator, Event, Observer};
use crate::ir::{FixedFormat, LocalKind, Program, Scalar};
use crate::runtime::frame::tile_side;
use crate::runtime::render::tile_grid;
use crate::runtime::{Frame, Renderer};
use crate::scene::SceneObject;

/// Statement, branch and assignment lines printed per instance; the rest are counted.
pub const MAX_LINES: usize = 2000;

/// What a trace found, besides what it printed.
#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    /// The instances listed (indices into `Renderer::instances`), in draw order.
    pub listed: Vec<usize>,
    /// The evaluator's final depth and parameters at the pixel equal the frame's (`None`:
    /// the evaluator refused an instance, so there is nothing complete to compare).
    pub agrees: Option<bool>,
}

/// One thing the evaluator reported, kept until the instance is known to be listed.
enum Rec {
    Kernel { name: String, depth: u32 },
    KernelEnd { depth: u32 },
    PixelStart,
    Stmt(Span),
    Branch(bool),
    Assign(String),
    Return { span: Span, pixel: bool },
    FuelOut { site: Option<Span>, setup: bool },
    PixelEnd { alive: bool },
    Depth { before: u32, after: u32 },
    Plane { plane: u32, value: f32 },
}

/// The observer: the pixel's events of one instance, formatted where they need the IR.
struct Recorder<'p> {
    program: &'p Program,
    recs: Vec<Rec>,
    /// Statement, branch and assignment lines left out past [`MAX_LINES`].
    dropped: usize,
    lines: usize,
    in_pixel: bool,
    saw_pixel: bool,
    depth: u32,
}

impl Recorder<'_> {
    fn line(&mut self, rec: Rec) {
        if self.lines < MAX_LINES {
            self.lines += 1;
            self.recs.push(rec);
        } else {
            self.dropped += 1;
        }
    }
}

impl Observer for Recorder<'_> {
    fn event(&mut self, event: Event<'_>) {
        match event {
            Event::KernelStart { func, depth } => {
                self.depth = depth;
                self.recs.push(Rec::Kernel {
                    name: func.name.clone(),
                    depth,
                });
            }
            Event::KernelEnd { depth, .. } => {
                self.depth = depth.saturating_sub(1);
                self.recs.push(Rec::KernelEnd { depth });
            }
            Event::PixelStart => {
                self.in_pixel = true;
                self.saw_pixel = true;
                self.recs.push(Rec::PixelStart);
            }
            Event::Stmt { func, stmt } => self.line(Rec::Stmt(func.stmts.span(stmt))),
            Event::Branch { taken } => self.line(Rec::Branch(taken)),
            Event::Assign {
                func,
                local,
                sc,
                words,
                total,
                varying,
            } => {
                let Some(l) = func.locals.get(local.0 as usize) else {
                    return;
                };
                let name = match l.kind {
                    LocalKind::Temp => format!("{} (temporary)", l.name),
                    _ => l.name.clone(),
                };
                let mut text = format!("{name} = {}", value_text(sc, words, total));
                if self.in_pixel && !varying {
                    text.push_str(" (uniform)");
                }
                self.line(Rec::Assign(text));
            }
            Event::Return { stmt, func } => self.recs.push(Rec::Return {
                span: func.stmts.span(stmt),
                pixel: self.in_pixel,
            }),
            Event::FuelOut { site, setup } => self.recs.push(Rec::FuelOut {
                site: self.program.sites.get(site.0 as usize).copied(),
                setup,
            }),
            Event::PixelEnd { alive } => {
                self.in_pixel = false;
                self.recs.push(Rec::PixelEnd { alive });
            }
            Event::Depth { before, after } => self.recs.push(Rec::Depth { before, after }),
            Event::Plane { plane, value } => self.recs.push(Rec::Plane { plane, value }),
        }
    }
}

/// One lane word as the language writes the value.
fn word_text(sc: Scalar, w: u64) -> String {
    let w = w as u32;
    match sc {
        Scalar::Float => format!("{}", f32::from_bits(w)),
        Scalar::Int => format!("{}", w as i32),
        Scalar::Bool => format!("{}", w != 0),
        Scalar::Fixed(f) => format!("{}", fixed_value(f, w)),
    }
}

/// The value of a raw fixed-point word (unsigned when all its bits are fraction).
fn fixed_value(f: FixedFormat, raw: u32) -> f64 {
    let scale = (f64::from(f.frac)).exp2();
    if f.is_unsigned() {
        f64::from(raw) / scale
    } else {
        f64::from(raw as i32) / scale
    }
}

fn value_text(sc: Scalar, words: &[u64], total: usize) -> String {
    let parts: Vec<String> = words.iter().map(|&w| word_text(sc, w)).collect();
    match (parts.as_slice(), total) {
        ([one], 1) => one.clone(),
        _ if total > parts.len() => format!("{{{}, ... ({total} components)}}", parts.join(", ")),
        _ => format!("{{{}}}", parts.join(", ")),
    }
}

/// A raw `fixed<32,32>` depth: its value and its bits.
fn depth_text(raw: u32) -> String {
    format!("{} (raw 0x{raw:08x})", f64::from(raw) / 4294967296.0)
}

/// Where the trace's spans are: the sources, and the working directory, which file names
/// are shown relative to.
struct Places<'s> {
    sources: &'s SourceMap,
    cwd: String,
}

impl Places<'_> {
    /// `file:line:col` of a span's start; a span of no loaded file has its offset instead.
    fn location(&self, span: Span) -> String {
        if self.sources.files.get(span.file as usize).is_none() {
            return format!("<file {}>:{}", span.file, span.start);
        }
        let full = self.sources.location(span);
        match full.strip_prefix(&self.cwd) {
            Some(rest) if !self.cwd.is_empty() => rest.to_string(),
            _ => full,
        }
    }

    /// [`Places::location`] and the source line there, trimmed.
    fn located(&self, span: Span) -> (String, String) {
        let Some(file) = self.sources.files.get(span.file as usize) else {
            return (self.location(span), String::new());
        };
        let (line, _) = self.sources.line_col(span.file, span.start);
        let (a, b) = file.line_range(line - 1);
        (self.location(span), file.text[a..b].trim().to_string())
    }
}

/// Parse `X,Y` (the `--pixel` argument): two non-negative integers.
pub fn parse_pixel(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("`{s}` is not a pixel: expected X,Y, two non-negative integers (e.g. 12,7)");
    let (x, y) = s.split_once(',').ok_or_else(bad)?;
    let n = |t: &str| t.trim().parse::<u32>().map_err(|_| bad());
    Ok((n(x)?, n(y)?))
}

/// Trace pixel `(x, y)` of the scene `renderer` holds, whose `frame` was rendered from it
/// (`objects`: what each of the scene's objects became), printing to `out`. Errors: the
/// message to print (a pixel outside the image).
pub fn trace(
    sources: &SourceMap,
    renderer: &Renderer,
    objects: &[SceneObject],
    frame: &Frame,
    pixel: (u32, u32),
    out: &mut dyn Write,
) -> Result<Summary, String> {
    let opts = &renderer.options;
    let (width, height) = (frame.width, frame.height);
    let (px, py) = pixel;
    if frame.sample_count() > 1 {
        return Err(format!(
            "the frame has {} samples per pixel; a trace runs at the pixel centre and checks a one-sample frame: render with samples 1",
            frame.sample_count()
        ));
    }
    if px >= width || py >= height {
        return Err(format!(
            "pixel ({px}, {py}) is outside the {width}x{height} image (x in 0..={}, y in 0..={})",
            width.saturating_sub(1),
            height.saturating_sub(1)
        ));
    }
    let program = renderer.program();
    let side = tile_side(opts.tile_size);
    let grid_opts = crate::runtime::RenderOptions {
        width,
        height,
        tile_size: side,
        ..opts.clone()
    };
    let Some(tile) = tile_grid(&grid_opts)
        .into_iter()
        .find(|t| (t.x0..t.x1).contains(&px) && (t.y0..t.y1).contains(&py))
    else {
        return Err(format!("pixel ({px}, {py}) is in no tile of the image"));
    };
    let planes = renderer.num_planes() as usize;
    // The pixel's row of its render tile: the same groups, lanes and pass rectangle.
    let mut row = eval::Tile::new(
        tile.x0 as i32,
        py as i32,
        (tile.x1 - tile.x0) as usize,
        1,
        planes,
        width,
        height,
    );
    let budget = Budget {
        setup_fuel: opts.setup_fuel,
        pixel_fuel: opts.pixel_fuel,
        group_fuel_floor: opts.group_fuel_floor,
    };
    let evaluator = Evaluator::new(program, crate::jit::JitOptions::default().unroll_loops);
    let instances = renderer.instances();
    let mut text = String::new();
    let _ = writeln!(
        text,
        "trace of pixel ({px}, {py}) in a {width}x{height} image: {} instance(s) in draw order",
        instances.len()
    );
    let mut summary = Summary {
        listed: vec![],
        agrees: Some(true),
    };
    let places = Places {
        sources,
        cwd: std::env::current_dir()
            .map(|d| format!("{}/", d.display()))
            .unwrap_or_default(),
    };
    let mut last_writer = None;
    for (i, inst) in instances.iter().enumerate() {
        let mut rec = Recorder {
            program,
            recs: vec![],
            dropped: 0,
            lines: 0,
            in_pixel: false,
            saw_pixel: false,
            depth: 0,
        };
        let got = evaluator.run_observed(
            inst.func,
            &inst.key,
            &inst.args,
            &mut row,
            budget,
            (px as i32, py as i32),
            &mut rec,
        );
        let name = &program.func(inst.func).name;
        let outcome = match got {
            Ok(o) => o,
            Err(e) => {
                let _ = writeln!(text, "\ninstance {i} ({name}): the evaluator cannot run it: {e}");
                summary.agrees = None;
                continue;
            }
        };
        let setup_ended = rec
            .recs
            .iter()
            .any(|r| matches!(r, Rec::Return { pixel: false, .. } | Rec::FuelOut { setup: true, .. }));
        let bound_misses = outcome.bound.is_some_and(|b| {
            let (cx, cy) = (px as f32 + 0.5, py as f32 + 0.5);
            !(b[0] <= cx && cx <= b[2] && b[1] <= cy && cy <= b[3])
        });
        // A primitive that only calls others ends its setup with a `return` by design:
        // listed only if a call reached the pixel.
        let made_calls = rec.recs.iter().any(|r| matches!(r, Rec::Kernel { depth: 1.., .. }));
        let listed = rec.saw_pixel || (setup_ended && !made_calls && !bound_misses);
        if !listed {
            continue;
        }
        summary.listed.push(i);
        if rec.recs.iter().any(|r| matches!(r, Rec::Depth { .. })) {
            last_writer = Some(i);
        }
        print_instance(&mut text, &places, renderer, objects, i, outcome.bound, &rec);
    }
    if summary.listed.is_empty() {
        let _ = writeln!(
            text,
            "\nno instance covers pixel ({px}, {py}): none of the {} ran its pixel code there",
            instances.len()
        );
    }
    compare(&mut text, renderer, frame, &row, pixel, last_writer, &mut summary);
    let _ = out.write_all(text.as_bytes());
    Ok(summary)
}

/// Set where the innermost kernel run ended for the pixel.
fn set(retired: &mut [String], how: String) {
    if let Some(last) = retired.last_mut() {
        *last = how;
    }
}

/// The block of instance `i`: where it comes from, its bound, its statements for the
/// pixel, where it retired and what it wrote.
fn print_instance(
    text: &mut String,
    places: &Places,
    renderer: &Renderer,
    objects: &[SceneObject],
    i: usize,
    bound: Option<[f32; 4]>,
    rec: &Recorder,
) {
    let program = renderer.program();
    let name = &program.func(renderer.instances()[i].func).name;
    let origin = match objects.iter().position(|o| o.instances.contains(&i)) {
        Some(k) => {
            let o = &objects[k];
            format!(
                "scene {}, object {}, its instance {} of {}",
                places.location(o.begin),
                k + 1,
                i - o.instances.start + 1,
                o.instances.len()
            )
        }
        None => "no scene line".into(),
    };
    let _ = writeln!(text, "\ninstance {i}: {name} ({origin})");
    let _ = match bound {
        Some(b) => writeln!(text, "  bound: x {} .. {}, y {} .. {}", b[0], b[2], b[1], b[3]),
        None => writeln!(text, "  bound: none (the whole image)"),
    };
    let mut indent = 2usize;
    // Where each kernel run in progress ended for the pixel (the instance's, then calls).
    const NOT_REACHED: &str = "finished without reaching its pixel code";
    let mut retired = vec![String::from(NOT_REACHED)];
    let mut top_retired = String::from(NOT_REACHED);
    let mut depth: Option<(u32, u32)> = None;
    let mut plane_values: Vec<(u32, f32)> = vec![];
    for r in &rec.recs {
        let pad = " ".repeat(indent);
        match r {
            Rec::Kernel { name, depth } => {
                if *depth > 0 {
                    retired.push(NOT_REACHED.into());
                }
                indent = 2 + 2 * *depth as usize;
                let pad = " ".repeat(indent);
                let _ = if *depth == 0 {
                    writeln!(text, "{pad}setup (uniform, once for the tile):")
                } else {
                    writeln!(text, "{pad}call of {name} (depth {depth}), its setup:")
                };
            }
            Rec::PixelStart => {
                let _ = writeln!(text, "{pad}pixel part, for this pixel:");
            }
            Rec::Stmt(span) => {
                let (loc, line) = places.located(*span);
                let _ = writeln!(text, "{pad}  {loc}  {line}");
            }
            Rec::Branch(taken) => {
                let side = if *taken { "true: then" } else { "false: else" };
                let _ = writeln!(text, "{pad}      -> {side}");
            }
            Rec::Assign(a) => {
                let _ = writeln!(text, "{pad}      {a}");
            }
            Rec::Return { span, pixel } => {
                let loc = places.location(*span);
                let _ = if *pixel {
                    set(
                        &mut retired,
                        format!("return at {loc}: the pixel's run ends (outside or hidden)"),
                    );
                    writeln!(text, "{pad}      -> returns: the pixel's run ends here")
                } else {
                    set(
                        &mut retired,
                        format!("return at {loc} in setup: no pixel of this kernel runs"),
                    );
                    writeln!(text, "{pad}      -> returns in setup: no pixel runs")
                };
            }
            Rec::FuelOut { site, setup } => {
                let loc = site.map_or("?".into(), |s| places.location(s));
                let _ = if *setup {
                    set(
                        &mut retired,
                        format!("setup fuel ran out at the loop at {loc}: the run ends"),
                    );
                    writeln!(text, "{pad}  setup fuel ran out at the loop at {loc}: the run ends")
                } else {
                    writeln!(
                        text,
                        "{pad}  the group's pixel fuel ran out at the loop at {loc}: its loops end"
                    )
                };
            }
            Rec::KernelEnd { depth } => {
                let done = retired.pop().unwrap_or_default();
                if *depth == 0 {
                    top_retired = done;
                } else {
                    let _ = writeln!(text, "{pad}retired: {done}");
                    indent = 2 + 2 * (*depth as usize - 1);
                }
            }
            Rec::PixelEnd { alive } => {
                if *alive {
                    set(&mut retired, "finished: the pixel part ran to its end".into());
                }
            }
            Rec::Depth { before, after } => {
                let first = depth.map_or(*before, |d| d.0);
                depth = Some((first, *after));
            }
            Rec::Plane { plane, value } => match plane_values.iter_mut().find(|(p, _)| p == plane) {
                Some(slot) => slot.1 = *value,
                None => plane_values.push((*plane, *value)),
            },
        }
    }
    if rec.dropped > 0 {
        let _ = writeln!(text, "  ... {} more statement lines not shown", rec.dropped);
    }
    let _ = writeln!(text, "  retired: {top_retired}");
    let _ = match depth {
        Some((before, after)) => writeln!(text, "  wrote Z: {} -> {}", depth_text(before), depth_text(after)),
        None => writeln!(text, "  wrote Z: nothing"),
    };
    for p in renderer.shading_params() {
        let comps: Vec<Option<f32>> = (p.first_plane..p.first_plane + p.components)
            .map(|pl| plane_values.iter().find(|(q, _)| *q == pl).map(|v| v.1))
            .collect();
        if comps.iter().all(Option::is_none) {
            continue;
        }
        let shown: Vec<String> = comps
            .iter()
            .map(|c| c.map_or("(not written)".into(), |v| v.to_string()))
            .collect();
        let _ = writeln!(text, "  wrote {}: {}", p.name, shown.join(" "));
    }
}

/// The evaluator's final depth and parameters at the pixel against the frame's.
fn compare(
    text: &mut String,
    renderer: &Renderer,
    frame: &Frame,
    row: &eval::Tile,
    (px, py): (u32, u32),
    last_writer: Option<usize>,
    summary: &mut Summary,
) {
    let Some(i) = row.index(px as i32, py as i32) else {
        return;
    };
    let ours = row.depth[i];
    let theirs = frame.depth_at(px, py).unwrap_or(0);
    let mut differ = vec![];
    if ours != theirs {
        differ.push(format!(
            "depth: evaluator {}, frame {}",
            depth_text(ours),
            depth_text(theirs)
        ));
    }
    let mut compared = vec!["depth".to_string()];
    for p in renderer.shading_params() {
        let Some(frame_values) = frame.param_at(&p.name, px, py) else {
            continue;
        };
        let eval_values: Vec<f32> = (p.first_plane..p.first_plane + p.components)
            .map(|pl| {
                row.planes
                    .get(pl as usize * row.plane_stride + i)
                    .copied()
                    .unwrap_or(0.0)
            })
            .collect();
        let same = eval_values.len() == frame_values.len()
            && eval_values
                .iter()
                .zip(&frame_values)
                .all(|(a, b)| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()));
        compared.push(p.name.clone());
        if !same {
            let show = |v: &[f32]| v.iter().map(f32::to_string).collect::<Vec<_>>().join(" ");
            differ.push(format!(
                "{}: evaluator {}, frame {}",
                p.name,
                show(&eval_values),
                show(&frame_values)
            ));
        }
    }
    let writer = last_writer.map_or("no instance wrote Z".into(), |w| {
        format!("last Z written by instance {w}")
    });
    let _ = writeln!(text);
    match summary.agrees {
        None => {
            let _ = writeln!(
                text,
                "warning: not compared with the rendered frame: the evaluator could not run every instance"
            );
        }
        Some(_) if differ.is_empty() => {
            let _ = writeln!(
                text,
                "agrees with the rendered frame: {} at ({px}, {py}) equal bit for bit ({writer}; Z = {})",
                compared.join(", "),
                depth_text(theirs)
            );
        }
        Some(_) => {
            summary.agrees = Some(false);
            let _ = writeln!(
                text,
                "warning: the trace does NOT match the rendered frame at ({px}, {py}) ({writer}); the values above are the evaluator's:"
            );
            for d in differ {
                let _ = writeln!(text, "  {d}");
            }
        }
    }
}
