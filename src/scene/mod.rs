//! The text scene format: one API call per line (docs/scene.md).
//!
//! Reading a scene has two steps, because a scene may name extra primitive directories
//! (`prims DIR`) that must be compiled before its primitive names mean anything:
//! 1. [`parse`] splits the text into [`Command`]s: tokens are whitespace-separated, `#` starts
//!    a comment, numbers are f32 (`inf` and `nan` included: they pass through to the kernels).
//!    Unknown commands, wrong arity and bad numbers are reported here; a bad line is kept as
//!    [`CommandKind::Invalid`] so the next step can keep block structure.
//! 2. [`apply`] makes the calls on a [`Renderer`] and turns its errors and warnings into
//!    diagnostics at the offending token (unknown primitive or parameter, wrong component
//!    count, `vertex` outside `begin`/`end`, ...).
//!
//! Both steps go on after an error and report every problem they find; neither panics on any
//! input. Every diagnostic names `file:line:col` of the scene file (added to the caller's
//! [`SourceMap`]).

use std::path::{Path, PathBuf};

use crate::diag::{Diagnostic, Diagnostics, FileId, SourceMap, Span};
use crate::pipeline::face::CullMode;
use crate::runtime::shading::language::ShaderArg;
use crate::runtime::shading::{Fog, LightingSpaceChoice, SceneLight, SurfaceMaterial, Texture};
use crate::runtime::{ApiIssue, Renderer, Target, Value};

/// Which side(s) a `surface` line sets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SurfaceSides {
    Front,
    Back,
    Both,
}

/// One whitespace-separated token and where it is.
#[derive(Clone, Debug, PartialEq)]
pub struct Token {
    pub text: String,
    pub span: Span,
}

/// Which language shader a command binds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShaderCommand {
    Surface,
    Light,
    Atmosphere,
}

#[derive(Clone, Debug, PartialEq)]
pub enum CommandKind {
    Image {
        width: u32,
        height: u32,
    },
    Background([f32; 3]),
    Tile(u32),
    /// `samples N [FILTER]`: samples per pixel and how they resolve.
    Samples(u32, Option<crate::runtime::samples::Filter>),
    Prims(String),
    Transform([f32; 16]),
    Ortho([f32; 6]),
    Perspective([f32; 3]),
    /// `material_interp NAME KIND [arg=v[,v...] [v ...]]...`
    MaterialInterp {
        name: String,
        kind: String,
        args: Vec<(String, Value)>,
    },
    Material {
        name: String,
        value: Value,
    },
    Begin(String),
    RastParam {
        name: String,
        value: Value,
    },
    SequencePoint,
    Vertex([f32; 4]),
    End,
    /// Model stack and camera (docs/scene.md, "Transforms").
    Push,
    Pop,
    Translate([f32; 3]),
    Rotate([f32; 4]),
    Scale([f32; 3]),
    Concat([f32; 16]),
    Model([f32; 16]),
    LookAt([f32; 9]),
    Oblique([f32; 9]),
    View([f32; 16]),
    ClipPlane([f32; 4]),
    Cull(CullMode),
    Distinguish(bool),
    /// Lights, materials and the shading effects.
    Light(SceneLight),
    Ambient([f32; 3]),
    /// `surface front|back|both ka kd ks shininess [sr sg sb]`
    Surface {
        sides: SurfaceSides,
        material: SurfaceMaterial,
    },
    Fog(Fog),
    /// `shader NAME [ARG=v...]`, `lightsource NAME [ARG=v...]`, `atmosphere NAME [ARG=v...]`.
    Shader {
        kind: ShaderCommand,
        name: String,
        args: Vec<(String, ShaderArg)>,
    },
    Texture(Texture),
    /// `shading_pass rust|language`: whether the fixed shading lines run as library
    /// shaders (`language`) or in the Rust pass (`rust`, the default).
    ShadingPass(bool),
    LightingSpace(LightingSpaceChoice),
    /// A line that failed to parse; the command word if it was a known one (so a broken
    /// `begin` still opens a block and a broken `end` still closes it).
    Invalid(Option<String>),
}

/// One scene line: its tokens (the first is the command word) and what it says.
#[derive(Clone, Debug, PartialEq)]
pub struct Command {
    pub kind: CommandKind,
    pub tokens: Vec<Token>,
    /// The token span of each `material_interp` argument (`name=...` and its values).
    pub arg_spans: Vec<Span>,
}

/// Largest scene file, in bytes (E0606, before the file is read). Spans are 32-bit offsets;
/// and a scene of triangles takes about 20 bytes of memory per byte of text once parsed and
/// applied (a 300 MB one peaks at 6 GB), so this keeps a scene within a workstation's memory.
pub const MAX_SCENE_BYTES: u64 = 1 << 30;

/// Read the scene file at `path`, refusing one larger than [`MAX_SCENE_BYTES`] before
/// reading it. Errors: the message to print.
pub fn read_file(path: &Path) -> Result<String, String> {
    let cannot = |e: std::io::Error| format!("cannot read scene `{}`: {e}", path.display());
    let len = std::fs::metadata(path).map_err(cannot)?.len();
    if len > MAX_SCENE_BYTES {
        return Err(format!(
            "scene `{}` is {len} bytes, more than the limit of {MAX_SCENE_BYTES} (E0606); nothing rendered",
            path.display()
        ));
    }
    std::fs::read_to_string(path).map_err(cannot)
}

/// A parsed scene.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Scene {
    pub file: FileId,
    pub commands: Vec<Command>,
}

impl Scene {
    /// The `prims DIR` directories, resolved against `base` (the scene file's directory).
    pub fn prim_dirs(&self, base: &Path) -> Vec<PathBuf> {
        self.commands
            .iter()
            .filter_map(|c| match &c.kind {
                CommandKind::Prims(dir) => Some(base.join(dir)),
                _ => None,
            })
            .collect()
    }

    /// The library names the scene uses: the primitives its `begin`s name, and the kinds its
    /// `material_interp`s name (a kind that is a shared interpolator's name is that
    /// interpolator). What [`crate::runtime::Registry::load_for`] compiles the scene with.
    pub fn library_names(&self) -> (Vec<&str>, Vec<&str>) {
        let (mut prims, mut kinds) = (vec![], vec![]);
        for c in &self.commands {
            match &c.kind {
                CommandKind::Begin(name) => prims.push(name.as_str()),
                CommandKind::MaterialInterp { kind, .. } => kinds.push(kind.as_str()),
                CommandKind::ShadingPass(true) => kinds.push("fixed_phong"),
                CommandKind::Shader { name, .. } => {
                    kinds.push(name.as_str());
                    kinds.push(crate::runtime::shading::language::DEFAULT_SURFACE);
                }
                _ => {}
            }
        }
        (prims, kinds)
    }
}

const COMMANDS: &[&str] = &[
    "image",
    "background",
    "tile",
    "samples",
    "prims",
    "transform",
    "ortho",
    "perspective",
    "material_interp",
    "material",
    "begin",
    "rast_param",
    "sequence_point",
    "vertex",
    "end",
    "push",
    "pop",
    "translate",
    "rotate",
    "scale",
    "concat",
    "model",
    "look_at",
    "oblique",
    "view",
    "clip_plane",
    "cull",
    "distinguish",
    "light",
    "ambient",
    "surface",
    "fog",
    "texture",
    "shader",
    "lightsource",
    "atmosphere",
    "lighting_space",
    "shading_pass",
];

/// Split a line into tokens, stopping at `#`.
fn tokenize(file: FileId, line: &str, line_start: usize) -> Vec<Token> {
    let code = match line.find('#') {
        Some(i) => &line[..i],
        None => line,
    };
    let mut tokens = vec![];
    let mut start = None;
    for (i, c) in code.char_indices().chain(std::iter::once((code.len(), ' '))) {
        match (c.is_whitespace(), start) {
            (true, Some(s)) => {
                tokens.push(Token {
                    text: code[s..i].to_string(),
                    span: Span::new(file, line_start + s, line_start + i),
                });
                start = None;
            }
            (false, None) => start = Some(i),
            _ => {}
        }
    }
    tokens
}

/// Parse the scene text of `file`. Syntax errors go to `diags`.
pub fn parse(sources: &SourceMap, file: FileId, diags: &mut Diagnostics) -> Scene {
    let text = sources.text(file);
    let mut commands = vec![];
    let mut line_start = 0;
    for line in text.split_inclusive('\n') {
        let tokens = tokenize(file, line.trim_end_matches(['\n', '\r']), line_start);
        line_start += line.len();
        if tokens.is_empty() {
            continue;
        }
        let (kind, arg_spans) = match parse_command(&tokens) {
            Ok(parsed) => parsed,
            Err(d) => {
                diags.push(d);
                let word = &tokens[0].text;
                (
                    CommandKind::Invalid(COMMANDS.contains(&word.as_str()).then(|| word.clone())),
                    vec![],
                )
            }
        };
        commands.push(Command {
            kind,
            tokens,
            arg_spans,
        });
    }
    Scene { file, commands }
}

fn span_of(tokens: &[Token]) -> Span {
    match (tokens.first(), tokens.last()) {
        (Some(a), Some(b)) => a.span.to(b.span),
        _ => Span::default(),
    }
}

fn arity_error(tokens: &[Token], expected: &str) -> Diagnostic {
    let cmd = &tokens[0];
    let given = tokens.len() - 1;
    let d = Diagnostic::error(
        "E0602",
        format!(
            "`{}` takes {expected}, got {given} argument{}",
            cmd.text,
            if given == 1 { "" } else { "s" }
        ),
    );
    if given > 0 {
        d.primary(span_of(&tokens[1..]), "wrong number of arguments")
            .secondary(cmd.span, "this command")
    } else {
        d.primary(cmd.span, "arguments missing")
    }
}

fn number(token: &Token) -> Result<f32, Diagnostic> {
    token.text.parse::<f32>().map_err(|_| {
        Diagnostic::error("E0603", format!("`{}` is not a number", token.text)).primary(token.span, "expected a number")
    })
}

fn numbers(tokens: &[Token]) -> Result<Vec<f32>, Diagnostic> {
    tokens.iter().map(number).collect()
}

fn fixed_numbers<const N: usize>(tokens: &[Token]) -> Result<[f32; N], Diagnostic> {
    if tokens.len() != N + 1 {
        return Err(arity_error(tokens, &format!("{N} numbers")));
    }
    let v = numbers(&tokens[1..])?;
    Ok(std::array::from_fn(|i| v[i]))
}

/// A whole positive number (image size, tile size).
fn count(token: &Token, what: &str) -> Result<u32, Diagnostic> {
    let v = number(token)?;
    if v.fract() != 0.0 || !(1.0..=1_000_000.0).contains(&v) {
        return Err(Diagnostic::error(
            "E0604",
            format!("{what} must be a positive whole number, got `{}`", token.text),
        )
        .primary(token.span, "not a positive whole number"));
    }
    Ok(v as u32)
}

fn name_and_values(tokens: &[Token]) -> Result<(String, Value), Diagnostic> {
    if tokens.len() < 3 {
        return Err(arity_error(tokens, "a name and at least one number"));
    }
    Ok((tokens[1].text.clone(), Value(numbers(&tokens[2..])?)))
}

fn parse_command(tokens: &[Token]) -> Result<(CommandKind, Vec<Span>), Diagnostic> {
    let cmd = &tokens[0];
    let n_args = tokens.len() - 1;
    let kind = match cmd.text.as_str() {
        "image" => {
            if n_args != 2 {
                return Err(arity_error(tokens, "2 numbers (width height)"));
            }
            CommandKind::Image {
                width: count(&tokens[1], "image width")?,
                height: count(&tokens[2], "image height")?,
            }
        }
        "background" => CommandKind::Background(fixed_numbers::<3>(tokens)?),
        "tile" => {
            if n_args != 1 {
                return Err(arity_error(tokens, "1 number (the tile side)"));
            }
            CommandKind::Tile(count(&tokens[1], "tile size")?)
        }
        "samples" => {
            if n_args != 1 && n_args != 2 {
                return Err(arity_error(
                    tokens,
                    "1 number (samples per pixel) and optionally a filter (box or gaussian)",
                ));
            }
            let filter = match tokens.get(2) {
                None => None,
                Some(t) => Some(crate::runtime::samples::Filter::parse(&t.text).ok_or_else(|| {
                    Diagnostic::error(
                        "E0604",
                        format!("unknown sample filter `{}`: use box or gaussian", t.text),
                    )
                    .primary(t.span, "not a filter")
                })?),
            };
            CommandKind::Samples(count(&tokens[1], "sample count")?, filter)
        }
        "prims" => {
            if n_args != 1 {
                return Err(arity_error(tokens, "1 directory"));
            }
            CommandKind::Prims(tokens[1].text.clone())
        }
        "transform" => CommandKind::Transform(fixed_numbers::<16>(tokens)?),
        "ortho" => CommandKind::Ortho(fixed_numbers::<6>(tokens)?),
        "perspective" => CommandKind::Perspective(fixed_numbers::<3>(tokens)?),
        "material_interp" => return parse_material_interp(tokens),
        "shader" | "lightsource" | "atmosphere" => {
            if tokens.len() < 2 {
                return Err(arity_error(tokens, "a shader name and `name=value` arguments"));
            }
            let kind = match tokens[0].text.as_str() {
                "shader" => ShaderCommand::Surface,
                "lightsource" => ShaderCommand::Light,
                _ => ShaderCommand::Atmosphere,
            };
            let (args, spans) = shader_args(&tokens[2..])?;
            return Ok((
                CommandKind::Shader {
                    kind,
                    name: tokens[1].text.clone(),
                    args,
                },
                spans,
            ));
        }
        "material" => {
            let (name, value) = name_and_values(tokens)?;
            CommandKind::Material { name, value }
        }
        "rast_param" => {
            let (name, value) = name_and_values(tokens)?;
            CommandKind::RastParam { name, value }
        }
        "begin" => {
            if n_args != 1 {
                return Err(arity_error(tokens, "1 primitive name"));
            }
            CommandKind::Begin(tokens[1].text.clone())
        }
        "sequence_point" | "end" if n_args != 0 => return Err(arity_error(tokens, "no arguments")),
        "sequence_point" => CommandKind::SequencePoint,
        "end" => CommandKind::End,
        "vertex" => {
            if !(3..=4).contains(&n_args) {
                return Err(arity_error(tokens, "3 or 4 numbers (x y z [w])"));
            }
            let v = numbers(&tokens[1..])?;
            CommandKind::Vertex([v[0], v[1], v[2], v.get(3).copied().unwrap_or(1.0)])
        }
        "push" | "pop" if n_args != 0 => return Err(arity_error(tokens, "no arguments")),
        "push" => CommandKind::Push,
        "pop" => CommandKind::Pop,
        "translate" => CommandKind::Translate(fixed_numbers::<3>(tokens)?),
        "rotate" => CommandKind::Rotate(fixed_numbers::<4>(tokens)?),
        "scale" => CommandKind::Scale(fixed_numbers::<3>(tokens)?),
        "concat" => CommandKind::Concat(fixed_numbers::<16>(tokens)?),
        "model" => CommandKind::Model(fixed_numbers::<16>(tokens)?),
        "look_at" => CommandKind::LookAt(fixed_numbers::<9>(tokens)?),
        "oblique" => CommandKind::Oblique(fixed_numbers::<9>(tokens)?),
        "view" => CommandKind::View(fixed_numbers::<16>(tokens)?),
        "clip_plane" => CommandKind::ClipPlane(fixed_numbers::<4>(tokens)?),
        "cull" => CommandKind::Cull(match word_arg(tokens, &["none", "back", "front"])? {
            "back" => CullMode::Back,
            "front" => CullMode::Front,
            _ => CullMode::None,
        }),
        "distinguish" => CommandKind::Distinguish(word_arg(tokens, &["on", "off"])? == "on"),
        "shading_pass" => CommandKind::ShadingPass(word_arg(tokens, &["rust", "language"])? == "language"),
        "lighting_space" => CommandKind::LightingSpace(match word_arg(tokens, &["lc", "wc", "dc"])? {
            "wc" => LightingSpaceChoice::World,
            "dc" => LightingSpaceChoice::Device,
            _ => LightingSpaceChoice::Lighting,
        }),
        "ambient" => CommandKind::Ambient(fixed_numbers::<3>(tokens)?),
        "light" => CommandKind::Light(parse_light(tokens)?),
        "surface" => parse_surface(tokens)?,
        "fog" => {
            let [r, g, b, start, end] = fixed_numbers::<5>(tokens)?;
            CommandKind::Fog(Fog {
                colour: [r, g, b].map(f64::from),
                start: f64::from(start),
                end: f64::from(end),
            })
        }
        "texture" => {
            // texture checker PARAM SCALE [DARK]
            if !(3..=4).contains(&n_args) || tokens[1].text != "checker" {
                return Err(arity_error(tokens, "`checker PARAM SCALE [DARK]`"));
            }
            let v = numbers(&tokens[3..])?;
            CommandKind::Texture(Texture {
                param: tokens[2].text.clone(),
                scale: f64::from(v[0]),
                dark: f64::from(v.get(1).copied().unwrap_or(0.5)),
            })
        }
        other => {
            return Err(Diagnostic::error("E0601", format!("unknown command `{other}`"))
                .primary(cmd.span, "unknown command")
                .suggest(other, COMMANDS.iter().copied()));
        }
    };
    Ok((kind, vec![]))
}

/// The one word argument of `cull`, `distinguish`, `lighting_space`.
fn word_arg<'t>(tokens: &'t [Token], allowed: &[&str]) -> Result<&'t str, Diagnostic> {
    if tokens.len() != 2 {
        return Err(arity_error(tokens, &format!("one of {}", allowed.join(", "))));
    }
    let word = tokens[1].text.as_str();
    if allowed.contains(&word) {
        Ok(word)
    } else {
        Err(
            Diagnostic::error("E0604", format!("`{word}` is not one of {}", allowed.join(", ")))
                .primary(tokens[1].span, "unknown choice")
                .suggest(word, allowed.iter().copied()),
        )
    }
}

/// `light directional DX DY DZ R G B` or `light point X Y Z R G B [C0 C1 C2]` (world space).
fn parse_light(tokens: &[Token]) -> Result<SceneLight, Diagnostic> {
    let kind = tokens.get(1).map(|t| t.text.as_str());
    let n = tokens.len().saturating_sub(2);
    match kind {
        Some("directional") if n == 6 => {
            let v: Vec<f64> = numbers(&tokens[2..])?.into_iter().map(f64::from).collect();
            Ok(SceneLight::Directional {
                towards_light: [v[0], v[1], v[2]],
                colour: [v[3], v[4], v[5]],
            })
        }
        Some("point") if n == 6 || n == 9 => {
            let v: Vec<f64> = numbers(&tokens[2..])?.into_iter().map(f64::from).collect();
            Ok(SceneLight::Positional {
                position: [v[0], v[1], v[2]],
                colour: [v[3], v[4], v[5]],
                attenuation: if n == 9 { [v[6], v[7], v[8]] } else { [1.0, 0.0, 0.0] },
            })
        }
        _ => Err(arity_error(
            tokens,
            "`directional DX DY DZ R G B` or `point X Y Z R G B [C0 C1 C2]`",
        )),
    }
}

/// `surface front|back|both KA KD KS SHININESS [SR SG SB]`.
fn parse_surface(tokens: &[Token]) -> Result<CommandKind, Diagnostic> {
    let n = tokens.len().saturating_sub(2);
    if n != 4 && n != 7 {
        return Err(arity_error(tokens, "`front|back|both KA KD KS SHININESS [SR SG SB]`"));
    }
    let sides = match word_arg(&tokens[..2], &["front", "back", "both"])? {
        "front" => SurfaceSides::Front,
        "back" => SurfaceSides::Back,
        _ => SurfaceSides::Both,
    };
    let v: Vec<f64> = numbers(&tokens[2..])?.into_iter().map(f64::from).collect();
    Ok(CommandKind::Surface {
        sides,
        material: SurfaceMaterial {
            ka: v[0],
            kd: v[1],
            ks: v[2],
            shininess: v[3],
            specular_colour: if n == 7 { [v[4], v[5], v[6]] } else { [1.0; 3] },
        },
    })
}

/// `material_interp NAME KIND arg=v[,v...] [v ...]`: bare numbers after an argument add
/// components to it (`axis=0 0 1`).
fn parse_material_interp(tokens: &[Token]) -> Result<(CommandKind, Vec<Span>), Diagnostic> {
    if tokens.len() < 3 {
        return Err(arity_error(tokens, "a parameter name and an interpolation kind"));
    }
    let (args, spans) = named_args(&tokens[3..])?;
    Ok((
        CommandKind::MaterialInterp {
            name: tokens[1].text.clone(),
            kind: tokens[2].text.clone(),
            args,
        },
        spans,
    ))
}

/// A shader's arguments: `name="text"` (no spaces inside the quotes) for a `string`
/// parameter, the rest as [`named_args`].
fn shader_args(tokens: &[Token]) -> Result<(Vec<(String, ShaderArg)>, Vec<Span>), Diagnostic> {
    let mut args = vec![];
    let mut spans = vec![];
    let mut numbers: Vec<Token> = vec![];
    let flush = |numbers: &mut Vec<Token>, args: &mut Vec<_>, spans: &mut Vec<Span>| -> Result<(), Diagnostic> {
        let (a, s) = named_args(numbers)?;
        args.extend(a.into_iter().map(|(n, v)| (n, ShaderArg::Numbers(v))));
        spans.extend(s);
        numbers.clear();
        Ok(())
    };
    for token in tokens {
        let text = token.text.split_once('=').and_then(|(name, value)| {
            let inner = value.strip_prefix('"')?.strip_suffix('"')?;
            Some((name, inner))
        });
        match text {
            Some((name, inner)) if !name.is_empty() => {
                flush(&mut numbers, &mut args, &mut spans)?;
                args.push((name.to_string(), ShaderArg::Text(inner.to_string())));
                spans.push(token.span);
            }
            _ => numbers.push(token.clone()),
        }
    }
    flush(&mut numbers, &mut args, &mut spans)?;
    Ok((args, spans))
}

/// `name=v[,v...]` arguments, a name's further values as separate tokens allowed
/// (`axis=0 0 1`), with each argument's span.
fn named_args(tokens: &[Token]) -> Result<(Vec<(String, Value)>, Vec<Span>), Diagnostic> {
    let mut args: Vec<(String, Value)> = vec![];
    let mut spans: Vec<Span> = vec![];
    for token in tokens {
        if let Some((name, values)) = token.text.split_once('=') {
            if name.is_empty() {
                return Err(
                    Diagnostic::error("E0604", "argument without a name").primary(token.span, "expected `name=value`")
                );
            }
            let mut value = vec![];
            for part in values.split(',').filter(|p| !p.is_empty()) {
                value.push(number(&Token {
                    text: part.to_string(),
                    span: token.span,
                })?);
            }
            args.push((name.to_string(), Value(value)));
            spans.push(token.span);
        } else if let Some(last) = args.last_mut() {
            last.1 .0.push(number(token)?);
            if let Some(s) = spans.last_mut() {
                *s = s.to(token.span);
            }
        } else {
            return Err(
                Diagnostic::error("E0604", format!("`{}` is not a `name=value` argument", token.text))
                    .primary(token.span, "expected `name=value`"),
            );
        }
    }
    if let Some((i, _)) = args.iter().enumerate().find(|(_, (_, v))| v.is_empty()) {
        return Err(
            Diagnostic::error("E0604", format!("argument `{}` has no value", args[i].0))
                .primary(spans[i], "expected `name=number`"),
        );
    }
    Ok((args, spans))
}

/// The instances one `begin` ... `end` object of a scene became: its `begin` word and
/// their indices in [`Renderer::instances`] (none for an object that was culled, clipped
/// away or rejected; several for a polygon, polyline or point set).
#[derive(Clone, Debug, PartialEq)]
pub struct SceneObject {
    pub begin: Span,
    pub instances: std::ops::Range<usize>,
}

/// Make the scene's calls on `renderer`. API errors and warnings go to `diags` at the
/// offending token.
pub fn apply(scene: &Scene, renderer: &mut Renderer, diags: &mut Diagnostics) {
    apply_objects(scene, renderer, diags);
}

/// [`apply`], returning which instances each object that made some became, in order.
pub fn apply_objects(scene: &Scene, renderer: &mut Renderer, diags: &mut Diagnostics) -> Vec<SceneObject> {
    let mut open_begin: Option<Span> = None;
    let mut objects = vec![];
    let mut last_begin: Option<Span> = None;
    for c in &scene.commands {
        let before = renderer.instances().len();
        if matches!(c.kind, CommandKind::Begin(_)) {
            last_begin = Some(c.tokens[0].span);
        }
        let result = match &c.kind {
            CommandKind::Image { width, height } => renderer.set_image_size(*width, *height),
            CommandKind::Background(rgb) => {
                renderer.set_background(*rgb);
                Ok(())
            }
            CommandKind::Tile(side) => renderer.set_tile_size(*side),
            CommandKind::Samples(n, filter) => {
                if let Some(filter) = filter {
                    renderer.set_filter(*filter);
                }
                renderer.set_samples(*n)
            }
            CommandKind::Prims(_) => Ok(()),
            CommandKind::Transform(rows) => {
                renderer.set_transform(crate::runtime::transform::from_rows(rows));
                Ok(())
            }
            CommandKind::Ortho([l, r, b, t, n, f]) => {
                renderer.ortho_checked([*l, *r, *b, *t].map(f64::from), f64::from(*n), f64::from(*f))
            }
            CommandKind::Perspective([fov, n, f]) => {
                renderer.perspective_checked(f64::from(*fov), f64::from(*n), f64::from(*f))
            }
            CommandKind::MaterialInterp { name, kind, args } => renderer.material_interp(name, kind, args),
            CommandKind::Shader { kind, name, args } => match kind {
                ShaderCommand::Surface => renderer.surface_shader(name, args),
                ShaderCommand::Light => renderer.light_shader(name, args),
                ShaderCommand::Atmosphere => renderer.atmosphere_shader(name, args),
            },
            CommandKind::Push => {
                renderer.push_transform();
                Ok(())
            }
            CommandKind::Pop => renderer.pop_transform(),
            CommandKind::Translate(t) => renderer.translate(t.map(f64::from)),
            CommandKind::Rotate([deg, x, y, z]) => renderer.rotate(f64::from(*deg), [*x, *y, *z].map(f64::from)),
            CommandKind::Scale(v) => renderer.scale(v.map(f64::from)),
            CommandKind::Concat(rows) => renderer.concat(dmat_from_rows(rows)),
            CommandKind::Model(rows) => renderer.set_model(dmat_from_rows(rows)),
            CommandKind::LookAt(v) => {
                let v = v.map(f64::from);
                renderer.look_at([v[0], v[1], v[2]], [v[3], v[4], v[5]], [v[6], v[7], v[8]])
            }
            CommandKind::Oblique(v) => {
                let v = v.map(f64::from);
                renderer.oblique([v[0], v[1], v[2], v[3]], v[4], v[5], [v[6], v[7], v[8]])
            }
            CommandKind::View(rows) => renderer.view_matrix(dmat_from_rows(rows)),
            CommandKind::ClipPlane(p) => renderer.clip_plane(p.map(f64::from)),
            CommandKind::Cull(mode) => {
                renderer.set_cull(*mode);
                Ok(())
            }
            CommandKind::Distinguish(on) => {
                renderer.set_distinguish(*on);
                Ok(())
            }
            CommandKind::Light(light) => {
                renderer.shading_setup.lights.push(*light);
                Ok(())
            }
            CommandKind::Ambient(c) => {
                renderer.shading_setup.ambient_light = c.map(f64::from);
                Ok(())
            }
            CommandKind::Surface { sides, material } => {
                if *sides != SurfaceSides::Back {
                    renderer.shading_setup.front = *material;
                }
                if *sides != SurfaceSides::Front {
                    renderer.shading_setup.back = Some(*material);
                }
                Ok(())
            }
            CommandKind::Fog(fog) => {
                renderer.shading_setup.fog = Some(*fog);
                Ok(())
            }
            CommandKind::Texture(t) => {
                renderer.shading_setup.texture = Some(t.clone());
                Ok(())
            }
            CommandKind::ShadingPass(language) => {
                renderer.options.fixed_shading_in_language = *language;
                Ok(())
            }
            CommandKind::LightingSpace(space) => {
                renderer.shading_setup.space = *space;
                Ok(())
            }
            CommandKind::Material { name, value } => renderer.material(name, value),
            CommandKind::Begin(prim) => {
                let r = renderer.begin(prim);
                if renderer.in_primitive() && open_begin.is_none() {
                    open_begin = Some(c.tokens[0].span);
                }
                r
            }
            CommandKind::RastParam { name, value } => renderer.rast_param(name, value),
            CommandKind::SequencePoint => renderer.sequence_point(),
            CommandKind::Vertex([x, y, z, w]) => renderer.vertex(*x, *y, *z, *w),
            CommandKind::End => {
                open_begin = None;
                renderer.end()
            }
            CommandKind::Invalid(Some(word)) if word == "begin" => {
                renderer.begin_discarded();
                open_begin.get_or_insert(c.tokens[0].span);
                Ok(())
            }
            CommandKind::Invalid(Some(word)) if word == "end" => {
                // Already reported; close the block without building it twice.
                if renderer.in_primitive() {
                    let _ = renderer.end();
                }
                open_begin = None;
                Ok(())
            }
            CommandKind::Invalid(_) => Ok(()),
        };
        if let Err(issue) = result {
            diags.push(issue_diagnostic(&issue, c));
        }
        for w in renderer.take_warnings() {
            diags.push(issue_diagnostic(&w, c));
        }
        let after = renderer.instances().len();
        if after > before {
            objects.push(SceneObject {
                begin: last_begin.unwrap_or(c.tokens[0].span),
                instances: before..after,
            });
        }
    }
    if let Some(begin) = open_begin.filter(|_| renderer.in_primitive()) {
        diags.push(
            Diagnostic::error("E0605", "`begin` without `end`: the primitive is not rendered")
                .primary(begin, "this primitive is never closed"),
        );
    }
    objects
}

fn issue_diagnostic(issue: &ApiIssue, c: &Command) -> Diagnostic {
    let tokens = &c.tokens;
    let label = match issue.target {
        Target::Call => "this call",
        Target::Name => "this name",
        Target::Values => "these values",
        Target::Kind => "this kind",
        Target::Arg(_) => "this argument",
    };
    let span = match issue.target {
        Target::Call => tokens[0].span,
        Target::Name => tokens.get(1).map_or(tokens[0].span, |t| t.span),
        Target::Values => {
            // The numbers: after the name for name+value commands, else all arguments.
            let first_value = match c.kind {
                CommandKind::Material { .. } | CommandKind::RastParam { .. } | CommandKind::MaterialInterp { .. } => 2,
                _ => 1,
            };
            if tokens.len() > first_value {
                span_of(&tokens[first_value..])
            } else {
                tokens[0].span
            }
        }
        Target::Kind => tokens.get(2).map_or(tokens[0].span, |t| t.span),
        Target::Arg(i) => c.arg_spans.get(i).copied().unwrap_or(tokens[0].span),
    };
    let base = match issue.severity {
        crate::diag::Severity::Error => Diagnostic::error(issue.code, issue.message.clone()),
        crate::diag::Severity::Warning => Diagnostic::warning(issue.code, issue.message.clone()),
    };
    let d = base.primary(span, label);
    match &issue.help {
        Some(help) => d.help(help.clone()),
        None => d,
    }
}

/// A scene file made ready to render, as `primflow render` and `primflow bench --scene` load
/// it: parsed, the library files its names lead to compiled (with `dirs` and the scene's own
/// `prims DIR` lines, resolved against `base`, its directory; see
/// [`crate::runtime::Registry::load_for`]), and applied to a fresh [`Renderer`]. `None` when
/// the scene, the library or the applied calls have errors (all of them in `diags`, at
/// `file:line:col`); warnings are in `diags` either way.
pub fn load_for_render(
    sources: &mut SourceMap,
    file: FileId,
    base: &Path,
    dirs: &[PathBuf],
    diags: &mut Diagnostics,
) -> Option<Renderer> {
    load_objects(sources, file, base, dirs, diags).map(|(r, _)| r)
}

/// [`load_for_render`], with the instances each object became ([`apply_objects`]).
pub fn load_objects(
    sources: &mut SourceMap,
    file: FileId,
    base: &Path,
    dirs: &[PathBuf],
    diags: &mut Diagnostics,
) -> Option<(Renderer, Vec<SceneObject>)> {
    let scene = parse(sources, file, diags);
    if diags.has_errors() {
        return None;
    }
    check_prim_dirs(&scene, base, diags);
    if diags.has_errors() {
        return None;
    }
    let mut dirs = dirs.to_vec();
    dirs.extend(scene.prim_dirs(base));
    let (prims, kinds) = scene.library_names();
    let registry = crate::runtime::Registry::load_for(sources, &dirs, &prims, &kinds, diags)?;
    let mut renderer = Renderer::new(registry.program);
    let objects = apply_objects(&scene, &mut renderer, diags);
    (!diags.has_errors()).then_some((renderer, objects))
}

/// E0709 at each `prims DIR` line whose directory cannot be read, before any library is
/// loaded (the registry's own E0709 has no scene line to point at).
fn check_prim_dirs(scene: &Scene, base: &Path, diags: &mut Diagnostics) {
    for c in &scene.commands {
        let CommandKind::Prims(dir) = &c.kind else { continue };
        let path = base.join(dir);
        if let Err(e) = std::fs::read_dir(&path) {
            diags.push(
                Diagnostic::error(
                    "E0709",
                    format!("cannot read primitive directory `{}`: {e}", path.display()),
                )
                .primary(c.tokens[1].span, "this directory"),
            );
        }
    }
}

/// Parse and apply a scene in one go (for tests and tools that have no `prims` lines to
/// honour): returns the parsed scene.
pub fn load_into(sources: &SourceMap, file: FileId, renderer: &mut Renderer, diags: &mut Diagnostics) -> Scene {
    let scene = parse(sources, file, diags);
    apply(&scene, renderer, diags);
    scene
}

/// A 4x4 matrix given row by row in the scene file.
fn dmat_from_rows(rows: &[f32; 16]) -> glam::DMat4 {
    glam::DMat4::from_cols_array(&rows.map(f64::from)).transpose()
}
