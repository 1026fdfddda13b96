//! The deferred pass of language shaders: the scene's surface bindings, lights and
//! atmosphere, linked (`crate::link`) and JIT-compiled once per frame before the tiles, run
//! in each tile's task right after its primitives (`render::Renderer::render_into`).
//!
//! Per frame: one linked primitive per surface binding (binding 0 is the default surface,
//! [`DEFAULT_SURFACE`], for pixels drawn before any `shader` line), each compiled by its
//! own JIT at tier 1 with the key `[__out: 3 components]`. The G-buffer gets three more
//! planes, after the shading parameters' (`Ci`); when the frame has more than one binding,
//! the reserved shading parameter [`SURFACE_PARAM`] (a constant the API sets at each
//! `shader` line) says which binding drew each pixel, and each binding's kernel shades only
//! its own pixels. After the tiles, `Ci` becomes the frame's colours (0 where nothing was
//! drawn).
//!
//! Arguments are uniform per binding: scene values or the declared defaults. `point`,
//! `vector` and `normal` arguments are given in world coordinates and moved into lighting
//! coordinates here, once per frame (a point's w is set to 1 after the move).
//!
//! Invariants: the kernels touch only their tile of the frame (the same contract as
//! primitive kernels, `abi::ctx`), so the colours are the same for any tile size and thread
//! count; anything that fails to link or compile is an error diagnostic and the frame keeps
//! unshaded colours, never a panic.

use std::sync::Arc;

use glam::{DMat4, DVec4};

use crate::abi::{ArgLayout, Binding, BindingKind, Kernel, ParamSlot, VariantKey};
use crate::diag::{Diagnostic, Diagnostics};
use crate::ir::{FuncId, Program};
use crate::jit::Jit;
use crate::link::{self, ArgSource, Group, PlaneParam};
use crate::mid::Tier;
use crate::runtime::texture::{TextureSet, TEXTURE_MEMORY_LIMIT};
use crate::syntax::ast::{self, ItemKind};

use super::{SceneLight, ShadingSetup};

/// The reserved shading parameter holding each pixel's surface binding.
pub const SURFACE_PARAM: &str = "__surface";
/// What pixels drawn before any `shader` line are shaded with.
pub const DEFAULT_SURFACE: &str = "matte";

/// A shader and the arguments the scene gives it by name.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ShaderUse {
    pub name: String,
    pub args: Vec<(String, Vec<f32>)>,
    /// The values of its `string` parameters (surfaces only), by name: constants of its
    /// code, substituted when the frame is linked (`crate::link`).
    pub text: Vec<(String, String)>,
}

/// One argument of a shader line.
#[derive(Clone, Debug, PartialEq)]
pub enum ShaderArg {
    Numbers(crate::runtime::Value),
    /// For a `string` parameter.
    Text(String),
}

/// What the scene asks of the language shaders.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LanguageShading {
    /// What shades pixels drawn before the first binding ([`DEFAULT_SURFACE`] when `None`).
    pub default_surface: Option<ShaderUse>,
    /// Surface bindings in order; a pixel's binding number is its index + 1.
    pub surfaces: Vec<ShaderUse>,
    pub lights: Vec<ShaderUse>,
    pub atmosphere: Option<ShaderUse>,
}

impl LanguageShading {
    /// The fixed shading lines as library shaders: `ambient` an `ambientlight`, each
    /// `light` a `distantlight` or an `attenuated_pointlight`, the front material, the
    /// checker texture (over `st` only) and "no light, no lighting" the default surface
    /// `fixed_phong`, `fog` the `fog` atmosphere. Returns what does not carry over.
    pub fn from_fixed(setup: &ShadingSetup) -> (LanguageShading, Vec<String>) {
        let mut notes = vec![];
        let arg = |name: &str, v: &[f64]| (name.to_string(), v.iter().map(|&x| x as f32).collect::<Vec<f32>>());
        let mut lights = vec![];
        if setup.ambient_light != [0.0; 3] {
            lights.push(ShaderUse {
                text: vec![],
                name: "ambientlight".into(),
                args: vec![arg("lightcolor", &setup.ambient_light)],
            });
        }
        for l in &setup.lights {
            lights.push(match *l {
                SceneLight::Directional { towards_light, colour } => ShaderUse {
                    text: vec![],
                    name: "distantlight".into(),
                    args: vec![
                        arg("lightcolor", &colour),
                        arg("from", &towards_light),
                        arg("to", &[0.0; 3]),
                    ],
                },
                SceneLight::Positional {
                    position,
                    colour,
                    attenuation,
                } => ShaderUse {
                    text: vec![],
                    name: "attenuated_pointlight".into(),
                    args: vec![
                        arg("lightcolor", &colour),
                        arg("from", &position),
                        arg("c0", &attenuation[..1]),
                        arg("c1", &attenuation[1..2]),
                        arg("c2", &attenuation[2..]),
                    ],
                },
            });
        }
        let m = &setup.front;
        let mut surface = vec![
            arg("Ka", &[m.ka]),
            arg("Kd", &[m.kd]),
            arg("Ks", &[m.ks]),
            arg("shininess", &[m.shininess]),
            arg("specularcolor", &m.specular_colour),
            arg("lit", &[if setup.lights.is_empty() { 0.0 } else { 1.0 }]),
        ];
        if let Some(t) = &setup.texture {
            if t.param == "st" {
                surface.push(arg("checker_scale", &[t.scale]));
                surface.push(arg("checker_dark", &[t.dark]));
            } else {
                notes.push(format!(
                    "the checker texture over `{}` is not mapped (the language shaders read s and t from `st`)",
                    t.param
                ));
            }
        }
        if setup.back.is_some() {
            notes.push("the back material is not mapped (`fixed_phong` faces the normal forward)".into());
        }
        let atmosphere = setup.fog.map(|f| ShaderUse {
            text: vec![],
            name: "fog".into(),
            args: vec![
                arg("background", &f.colour),
                arg("start", &[f.start]),
                arg("end", &[f.end]),
            ],
        });
        (
            LanguageShading {
                default_surface: Some(ShaderUse {
                    text: vec![],
                    name: "fixed_phong".into(),
                    args: surface,
                }),
                surfaces: vec![],
                lights,
                atmosphere,
            },
            notes,
        )
    }

    /// Whether the frame is shaded by language shaders (any `shader`, `lightsource` or
    /// `atmosphere` line).
    pub fn active(&self) -> bool {
        !self.surfaces.is_empty() || !self.lights.is_empty() || self.atmosphere.is_some()
    }
}

/// The frame's shading kernels, ready to run.
pub(crate) struct CompiledShading {
    /// Kept alive: the kernels' code lives in them (behind a lock only so that the
    /// compiled shading can be shared; nothing uses them after the compile).
    _jits: std::sync::Mutex<Vec<Jit>>,
    /// What was compiled, one line per kernel and per plane (`render --explain`).
    pub explain: Vec<String>,
    /// The frame's shading-parameter planes: those a shader reads, the binding plane and
    /// the ones the caller keeps, numbered from 0 in the API's order. The output planes
    /// follow them.
    pub planes: Vec<PlaneParam>,
    pub(crate) pass: ShadingRuns,
}

/// The kernels of a [`CompiledShading`] and what they run with (shared by the tile tasks).
pub(crate) struct ShadingRuns {
    pub(super) programs: Vec<Arc<Program>>,
    /// (kernel, argument block) per binding, each compiled for [`out_key`].
    pub(super) runs: Vec<(Arc<Kernel>, Vec<u32>)>,
    pub out_plane: u32,
    /// The kernels run on 2x2 quads of pixels (`super::quads`).
    pub(super) quads: bool,
}

/// The key every binding's `__shade` is compiled for: its one binding, the three output
/// planes.
pub(super) fn out_key() -> VariantKey {
    VariantKey {
        bindings: vec![Binding {
            kind: BindingKind::Kind(link::OUT_KIND.into()),
            components: 3,
        }],
        count_writes: false,
        trivial_accept: false,
    }
}

/// The spaces a frame's arguments are moved by.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Spaces {
    pub lighting_from_world: DMat4,
    pub device_from_lighting: DMat4,
    /// Homogeneous eye in lighting coordinates (w = 0: parallel view, towards the viewer).
    pub eye: [f64; 4],
    /// The centre of the near plane in lighting coordinates.
    pub near: [f64; 3],
}

/// The last frame's compiled shading and what it was compiled from: a renderer that
/// renders frame after frame with the same shaders, lights and planes links and compiles
/// them once.
#[derive(Default)]
pub(crate) struct ShadingCache(std::sync::Mutex<Option<CacheEntry>>);

struct CacheEntry {
    shading: LanguageShading,
    planes: Vec<PlaneParam>,
    keep: Vec<String>,
    spaces: Spaces,
    compiled: Arc<CompiledShading>,
    /// The compile's warnings, reported again with every frame that uses it.
    diags: Diagnostics,
}

impl ShadingCache {
    /// The compiled shading of the last compile (the last language-shaded frame's).
    pub(crate) fn last(&self) -> Option<Arc<CompiledShading>> {
        let slot = self.0.lock().unwrap_or_else(|p| p.into_inner());
        slot.as_ref().map(|e| e.compiled.clone())
    }
}

/// [`compile`], or the cached result when the inputs are those of the last compile.
pub(crate) fn compile_cached(
    cache: &ShadingCache,
    program: &Program,
    shading: &LanguageShading,
    planes: &[PlaneParam],
    keep: &[String],
    spaces: &Spaces,
    diags: &mut Diagnostics,
) -> Option<Arc<CompiledShading>> {
    let mut slot = cache.0.lock().unwrap_or_else(|p| p.into_inner());
    if let Some(e) = slot.as_ref() {
        if e.shading == *shading && e.planes == planes && e.keep == keep && e.spaces == *spaces {
            diags.extend(e.diags.clone());
            return Some(e.compiled.clone());
        }
    }
    let mut own = Diagnostics::new();
    let compiled = compile(program, shading, planes, keep, spaces, &mut own).map(Arc::new);
    diags.extend(own.clone());
    *slot = compiled.clone().map(|compiled| CacheEntry {
        shading: shading.clone(),
        planes: planes.to_vec(),
        keep: keep.to_vec(),
        spaces: spaces.clone(),
        compiled,
        diags: own,
    });
    compiled
}

/// Link and compile the frame's shading. `all_planes`: every shading parameter's planes
/// as the API allocated them; `keep`: the parameters the caller reads from the frame,
/// whether or not a shader does. The frame's planes are [`CompiledShading::planes`], then
/// the three output planes. Errors go to `diags`.
pub(crate) fn compile(
    program: &Program,
    shading: &LanguageShading,
    all_planes: &[PlaneParam],
    keep: &[String],
    spaces: &Spaces,
    diags: &mut Diagnostics,
) -> Option<CompiledShading> {
    let find = |name: &str, kind: ItemKind| {
        program
            .shading_items
            .iter()
            .find(|i| i.kind == kind && i.name.name == name)
    };
    let mut lights = vec![];
    for l in &shading.lights {
        match find(&l.name, ItemKind::Light) {
            Some(item) => lights.push(item),
            None => {
                diags.push(Diagnostic::error("E1002", format!("no light shader `{}`", l.name)));
                return None;
            }
        }
    }
    let atmosphere = match &shading.atmosphere {
        Some(a) => match find(&a.name, ItemKind::Atmosphere) {
            Some(item) => Some(item),
            None => {
                diags.push(Diagnostic::error("E1002", format!("no atmosphere shader `{}`", a.name)));
                return None;
            }
        },
        None => None,
    };
    let default = ShaderUse {
        text: vec![],
        name: DEFAULT_SURFACE.into(),
        args: vec![],
    };
    let default = shading.default_surface.as_ref().unwrap_or(&default);
    let bindings: Vec<&ShaderUse> = std::iter::once(default).chain(&shading.surfaces).collect();
    let mut jits = vec![];
    let mut programs = vec![];
    let mut runs = vec![];
    let light_names: Vec<&str> = shading.lights.iter().map(|l| l.name.as_str()).collect();
    let mut explain = vec![format!(
        "language shaders: lights [{}], atmosphere {}",
        light_names.join(", "),
        shading.atmosphere.as_ref().map_or("none", |a| a.name.as_str()),
    )];
    // One layout for the whole frame: on quads as soon as any of its shaders takes a
    // derivative.
    let mut items: Vec<&ast::Item> = lights.clone();
    items.extend(atmosphere);
    for b in &bindings {
        items.extend(find(&b.name, ItemKind::Surface));
    }
    let quads = items.iter().any(|i| link::takes_derivatives(i));
    if quads {
        explain.push("shading on 2x2 quads of pixels: a shader takes screen-space derivatives".into());
    }
    let mut surfaces = vec![];
    for binding in &bindings {
        match find(&binding.name, ItemKind::Surface) {
            Some(surface) => surfaces.push(surface),
            None => {
                diags.push(Diagnostic::error(
                    "E1002",
                    format!("no surface shader `{}`", binding.name),
                ));
                return None;
            }
        }
    }
    // Binding 0 runs only where a pixel can have no binding: a frame with bindings whose
    // every pixel has one still runs it (it shades nothing there).
    let link_all = |planes: &[PlaneParam]| -> Result<Vec<link::Linked>, String> {
        let material = planes.iter().find(|p| p.name == SURFACE_PARAM).map(|p| p.first_plane);
        let out_plane = planes.iter().map(|p| p.components).sum();
        let group = |id: usize| Group {
            surface: surfaces[id],
            lights: lights.clone(),
            atmosphere,
            planes,
            material: material.map(|p| (p, id as u32)),
            surface_text: &bindings[id].text,
            out_plane,
            quads,
        };
        (0..bindings.len()).map(|id| link::link(&group(id))).collect()
    };
    // Linked against every plane the API allocated, the shaders say what they read; the
    // frame keeps only those planes (`runtime::live`), and they are linked again against
    // the planes' new numbers.
    let ice = |e: String| Diagnostic::error("E0900", format!("internal compiler error: {e}"));
    let mut linked_all = match link_all(all_planes) {
        Ok(l) => l,
        Err(e) => {
            diags.push(ice(e));
            return None;
        }
    };
    let why = |name: &str| -> Option<String> {
        let readers: Vec<&str> = bindings
            .iter()
            .zip(&linked_all)
            .filter(|(_, l)| l.reads.iter().any(|r| r == name))
            .map(|(b, _)| b.name.as_str())
            .collect();
        if name == SURFACE_PARAM {
            Some("which surface binding drew each pixel".into())
        } else if !readers.is_empty() {
            Some(format!("read by surface(s) {}", readers.join(", ")))
        } else if keep.iter().any(|k| k == name) {
            Some("kept for the caller (`--param`, a test expectation)".into())
        } else {
            None
        }
    };
    let mut planes = vec![];
    let mut dead = vec![];
    let mut next = 0;
    for p in all_planes {
        match why(&p.name) {
            Some(reason) => {
                let last = next + p.components - 1;
                let at = if last == next {
                    format!("plane {next}")
                } else {
                    format!("planes {next}-{last}")
                };
                explain.push(format!("G-buffer {at}: `{}` ({reason})", p.name));
                planes.push(PlaneParam {
                    first_plane: next,
                    ..p.clone()
                });
                next += p.components;
            }
            None => dead.push(format!("`{}`", p.name)),
        }
    }
    let out_plane = next;
    explain.push(format!(
        "G-buffer planes {out_plane}-{}: `Ci` (the shaders' output)",
        out_plane + 2
    ));
    if !dead.is_empty() {
        explain.push(format!(
            "not allocated, not interpolated by any primitive: {} (no shader of the frame reads them)",
            dead.join(", ")
        ));
    }
    if planes != all_planes {
        linked_all = match link_all(&planes) {
            Ok(l) => l,
            Err(e) => {
                diags.push(ice(e));
                return None;
            }
        };
    }
    let material = planes.iter().any(|p| p.name == SURFACE_PARAM);
    // Check every binding, then load the textures they name, then compile.
    let mut checked = vec![];
    for (id, ((binding, surface), linked)) in bindings.iter().zip(surfaces).zip(linked_all).enumerate() {
        for (name, _) in &linked.unprovided {
            diags.push(Diagnostic::warning(
                "W1001",
                format!(
                    "surface `{}` reads `{name}` per pixel, but no primitive of the frame provides it: its default is used",
                    binding.name
                ),
            ));
        }
        explain.push(format!(
            "surface `{}` (binding {id}{}): reads plane(s) of [{}]{}",
            binding.name,
            if id == 0 {
                ", pixels drawn before any `shader` line"
            } else {
                ""
            },
            linked.reads.join(", "),
            if material {
                format!(", only where `{SURFACE_PARAM}` is {id}")
            } else {
                String::new()
            }
        ));
        let mut check_diags = Diagnostics::new();
        let linked_program = crate::check::check_linked(program, &linked.items, &mut check_diags);
        if check_diags.has_errors() {
            diags.extend(check_diags);
            return None;
        }
        checked.push((binding, surface, linked, linked_program));
    }
    // Every texture the shaders name, loaded once for the frame before anything renders.
    let mut textures = TextureSet::new();
    let mut texture_ids: std::collections::HashMap<&str, u32> = Default::default();
    for (_, _, _, linked_program) in &checked {
        let named = &linked_program.textures;
        for (file, span) in named.names.iter().zip(&named.spans) {
            if texture_ids.contains_key(file.as_str()) {
                continue;
            }
            match textures.load(std::path::Path::new(file), TEXTURE_MEMORY_LIMIT) {
                Ok(id) => {
                    if let Some((w, h)) = textures.level_size(id, 0) {
                        explain.push(format!(
                            "texture `{file}`: {w}x{h}, {} mip level(s)",
                            textures.levels(id)
                        ));
                    }
                    texture_ids.insert(file, id);
                }
                Err(e) => {
                    diags.push(Diagnostic::error("E1004", e.to_string()).primary(*span, "named here"));
                    return None;
                }
            }
        }
    }
    let ids: Vec<Vec<u32>> = checked
        .iter()
        .map(|(.., p)| p.textures.names.iter().map(|n| texture_ids[n.as_str()]).collect())
        .collect();
    let textures = Arc::new(textures);
    for ((binding, surface, linked, mut linked_program), ids) in checked.into_iter().zip(ids) {
        if !ids.is_empty() {
            linked_program.textures.loaded = Some((textures.clone(), ids));
        }
        let linked_program = Arc::new(linked_program);
        let Some(func) = linked_program.find(link::SHADE) else {
            diags.push(Diagnostic::error(
                "E0900",
                "internal compiler error: no linked shading primitive",
            ));
            return None;
        };
        let key = out_key();
        let mut jit = match Jit::at_tier(linked_program.clone(), Tier::Optimised) {
            Ok(j) => j,
            Err(e) => {
                diags.push(Diagnostic::error(
                    "E0802",
                    format!("cannot compile the shading pass: {e}"),
                ));
                return None;
            }
        };
        let kernel = match jit.kernel(func, &key) {
            Ok(k) => k,
            Err(e) => {
                diags.push(Diagnostic::error(
                    "E0802",
                    format!("cannot compile the shading pass: {e}"),
                ));
                return None;
            }
        };
        let uses = ShadingUses {
            surface: binding,
            lights: &shading.lights,
            atmosphere: shading.atmosphere.as_ref(),
            surface_item: surface,
            light_items: &lights,
            atmosphere_item: atmosphere,
        };
        let args = match argument_block(&linked_program, func, &key, &linked.args, &uses, out_plane, spaces) {
            Ok(a) => a,
            Err(e) => {
                diags.push(e);
                return None;
            }
        };
        runs.push((kernel, args));
        programs.push(linked_program);
        jits.push(jit);
    }
    Some(CompiledShading {
        _jits: std::sync::Mutex::new(jits),
        explain,
        planes,
        pass: ShadingRuns {
            programs,
            runs,
            out_plane,
            quads,
        },
    })
}

struct ShadingUses<'a> {
    surface: &'a ShaderUse,
    lights: &'a [ShaderUse],
    atmosphere: Option<&'a ShaderUse>,
    surface_item: &'a ast::Item,
    light_items: &'a [&'a ast::Item],
    atmosphere_item: Option<&'a ast::Item>,
}

/// The argument block of a linked primitive: its parameters in [`link::Linked::args`]
/// order, then the output planes' table.
fn argument_block(
    program: &Program,
    func: FuncId,
    key: &VariantKey,
    sources: &[ArgSource],
    uses: &ShadingUses,
    out_plane: u32,
    spaces: &Spaces,
) -> Result<Vec<u32>, Diagnostic> {
    let f = program.func(func);
    let layout = ArgLayout::new(program, func, key);
    let mut args = vec![0u32; layout.words(0)];
    for c in 0..3 {
        args[layout.plane_table as usize + c] = out_plane + c as u32;
    }
    let fixed: Vec<(usize, &crate::ir::Param, u32, u32)> = f
        .params
        .iter()
        .zip(&layout.params)
        .enumerate()
        .filter_map(|(i, (p, slot))| match slot {
            ParamSlot::Fixed { offset, words } => Some((i, p, *offset, *words)),
            _ => None,
        })
        .collect();
    if fixed.len() != sources.len() {
        return Err(Diagnostic::error(
            "E0900",
            "internal compiler error: the linked shading primitive's parameters do not match its sources",
        ));
    }
    for ((_, p, offset, words), source) in fixed.iter().zip(sources) {
        let ty = &f.local(p.local).ty;
        let given_default = || {
            p.default.as_ref().map(|d| {
                crate::runtime::value::encode_default(d, ty, crate::ir::ParamSpace::None, &glam::Mat4::IDENTITY)
            })
        };
        let (given, decl, shader): (Option<&Vec<f32>>, Option<&ast::Param>, &str) = match source {
            ArgSource::Surface(name) => (
                uses.surface.args.iter().find(|(n, _)| n == name).map(|(_, v)| v),
                uses.surface_item.params.iter().find(|q| &q.name.name == name),
                &uses.surface.name,
            ),
            ArgSource::Light { index, name } => (
                uses.lights[*index].args.iter().find(|(n, _)| n == name).map(|(_, v)| v),
                uses.light_items[*index].params.iter().find(|q| &q.name.name == name),
                &uses.lights[*index].name,
            ),
            ArgSource::Atmosphere(name) => (
                uses.atmosphere
                    .and_then(|a| a.args.iter().find(|(n, _)| n == name).map(|(_, v)| v)),
                uses.atmosphere_item
                    .and_then(|a| a.params.iter().find(|q| &q.name.name == name)),
                uses.atmosphere.map(|a| a.name.as_str()).unwrap_or(""),
            ),
            ArgSource::LightingFromDevice => {
                let m = spaces.device_from_lighting.inverse();
                let rows: Vec<u32> = (0..4)
                    .flat_map(|r| (0..4).map(move |c| (r, c)))
                    .map(|(r, c)| (m.col(c)[r] as f32).to_bits())
                    .collect();
                write(&mut args, *offset, *words, &rows);
                continue;
            }
            ArgSource::Eye | ArgSource::Near => {
                let v: &[f64] = if *source == ArgSource::Eye {
                    &spaces.eye
                } else {
                    &spaces.near
                };
                let e: Vec<u32> = v.iter().map(|&x| (x as f32).to_bits()).collect();
                write(&mut args, *offset, *words, &e);
                continue;
            }
        };
        // A point may be given as x y z (w = 1).
        let padded: Option<Vec<f32>> = match (given, decl.map(|d| &d.ty.kind)) {
            (Some(v), Some(ast::TypeKind::Point)) if v.len() == 3 => Some(vec![v[0], v[1], v[2], 1.0]),
            _ => None,
        };
        let given = padded.as_ref().or(given);
        let mut words_of = match given {
            Some(v) => crate::runtime::value::encode(v, ty, crate::ir::ParamSpace::None, &glam::Mat4::IDENTITY)
                .map_err(|e| {
                    Diagnostic::error("E0703", format!("argument `{}` of shader `{shader}`: {e:?}", p.name))
                })?,
            None => given_default().unwrap_or_else(|| vec![0; *words as usize]),
        };
        // Positions and directions: world coordinates to lighting coordinates.
        if let Some(decl) = decl {
            let kind = decl.ty.kind.clone();
            move_to_lighting(&mut words_of, &kind, &spaces.lighting_from_world);
        }
        write(&mut args, *offset, *words, &words_of);
    }
    Ok(args)
}

fn write(args: &mut [u32], offset: u32, words: u32, data: &[u32]) {
    let at = offset as usize;
    let n = (words as usize).min(data.len());
    args[at..at + n].copy_from_slice(&data[..n]);
}

/// A point (x, y, z[, w]), vector or normal argument, from world to lighting coordinates,
/// in place (floats as bits; arrays of them element by element).
fn move_to_lighting(words: &mut [u32], kind: &ast::TypeKind, lighting_from_world: &DMat4) {
    let f = |w: u32| f32::from_bits(w) as f64;
    match kind {
        ast::TypeKind::Point => {
            for p in words.chunks_exact_mut(4) {
                let q = *lighting_from_world * DVec4::new(f(p[0]), f(p[1]), f(p[2]), 1.0);
                let q = if q.w != 0.0 { q / q.w } else { q };
                p.copy_from_slice(&[q.x, q.y, q.z, 1.0].map(|x| (x as f32).to_bits()));
            }
        }
        ast::TypeKind::Vector => {
            for v in words.chunks_exact_mut(3) {
                let q = *lighting_from_world * DVec4::new(f(v[0]), f(v[1]), f(v[2]), 0.0);
                v.copy_from_slice(&[q.x, q.y, q.z].map(|x| (x as f32).to_bits()));
            }
        }
        ast::TypeKind::Normal => {
            let m = lighting_from_world.inverse().transpose();
            for v in words.chunks_exact_mut(3) {
                let q = m * DVec4::new(f(v[0]), f(v[1]), f(v[2]), 0.0);
                v.copy_from_slice(&[q.x, q.y, q.z].map(|x| (x as f32).to_bits()));
            }
        }
        _ => {}
    }
}

impl ShadingRuns {
    /// Run every binding's kernel over `tile` of the frame.
    ///
    /// # Safety
    /// As `render::render_tile`: the caller owns `tile`'s rectangle of `target`.
    pub(crate) unsafe fn shade_tile(
        &self,
        tile: &super::super::frame::Tile,
        opts: &super::super::RenderOptions,
        target: super::super::frame::FrameTarget<'_>,
    ) -> Vec<(usize, crate::runtime::errors::Counts)> {
        let mut out = vec![];
        // SAFETY: the caller's contract.
        let mut quads = self
            .quads
            .then(|| unsafe { super::quads::QuadTile::gather(tile, &target) });
        for (b, ((kernel, args), program)) in self.runs.iter().zip(&self.programs).enumerate() {
            crate::runtime::errors::CountArrays::with(program, |counts| {
                let mut ctx = super::super::render::tile_context(tile, opts, &target);
                if let Some(q) = &mut quads {
                    ctx = q.context(ctx);
                }
                ctx.setup_counts = counts.scratch();
                ctx.pixel_counts = counts.counts();
                // SAFETY: the caller's contract; the argument block was built for this
                // kernel's layout.
                unsafe { (kernel.entry)(&mut ctx, args.as_ptr()) };
                if ctx.error != 0 {
                    let mut errors = vec![];
                    counts.take(&mut errors);
                    out.push((b, errors));
                }
            });
        }
        if let Some(q) = &quads {
            let first = self.out_plane as usize;
            // SAFETY: the caller's contract.
            unsafe { q.scatter(tile, &target, first..first + 3) };
        }
        out
    }

    /// Report the run-time errors counted per binding.
    pub(crate) fn report(&self, errors: &[(usize, crate::runtime::errors::Counts)], diags: &mut Diagnostics) {
        for (b, program) in self.programs.iter().enumerate() {
            let counts: crate::runtime::errors::Counts = errors
                .iter()
                .filter(|(k, _)| *k == b)
                .flat_map(|(_, c)| c.iter().copied())
                .collect();
            if !counts.is_empty() {
                crate::runtime::errors::report(program, &counts, diags);
            }
        }
    }
}
