//! `primflow fuzz`: a campaign of generated and mutated inputs through the whole program,
//! on the stable toolchain.
//!
//! Input `i` of a campaign with seed `s` is a pure function of `(s, i)` and the corpus
//! ([`Corpus`]: the library, `tests/check/ok`, the example and test scenes and
//! `fuzz/corpus`), so any input can be regenerated from its number. Its class says what it is
//! and how far it goes:
//!
//! | class | input | run |
//! |---|---|---|
//! | `source` | a corpus primitive with random character spans replaced by tokens ([`mutate::splice`]) | parse and check, alone and with the library |
//! | `deep` | a deep or huge program ([`deep`]: sums, nested calls, casts, blocks, helper chains, long lines, many errors) | check, and when it checks, both JIT tiers |
//! | `prim` | a library primitive with literals and operators changed ([`mutate::literals`]) | check the library with it; render an example scene at both tiers |
//! | `scene` | an example or test scene, mutated | load and render (at most 128 x 128) at both tiers |
//! | `valid` | a generated valid program ([`gen`]) and a scene drawing it | both tiers, two tile sizes |
//!
//! Each input ends in one [`Outcome`]. Accepted or rejected with diagnostics are the good
//! ends; a finding is an internal compiler error (E0900 or a JIT panic it caught), a panic, a
//! signal (a stack overflow, an abort), a hang past the time limit, or a mismatch: frames of
//! tier 0 and tier 1, or of two tile sizes, that differ in one depth or plane bit (NaN
//! equals NaN). Panics are caught in the worker; signals and hangs are seen by the campaign
//! ([`campaign`]), which runs the inputs in worker processes and restarts a worker after
//! the input that killed it.

pub mod campaign;
pub mod deep;
pub mod gen;
pub mod mutate;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::diag::{Diagnostics, SourceMap};
use crate::jit::{Jit, Tier};
use crate::runtime::{Registry, Renderer};
use crate::workload::Lcg;

/// What an input is and how far it runs (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, clap::ValueEnum)]
pub enum Class {
    Source,
    Deep,
    Prim,
    Scene,
    Valid,
}

impl Class {
    pub const ALL: [Class; 5] = [Class::Source, Class::Deep, Class::Prim, Class::Scene, Class::Valid];

    pub fn name(self) -> &'static str {
        match self {
            Class::Source => "source",
            Class::Deep => "deep",
            Class::Prim => "prim",
            Class::Scene => "scene",
            Class::Valid => "valid",
        }
    }

    /// The class of input `i` of a mixed campaign: per 20 inputs, 11 source, 2 deep, 3 prim,
    /// 2 scene, 2 valid (the cheap classes most, the slow ones enough to matter).
    pub fn of(i: u64) -> Class {
        match i % 20 {
            0..=10 => Class::Source,
            11..=12 => Class::Deep,
            13..=15 => Class::Prim,
            16..=17 => Class::Scene,
            _ => Class::Valid,
        }
    }
}

/// How one input ended.
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome {
    /// It checked (and rendered, where its class renders).
    Accepted,
    /// Rejected with at least one error diagnostic: the code of the first.
    Rejected(String),
    /// An internal compiler error was reported.
    Ice(String),
    /// Frames that must be identical differ.
    Mismatch(String),
    /// A panic escaped (caught by the worker).
    Panic(String),
    /// The worker died on it (seen by the campaign).
    Signal(String),
    /// It ran past the time limit (seen by the campaign).
    Hang,
}

impl Outcome {
    pub fn is_finding(&self) -> bool {
        !matches!(self, Outcome::Accepted | Outcome::Rejected(_))
    }
}

/// One generated input: its class, a file name and its text.
pub struct Input {
    pub class: Class,
    pub name: String,
    pub text: String,
}

/// The texts the mutators start from.
pub struct Corpus {
    /// The library's `.prim` files (name, text), in name order.
    pub library: Vec<(String, String)>,
    /// Every primitive source: the library, `tests/check/ok`, `fuzz/corpus`.
    pub prims: Vec<(String, String)>,
    /// Every scene: `examples`, `prims/tests`, `fuzz/corpus`.
    pub scenes: Vec<(String, String)>,
    /// The example scenes alone (what `prim` inputs render).
    pub examples: Vec<(String, String)>,
}

impl Corpus {
    /// The corpus of the source tree this binary was built from.
    pub fn load() -> Result<Corpus, String> {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let library: Vec<(String, String)> = crate::runtime::LIBRARY
            .iter()
            .map(|(name, text)| (name.to_string(), text.to_string()))
            .collect();
        let mut prims = library.clone();
        prims.extend(read_dir(&root.join("tests/check/ok"), "prim")?);
        prims.extend(read_dir(&root.join("fuzz/corpus"), "prim")?);
        let examples = read_dir(&root.join("examples"), "scene")?;
        let mut scenes = examples.clone();
        scenes.extend(read_dir(&root.join("prims/tests"), "scene")?);
        scenes.extend(read_dir(&root.join("fuzz/corpus"), "scene")?);
        Ok(Corpus {
            library,
            prims,
            scenes,
            examples,
        })
    }
}

/// The files of `dir` ending in `.ext`, sorted by name.
fn read_dir(dir: &Path, ext: &str) -> Result<Vec<(String, String)>, String> {
    let entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut paths: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == ext))
        .collect();
    paths.sort();
    paths
        .iter()
        .map(|p| {
            let text = std::fs::read_to_string(p).map_err(|e| format!("{}: {e}", p.display()))?;
            let name = p
                .file_name()
                .map_or(String::new(), |n| n.to_string_lossy().into_owned());
            Ok((name, text))
        })
        .collect()
}

/// Input `i` of the campaign with `seed` (its class from [`Class::of`] unless `only` gives
/// one).
pub fn input(corpus: &Corpus, seed: u64, i: u64, only: Option<Class>) -> Input {
    let class = only.unwrap_or(Class::of(i));
    let mut rng = Lcg(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ i.wrapping_mul(0xd1b5_4a32_d192_ed03) ^ 0x5eed);
    rng.next();
    let pick = |rng: &mut Lcg, n: usize| (rng.next() * n as f64) as usize % n.max(1);
    let name = format!("{}-{i}", class.name());
    match class {
        Class::Source => {
            let (_, text) = &corpus.prims[pick(&mut rng, corpus.prims.len())];
            let edits: Vec<(usize, usize, usize)> = (0..1 + pick(&mut rng, 4))
                .map(|_| (pick(&mut rng, 1 << 20), pick(&mut rng, 24), pick(&mut rng, 1000)))
                .collect();
            let text = mutate::splice(text, mutate::PRIM_TOKENS, &edits);
            Input {
                class,
                name: name + ".prim",
                text,
            }
        }
        Class::Deep => Input {
            class,
            name: name + ".prim",
            text: deep::source(&mut rng),
        },
        Class::Prim => {
            let which = pick(&mut rng, corpus.library.len());
            let edits: Vec<(usize, usize)> = (0..1 + pick(&mut rng, 3))
                .map(|_| (pick(&mut rng, 100_000), pick(&mut rng, 1000)))
                .collect();
            let text = mutate::literals(&corpus.library[which].1, &edits);
            Input {
                class,
                name: corpus.library[which].0.clone(),
                text,
            }
        }
        Class::Scene => {
            let (_, text) = &corpus.scenes[pick(&mut rng, corpus.scenes.len())];
            let text = if rng.next() < 0.6 {
                let edits: Vec<(usize, usize)> = (0..1 + pick(&mut rng, 3))
                    .map(|_| (pick(&mut rng, 100_000), pick(&mut rng, 1000)))
                    .collect();
                mutate::literals(text, &edits)
            } else {
                let edits: Vec<(usize, usize, usize)> = (0..1 + pick(&mut rng, 3))
                    .map(|_| (pick(&mut rng, 1 << 20), pick(&mut rng, 24), pick(&mut rng, 1000)))
                    .collect();
                mutate::splice(text, mutate::SCENE_TOKENS, &edits)
            };
            Input {
                class,
                name: name + ".scene",
                text,
            }
        }
        Class::Valid => Input {
            class,
            name: name + ".prim",
            text: gen::program_source(seed ^ i.wrapping_mul(0x2545_f491_4f6c_dd1d)),
        },
    }
}

/// Run `input` to its outcome (a panic escapes to the caller).
pub fn run(corpus: &Corpus, input: &Input) -> Outcome {
    match input.class {
        Class::Source => check_source(input),
        Class::Deep => match check_source(input) {
            Outcome::Accepted => jit_all(input),
            other => other,
        },
        Class::Prim => prim(corpus, input),
        Class::Scene => scene(input),
        Class::Valid => valid(corpus, input),
    }
}

/// The first error's code, or an ICE.
fn judge(diags: &Diagnostics) -> Outcome {
    if let Some(d) = diags
        .items
        .iter()
        .find(|d| d.code == "E0900" || d.message.contains("internal compiler error"))
    {
        return Outcome::Ice(format!("{}: {}", d.code, d.message));
    }
    match diags.items.iter().find(|d| d.severity == crate::diag::Severity::Error) {
        Some(d) => Outcome::Rejected(d.code.to_string()),
        None => Outcome::Accepted,
    }
}

/// Parse and check the input alone, then with the library; every diagnostic must render.
fn check_source(input: &Input) -> Outcome {
    let mut sources = SourceMap::new();
    let file = sources.add(input.name.clone(), input.text.clone());
    let mut diags = Diagnostics::new();
    let alone = crate::compile(&sources, &[file], &mut diags);
    let _ = diags.render(&sources);
    if alone.is_some() || judge(&diags).is_finding() {
        return judge(&diags);
    }
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    let (mut files, _) = Registry::load_sources(&mut sources, &[], &[], &mut diags);
    files.push(sources.add(input.name.clone(), input.text.clone()));
    let _ = Registry::compile(&sources, files, &mut diags);
    let _ = diags.render(&sources);
    judge(&diags)
}

/// Compile every primitive of the input (alone) under the default key at both tiers.
fn jit_all(input: &Input) -> Outcome {
    let mut sources = SourceMap::new();
    let file = sources.add(input.name.clone(), input.text.clone());
    let mut diags = Diagnostics::new();
    let Some(program) = crate::compile(&sources, &[file], &mut diags) else {
        return judge(&diags);
    };
    let program = Arc::new(program);
    for tier in [Tier::Fast, Tier::Optimised] {
        let Ok(mut jit) = Jit::at_tier(program.clone(), tier) else {
            return Outcome::Accepted;
        };
        for (i, f) in program.functions.iter().enumerate() {
            if f.kind != crate::ir::FuncKind::Primitive {
                continue;
            }
            if let Err(e) = jit.kernel(crate::ir::FuncId(i as u32), &Default::default()) {
                if e.message.contains("internal compiler error") || e.message.contains("panic") {
                    return Outcome::Ice(e.message);
                }
            }
        }
    }
    Outcome::Accepted
}

/// The library with one file replaced by the input; an example scene rendered with it.
fn prim(corpus: &Corpus, input: &Input) -> Outcome {
    let mut sources = SourceMap::new();
    let files: Vec<_> = corpus
        .library
        .iter()
        .map(|(name, text)| {
            let text = if *name == input.name { &input.text } else { text };
            sources.add(name.clone(), text.clone())
        })
        .collect();
    let mut diags = Diagnostics::new();
    let program = crate::compile(&sources, &files, &mut diags);
    let _ = diags.render(&sources);
    let Some(program) = program else {
        return judge(&diags);
    };
    let program = Arc::new(program);
    let which = input.text.len() % corpus.examples.len().max(1);
    let Some((name, text)) = corpus.examples.get(which) else {
        return Outcome::Accepted;
    };
    let file = sources.add(name.clone(), resized(text, 40, 30));
    compare_tiers(None, || {
        let mut r = Renderer::new(program.clone());
        let mut diags = Diagnostics::new();
        crate::scene::load_into(&sources, file, &mut r, &mut diags);
        (sources.clone(), r, diags)
    })
}

/// Load and render a scene (at most 128 x 128 pixels).
fn scene(input: &Input) -> Outcome {
    let base = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    compare_tiers(None, || {
        let mut sources = SourceMap::new();
        let file = sources.add(input.name.clone(), input.text.clone());
        let mut diags = Diagnostics::new();
        let r = crate::scene::load_for_render(&mut sources, file, &base, &[], &mut diags);
        let mut r = r.unwrap_or_else(|| Renderer::new(Arc::default()));
        let (w, h) = (r.options.width, r.options.height);
        if w > 128 || h > 128 {
            let _ = r.set_image_size(w.min(128), h.min(128));
        }
        (sources, r, diags)
    })
}

/// The generated program with the library, drawn by a generated scene at both tiers and
/// two tile sizes.
fn valid(corpus: &Corpus, input: &Input) -> Outcome {
    let mut sources = SourceMap::new();
    let mut files: Vec<_> = corpus
        .library
        .iter()
        .map(|(name, text)| sources.add(name.clone(), text.clone()))
        .collect();
    files.push(sources.add(input.name.clone(), input.text.clone()));
    let mut diags = Diagnostics::new();
    let program = crate::compile(&sources, &files, &mut diags);
    let _ = diags.render(&sources);
    let Some(program) = program else {
        return judge(&diags);
    };
    let mut rng = Lcg(input.text.len() as u64 ^ 0xfeed);
    let file = sources.add("valid.scene", valid_scene(&mut rng));
    let program = Arc::new(program);
    compare_tiers(Some(8), || {
        let mut r = Renderer::new(program.clone());
        let mut diags = Diagnostics::new();
        crate::scene::load_into(&sources, file, &mut r, &mut diags);
        (sources.clone(), r, diags)
    })
}

/// A scene drawing `gen` (see [`gen::program_source`]) two or three times with random
/// arguments.
fn valid_scene(rng: &mut Lcg) -> String {
    let mut s = String::from("image 40 24\northo 0 40 0 24 -1 1\n");
    for _ in 0..2 + (rng.next() * 2.0) as usize {
        s.push_str("begin gen\n");
        for p in ["p0", "p1", "p2", "p3"] {
            s.push_str(&format!("rast_param {p} {:.3}\n", rng.range(-4.0, 44.0)));
        }
        for p in ["n0", "n1"] {
            s.push_str(&format!("rast_param {p} {}\n", (rng.next() * 9.0) as i32 - 2));
        }
        let fa: Vec<String> = (0..5).map(|_| format!("{:.3}", rng.range(-3.0, 3.0))).collect();
        s.push_str(&format!("rast_param fa {}\n", fa.join(" ")));
        let ia: Vec<String> = (0..3).map(|_| format!("{}", (rng.next() * 9.0) as i32 - 2)).collect();
        s.push_str(&format!("rast_param ia {}\n", ia.join(" ")));
        for _ in 0..1 + (rng.next() * 3.0) as usize {
            s.push_str("sequence_point\n");
        }
        s.push_str("end\n");
    }
    s
}

/// `text` with its `image` line made `w` x `h`.
fn resized(text: &str, w: u32, h: u32) -> String {
    text.lines()
        .map(|l| {
            if l.trim_start().starts_with("image ") {
                format!("image {w} {h}")
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// Render the scene `load` gives at tier 0 and tier 1 (and with tile side `other_tile` at
/// tier 1); the frames must agree bit for bit (any NaN equals any NaN). A scene with errors
/// ends there.
fn compare_tiers(other_tile: Option<u32>, mut load: impl FnMut() -> (SourceMap, Renderer, Diagnostics)) -> Outcome {
    let mut frames = vec![];
    let mut runs: Vec<(Tier, Option<u32>)> = vec![(Tier::Fast, None), (Tier::Optimised, None)];
    if let Some(t) = other_tile {
        runs.push((Tier::Optimised, Some(t)));
    }
    // One JIT per tier: the second tile size reuses tier 1's kernels (the same program).
    let mut jits: Vec<(Tier, Jit)> = vec![];
    for (tier, tile) in runs {
        let (sources, mut r, diags) = load();
        let _ = diags.render(&sources);
        if diags.has_errors() {
            return judge(&diags);
        }
        let at = match jits.iter().position(|(t, _)| *t == tier) {
            Some(at) => at,
            None => {
                let Ok(jit) = Jit::at_tier(r.program().clone(), tier) else {
                    return Outcome::Accepted;
                };
                jits.push((tier, jit));
                jits.len() - 1
            }
        };
        let jit = &mut jits[at].1;
        if let Some(t) = tile {
            let _ = r.set_tile_size(t);
        }
        // Small budgets: an endless loop ends fast, the same way at every tier.
        r.options.setup_fuel = 1 << 14;
        r.options.pixel_fuel = 1 << 12;
        r.options.group_fuel_floor = crate::abi::DEFAULT_GROUP_FUEL_FLOOR / 16;
        let out = r.render(jit);
        let _ = out.diags.render(&sources);
        if let Outcome::Ice(m) = judge(&out.diags) {
            return Outcome::Ice(format!("{tier:?}: {m}"));
        }
        frames.push((format!("{tier:?} tile {tile:?}"), out.frame));
    }
    let (first_name, first) = &frames[0];
    for (name, f) in &frames[1..] {
        if f.depth != first.depth {
            return Outcome::Mismatch(format!("depth: {first_name} vs {name}"));
        }
        let same = f
            .planes
            .iter()
            .zip(&first.planes)
            .all(|(a, b)| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()));
        if !same || f.planes.len() != first.planes.len() {
            return Outcome::Mismatch(format!("planes: {first_name} vs {name}"));
        }
    }
    Outcome::Accepted
}
