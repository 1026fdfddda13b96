//! Shader groups: a frame's surface shader, its lights and its atmosphere linked into one
//! primitive of the deferred pass, at the syntax tree.
//!
//! A surface, light or atmosphere item is not a function of its own: what it reads (the
//! G-buffer planes that exist, the lights of the frame) is only known per frame. [`link`]
//! builds, for one surface binding of one frame, these items and hands them to the checker
//! with the program's helper functions:
//! - `__light_NAME(vector Ps; inout vector L; inout color Cl; PARAMS)`, one helper per light
//!   shader the frame uses, its body the light's;
//! - `__surface(GLOBALS; inout color Ci, Oi; PARAMS; LIGHT ARGUMENTS)`: the surface's body
//!   with each `illuminance` statement unrolled over the frame's (non-ambient) lights: per
//!   light a block declaring `L` and `Cl`, calling that light's helper with its arguments,
//!   then (for `illuminance(P, axis, angle)`) testing the cone, then the loop's body.
//!   `ambient()`, `diffuse(N)`, `specular(N, V, roughness)` and `phong(N, V, size)` in the
//!   surface become calls of generated helpers that unroll the same way ([`MODELS`]);
//! - `__atmosphere(vector P, I, E; inout color Ci, Oi; PARAMS)` when the frame has one;
//! - the primitive `__shade`: per pixel whose depth was written (and whose material plane
//!   names this binding, when the frame has several), the globals from the G-buffer planes
//!   through the built-in `__gbuffer(plane, X, Y)`, the surface and atmosphere calls, and
//!   `Ci` stored into the output planes as interpolation kind `__out`.
//!
//! Invariants: user code keeps its own spans (errors in a shader point into its file); the
//! generated code is parsed from text and every span in it is set to the shader's name, so
//! no diagnostic can point into text no source map holds. The primitive's parameters are, in
//! order, [`Linked::args`]: the runtime fills the argument block from that list alone.
//! Light and atmosphere parameters are renamed (`__l3_intensity`, `__a_start`) so that two
//! lights of one kind and the surface never share a name.

use crate::diag::{Diagnostics, FileId, Span};
use crate::syntax::ast::{self, Expr, ExprKind, Item, ItemKind, Stmt, StmtKind};

/// One shading parameter's planes in the frame's G-buffer.
#[derive(Clone, Debug, PartialEq)]
pub struct PlaneParam {
    pub name: String,
    pub first_plane: u32,
    pub components: u32,
}

/// What a linked primitive's parameter is filled with, in [`Linked::args`] order.
#[derive(Clone, Debug, PartialEq)]
pub enum ArgSource {
    /// A uniform parameter of the surface (by its name): the binding's value or the default.
    Surface(String),
    /// Parameter `name` of the frame's light `index`.
    Light { index: usize, name: String },
    /// A parameter of the atmosphere.
    Atmosphere(String),
    /// `float[4][4]`: lighting coordinates from device coordinates (the inverse of the
    /// frame's `device_from_lighting`).
    LightingFromDevice,
    /// `float[4]`: the eye in lighting coordinates, homogeneous (w = 0: a parallel view,
    /// x, y, z the unit direction towards the viewer).
    Eye,
    /// `float[3]`: the centre of the near plane in lighting coordinates (a parallel view's
    /// distances are measured from it).
    Near,
}

/// A frame's shading as the linker sees it.
pub struct Group<'a> {
    pub surface: &'a Item,
    /// Every light of the frame, in scene order (ambient ones too).
    pub lights: Vec<&'a Item>,
    pub atmosphere: Option<&'a Item>,
    pub planes: &'a [PlaneParam],
    /// The plane holding each pixel's surface binding and this binding's number in it, when
    /// the frame has several bindings.
    pub material: Option<(u32, u32)>,
    /// The values of the surface's `string` parameters the scene gives, by name (the
    /// others take their defaults).
    pub surface_text: &'a [(String, String)],
    /// The first of the three output planes (`Ci`).
    pub out_plane: u32,
    /// `__shade` runs on 2x2 quads of pixels (a shader of the frame [`takes_derivatives`]):
    /// it reads each pixel's centre from the planes `out_plane + 3` (x) and `out_plane + 4`
    /// (y) instead of its `X` and `Y`.
    pub quads: bool,
}

/// A linked shader group: items to check with the program's helpers.
pub struct Linked {
    pub items: Vec<Item>,
    /// The parameters of `__shade` before `X`, `Y`, `Z`, in order.
    pub args: Vec<ArgSource>,
    /// Varying surface parameters no plane of the frame provides (they take their default):
    /// (parameter, its span).
    pub unprovided: Vec<(String, Span)>,
    /// The planes the surface and atmosphere read (dead-parameter elimination keeps only
    /// these).
    pub reads: Vec<String>,
}

/// The file id generated text is parsed under (its spans are replaced before anything
/// can report them).
const GENERATED_FILE: FileId = u32::MAX;

/// Name of the linked primitive.
pub const SHADE: &str = "__shade";
/// Interpolation kind of the output planes.
pub const OUT_KIND: &str = "__out";

/// The light-dependent built-ins of surfaces, as generated helpers: (name, extra
/// parameters, body). `illuminance` in them is unrolled like the surface's own.
const MODELS: &[(&str, &str, &str)] = &[
    ("ambient", "", "color C = 0; __ambient_lights(C); return C;"),
    (
        "diffuse",
        "normal Nn",
        "color C = 0; illuminance(P, Nn, PI / 2) { C += Cl * dot(normalize(L), normalize(Nn)); } return C;",
    ),
    (
        "specular",
        "normal Nn; vector V; float roughness",
        "color C = 0; illuminance(P, Nn, PI / 2) { vector H = normalize(normalize(L) + V); \
         C += Cl * pow(max(0.0, dot(normalize(Nn), H)), 1 / roughness); } return C;",
    ),
    (
        "phong",
        "normal Nn; vector V; float size",
        "color C = 0; vector R = reflect(-normalize(V), normalize(Nn)); illuminance(P, Nn, PI / 2) { \
         C += Cl * pow(max(0.0, dot(R, normalize(L))), size); } return C;",
    ),
];

/// A light shader is ambient when its body never assigns `L`: it adds to `ambient()` and
/// `illuminance` skips it.
pub fn is_ambient(light: &Item) -> bool {
    let mut assigns_l = false;
    let mut work: Vec<&Stmt> = light.body.stmts.iter().collect();
    while let Some(s) = work.pop() {
        if let StmtKind::Assign { target, .. } = &s.kind {
            if root_name(target) == Some("L") {
                assigns_l = true;
            }
        }
        s.for_each_child(|c| work.push(c), |_| {});
    }
    !assigns_l
}

/// The names `block` mentions as variables, and the functions it calls.
#[derive(Default)]
struct Uses {
    names: std::collections::HashSet<String>,
    calls: std::collections::HashSet<String>,
}

impl Uses {
    fn of(block: &ast::Block) -> Uses {
        let mut uses = Uses::default();
        let mut stmts: Vec<&Stmt> = block.stmts.iter().collect();
        let mut exprs: Vec<&Expr> = vec![];
        while let Some(s) = stmts.pop() {
            s.for_each_child(|c| stmts.push(c), |e| exprs.push(e));
            while let Some(e) = exprs.pop() {
                match &e.kind {
                    ExprKind::Name(n) => {
                        uses.names.insert(n.name.clone());
                    }
                    ExprKind::Call { callee, .. } => {
                        uses.calls.insert(callee.name.clone());
                    }
                    _ => {}
                }
                e.for_each_child(|c| exprs.push(c));
            }
        }
        uses
    }
}

/// Whether shader `item` takes a screen-space derivative: its frame then shades on quads.
pub fn takes_derivatives(item: &Item) -> bool {
    let calls = Uses::of(&item.body).calls;
    DERIVATIVES.iter().any(|d| calls.contains(*d))
}

/// The built-ins that take screen-space derivatives (`texture` for its footprint).
const DERIVATIVES: &[&str] = &["Dx", "Dy", "filterwidth", "texture"];

fn root_name(e: &Expr) -> Option<&str> {
    match &e.kind {
        ExprKind::Name(n) => Some(&n.name),
        ExprKind::Index { base, .. } | ExprKind::Field { base, .. } => root_name(base),
        _ => None,
    }
}

/// Link `group` (see the module documentation). Errors only for generated text that does
/// not parse, which is a bug of this module.
pub fn link(group: &Group) -> Result<Linked, String> {
    // `string` parameters are constants of the code: their values replace their names in
    // the body (`Rewrite`), and the surface has no such parameter at run time.
    let text_args = text_values(group.surface, group.surface_text);
    let mut surface_owned = group.surface.clone();
    surface_owned.params.retain(|p| p.ty.kind != ast::TypeKind::String);
    let surface = &surface_owned;
    let span = surface.name.span;
    let plane = |name: &str| group.planes.iter().find(|p| p.name == name);
    let mut reads = vec![];
    let mut text = String::new();

    // Light helpers, one per light shader used.
    let mut light_kinds: Vec<&Item> = vec![];
    for l in &group.lights {
        if !light_kinds.iter().any(|k| k.name.name == l.name.name) {
            light_kinds.push(l);
        }
    }
    // Light arguments: `__l<i>_<name>` for every parameter of every light.
    let mut light_params = String::new();
    let mut light_args = String::new();
    for (i, l) in group.lights.iter().enumerate() {
        for p in &l.params {
            light_params.push_str(&format!("; {} __l{i}_{}", param_type_text(p), p.name.name));
            light_args.push_str(&format!(", __l{i}_{}", p.name.name));
        }
    }
    let mut ambient_calls = String::new();
    for (i, l) in group.lights.iter().enumerate() {
        if is_ambient(l) {
            ambient_calls.push_str(&format!(
                "{{ vector L = 0; color Cl = 0; __light_{}(P, L, Cl{}); C += Cl; }}",
                l.name.name,
                light_call_args(l, i)
            ));
        }
    }
    for (name, extra, body) in MODELS {
        let sep = if extra.is_empty() { "" } else { "; " };
        let body = body.replace("__ambient_lights(C);", &ambient_calls);
        text.push_str(&format!(
            "color __{name}({extra}{sep}vector P{light_params}) {{ {body} }}\n"
        ));
    }
    text.push_str(&format!(
        "void __surface(vector P; normal N, Ng; vector I, E; float s, t; color Cs, Os; inout color Ci, Oi{light_params}) {{}}\n"
    ));
    for k in &light_kinds {
        text.push_str(&format!(
            "void __light_{}(vector Ps; inout vector L; inout color Cl) {{}}\n",
            k.name.name
        ));
    }
    if group.atmosphere.is_some() {
        text.push_str("void __atmosphere(vector P, I, E; inout color Ci, Oi) {}\n");
    }

    // The primitive.
    let mut args = vec![];
    let mut prim_params = String::new();
    let mut surface_args = String::new();
    let mut varying_decls = String::new();
    let mut unprovided = vec![];
    for p in &surface.params {
        let name = &p.name.name;
        let varying = matches!(p.quals.variability, Some((ast::Variability::Varying, _)));
        if varying {
            // A primitive variable: the plane of the same name when the frame has one.
            match plane(name).filter(|pl| pl.components == components_of(p)) {
                Some(pl) => {
                    reads.push(name.clone());
                    varying_decls.push_str(&format!("{} = {};\n", decl_text(p), plane_list(pl, p)));
                }
                None => {
                    unprovided.push((name.clone(), p.name.span));
                    prim_params.push_str(&format!("{} {name}; ", param_type_text(p)));
                    args.push(ArgSource::Surface(name.clone()));
                }
            }
        } else {
            prim_params.push_str(&format!("{} {name}; ", param_type_text(p)));
            args.push(ArgSource::Surface(name.clone()));
        }
        surface_args.push_str(&format!(", {name}"));
    }
    for (i, l) in group.lights.iter().enumerate() {
        for p in &l.params {
            prim_params.push_str(&format!("{} __l{i}_{}; ", param_type_text(p), p.name.name));
            args.push(ArgSource::Light {
                index: i,
                name: p.name.name.clone(),
            });
        }
    }
    let mut atmosphere_args = String::new();
    if let Some(a) = group.atmosphere {
        for p in &a.params {
            prim_params.push_str(&format!("{} __a_{}; ", param_type_text(p), p.name.name));
            args.push(ArgSource::Atmosphere(p.name.name.clone()));
            atmosphere_args.push_str(&format!(", __a_{}", p.name.name));
        }
    }
    prim_params.push_str("float __lighting_from_device[4][4]; float __eye[4]; float __near[3]; ");
    args.push(ArgSource::LightingFromDevice);
    args.push(ArgSource::Eye);
    args.push(ArgSource::Near);

    // A global's planes are read only when the surface or the atmosphere names it (a
    // helper sees only what it is passed): an effect the shaders do not use reads nothing.
    let mut uses = Uses::of(&surface.body);
    if let Some(a) = group.atmosphere {
        uses.names.extend(Uses::of(&a.body).names);
    }
    let quads = group.quads;
    let used = &uses.names;
    let plane = |name: &str| {
        let wanted = match name {
            "N" => used.contains("N") || used.contains("Ng"),
            "s" | "t" | "st" => used.contains("s") || used.contains("t"),
            other => used.contains(other),
        };
        plane(name).filter(|_| wanted)
    };
    let read3 = |name: &str, default: &str, reads: &mut Vec<String>| -> String {
        match plane(name) {
            Some(pl) if pl.components >= 3 || pl.components == 1 => {
                reads.push(name.to_string());
                let k = |c: u32| pl.first_plane + if pl.components == 1 { 0 } else { c };
                format!(
                    "{{__gbuffer({}, X, Y), __gbuffer({}, X, Y), __gbuffer({}, X, Y)}}",
                    k(0),
                    k(1),
                    k(2)
                )
            }
            _ => default.to_string(),
        }
    };
    let read1 = |name: &str, reads: &mut Vec<String>| -> Option<String> {
        plane(name).map(|pl| {
            reads.push(name.to_string());
            format!("__gbuffer({}, X, Y)", pl.first_plane)
        })
    };
    let cs = read3("Cs", "1", &mut reads);
    let os = read3("Os", "1", &mut reads);
    let n = read3("N", "-I", &mut reads);
    let (s, t) = match (read1("s", &mut reads), read1("t", &mut reads)) {
        (Some(s), Some(t)) => (s, t),
        _ => match plane("st").filter(|p| p.components >= 2) {
            Some(pl) => {
                reads.push("st".into());
                (
                    format!("__gbuffer({}, X, Y)", pl.first_plane),
                    format!("__gbuffer({}, X, Y)", pl.first_plane + 1),
                )
            }
            None => ("0".into(), "0".into()),
        },
    };
    let material = match group.material {
        Some((plane, id)) => format!("if (__gbuffer({plane}, X, Y) != {id}) return;\n"),
        None => String::new(),
    };
    let atmosphere = if group.atmosphere.is_some() {
        format!("__atmosphere(P, I, E, Ci, Oi{atmosphere_args});\n")
    } else {
        String::new()
    };
    // On quads the group's lanes are not a row of the tile: the pixel centres come from
    // the two planes after the outputs (`runtime::shading::quads`).
    let (px, py) = if quads {
        let x = group.out_plane + 3;
        (format!("__gbuffer({x}, X, Y)"), format!("__gbuffer({}, X, Y)", x + 1))
    } else {
        ("X".to_string(), "Y".to_string())
    };
    text.push_str(&format!(
        "primitive {SHADE}({prim_params}varying float X, Y; inout varying fixed<32,32> Z) {{
bound(0, 0, 1e30, 1e30);
if (Z == 0) return;
{material}float q[4] = __lighting_from_device * {{{px}, {py}, float(Z), 1.0}};
vector P = {{q[0] / q[3], q[1] / q[3], q[2] / q[3]}};
vector E = {{__eye[0], __eye[1], __eye[2]}};
vector I = __eye[3] == 0 ? -E * max(dot({{__near[0], __near[1], __near[2]}} - P, E), 1e-20) : P - E;
normal N = {n};
normal Ng = N;
float s = {s}, t = {t};
color Cs = {cs}, Os = {os};
{varying_decls}color Ci = 0, Oi = Os;
__surface(P, N, Ng, I, E, s, t, Cs, Os, Ci, Oi{surface_args}{light_args});
{atmosphere}interpolation {{ {OUT_KIND}: interpolator_return(Ci); }}
}}
"
    ));

    // Parse, then set every generated span to the surface's name.
    let mut diags = Diagnostics::new();
    let module = crate::syntax::parse(GENERATED_FILE, &text, &mut diags);
    if diags.has_errors() {
        return Err(format!("generated shader group does not parse:\n{text}\n{diags:?}"));
    }
    let mut items = module.items;
    for item in &mut items {
        respan_item(item, span);
    }

    // Splice the shaders' parameters and bodies into their helpers.
    let lit = Rewrite {
        lights: &group.lights,
        text: &text_args,
    };
    for item in &mut items {
        let name = item.name.name.clone();
        if name == "__surface" {
            splice_params(item, &surface.params, Some(light_params_count(group)));
            let mut body = (*surface.body).clone();
            rewrite_block(&mut body, &lit);
            item.body = Box::new(body);
        } else if let Some(kind) = name.strip_prefix("__light_") {
            if let Some(l) = light_kinds.iter().find(|l| l.name.name == kind) {
                splice_params(item, &l.params, None);
                item.body = l.body.clone();
            }
        } else if name == "__atmosphere" {
            if let Some(a) = group.atmosphere {
                splice_params(item, &a.params, None);
                item.body = a.body.clone();
            }
        } else if MODELS.iter().any(|(m, _, _)| name == format!("__{m}")) {
            let mut body = (*item.body).clone();
            rewrite_block(&mut body, &lit);
            item.body = Box::new(body);
        }
    }
    copy_declarations(&mut items, group);
    reads.sort();
    reads.dedup();
    Ok(Linked {
        items,
        args,
        unprovided,
        reads,
    })
}

/// Link `shader` alone, against a frame with every conventional plane and one light of
/// each light shader in `lights` (a generic one when there is none): what `check` compiles
/// to report a shader's errors without a scene. A light or an atmosphere is linked with a
/// surface that uses every light.
pub fn canonical(shader: &Item, lights: &[&Item]) -> Result<Linked, String> {
    let planes: Vec<PlaneParam> = [("Cs", 3), ("Os", 3), ("N", 3), ("s", 1), ("t", 1)]
        .iter()
        .enumerate()
        .map(|(i, (n, c))| PlaneParam {
            name: n.to_string(),
            first_plane: 3 * i as u32,
            components: *c,
        })
        .collect();
    let span = shader.name.span;
    let fallback_surface = generated_item(CHECK_SURFACE, span)?;
    let generic_light = generated_item(CHECK_LIGHT, span)?;
    let mut all_lights = lights.to_vec();
    if all_lights.is_empty() {
        all_lights.push(&generic_light);
    }
    let (surface, lights, atmosphere) = match shader.kind {
        ItemKind::Surface => (shader, all_lights, None),
        ItemKind::Light => (&fallback_surface, vec![shader], None),
        _ => (&fallback_surface, all_lights, Some(shader)),
    };
    link(&Group {
        surface,
        lights,
        atmosphere,
        planes: &planes,
        material: None,
        surface_text: &[],
        out_plane: 15,
        quads: takes_derivatives(shader),
    })
}

/// What lights and atmospheres are checked with: a surface using every light.
const CHECK_SURFACE: &str = "surface __check_surface() { illuminance(P) { Ci += Cl * length(L); } }";
/// What surfaces are checked with when the program has no light shader.
const CHECK_LIGHT: &str = "light __check_light() { L = -Ps; Cl = 1; }";

/// The one item of generated `text`, every span set to `span`.
fn generated_item(text: &str, span: Span) -> Result<Item, String> {
    let mut diags = Diagnostics::new();
    let module = crate::syntax::parse(GENERATED_FILE, text, &mut diags);
    let mut item = module
        .items
        .into_iter()
        .next()
        .filter(|_| !diags.has_errors())
        .ok_or_else(|| format!("generated item does not parse: {text}"))?;
    respan_item(&mut item, span);
    Ok(item)
}

fn light_params_count(group: &Group) -> usize {
    group.lights.iter().map(|l| l.params.len()).sum()
}

fn light_call_args(l: &Item, i: usize) -> String {
    l.params.iter().map(|p| format!(", __l{i}_{}", p.name.name)).collect()
}

fn components_of(p: &ast::Param) -> u32 {
    let base = match p.ty.kind {
        ast::TypeKind::Point => 4,
        ast::TypeKind::Vector | ast::TypeKind::Normal | ast::TypeKind::Color => 3,
        ast::TypeKind::Matrix => 16,
        _ => 1,
    };
    let dims: u32 = p
        .dims
        .iter()
        .map(|d| match d {
            ast::ArrayDim::Sized(Expr {
                kind: ExprKind::Int(n), ..
            }) => (*n).clamp(0, 64) as u32,
            _ => 0,
        })
        .product();
    base * dims
}

/// `{__gbuffer(k, X, Y), ...}` for a varying parameter read from plane `pl`, or the single
/// read for a scalar.
fn plane_list(pl: &PlaneParam, p: &ast::Param) -> String {
    let reads: Vec<String> = (0..components_of(p))
        .map(|c| format!("__gbuffer({}, X, Y)", pl.first_plane + c))
        .collect();
    if reads.len() == 1
        && p.dims.is_empty()
        && !matches!(
            p.ty.kind,
            ast::TypeKind::Color | ast::TypeKind::Vector | ast::TypeKind::Normal | ast::TypeKind::Point
        )
    {
        reads[0].clone()
    } else {
        format!("{{{}}}", reads.join(", "))
    }
}

/// The base type of `p` as source text (generated parameters get their real type and
/// dimensions copied from the declaration after parsing: see [`copy_declarations`]).
fn param_type_text(p: &ast::Param) -> String {
    use ast::TypeKind as T;
    match p.ty.kind {
        T::Int => "int".into(),
        T::Bool => "bool".into(),
        T::Fixed { bits, frac } => format!("fixed<{bits},{frac}>"),
        T::Point => "point".into(),
        T::Vector => "vector".into(),
        T::Normal => "normal".into(),
        T::Color => "color".into(),
        T::Matrix => "matrix".into(),
        _ => "float".into(),
    }
}

/// `TYPE NAME[d]...` for a local declared like parameter `p` (literal dimensions only; the
/// declaration's dimensions are copied after parsing).
fn decl_text(p: &ast::Param) -> String {
    let mut out = format!("{} {}", param_type_text(p), p.name.name);
    for d in &p.dims {
        if let ast::ArrayDim::Sized(Expr {
            kind: ExprKind::Int(n), ..
        }) = d
        {
            out.push_str(&format!("[{n}]"));
        }
    }
    out
}

/// Give every generated parameter that stands for a shader's parameter that parameter's
/// type and dimensions (and, on the primitive, its default).
fn copy_declarations(items: &mut [Item], group: &Group) {
    let surface = group.surface;
    for item in items.iter_mut() {
        let prim = item.name.name == SHADE;
        for p in &mut item.params {
            let name = p.name.name.as_str();
            let from_surface = (prim || item.name.name == "__surface")
                .then(|| surface.params.iter().find(|q| q.name.name == name))
                .flatten();
            let from_light = name.strip_prefix("__l").and_then(|rest| {
                let (i, n) = rest.split_once('_')?;
                let l = group.lights.get(i.parse::<usize>().ok()?)?;
                l.params.iter().find(|q| q.name.name == n)
            });
            let from_atm = name
                .strip_prefix("__a_")
                .and_then(|n| group.atmosphere?.params.iter().find(|q| q.name.name == n));
            if let Some(src) = from_surface.or(from_light).or(from_atm) {
                p.ty = src.ty.clone();
                p.dims = src.dims.clone();
                p.default = if prim { src.default.clone() } else { None };
            }
        }
    }
}

/// Append the shader's parameters `params` to `item`'s (generated) ones, before the light
/// arguments when `light_tail` counts those at the end.
fn splice_params(item: &mut Item, params: &[ast::Param], light_tail: Option<usize>) {
    let at = item.params.len() - light_tail.unwrap_or(0);
    let mut own: Vec<ast::Param> = params
        .iter()
        .map(|p| {
            let mut p = p.clone();
            p.default = None;
            p
        })
        .collect();
    // Light arguments keep their generated names; their types come from the lights.
    let tail: Vec<ast::Param> = item.params.drain(at..).collect();
    item.params.append(&mut own);
    item.params.extend(tail);
}

/// Unroll `illuminance` and route the light-dependent built-ins in `block`.
/// The value of each `string` parameter of `surface`: the scene's, else its default (a
/// string literal), else empty.
fn text_values(surface: &Item, given: &[(String, String)]) -> Vec<(String, String)> {
    surface
        .params
        .iter()
        .filter(|p| p.ty.kind == ast::TypeKind::String)
        .map(|p| {
            let name = p.name.name.clone();
            let value = match given.iter().find(|(n, _)| *n == name) {
                Some((_, v)) => v.clone(),
                None => match &p.default {
                    Some(Expr {
                        kind: ExprKind::Str(v), ..
                    }) => v.clone(),
                    _ => String::new(),
                },
            };
            (name, value)
        })
        .collect()
}

/// What the rewrite of a surface's body (and the models') needs: the frame's lights, and
/// the values of the surface's `string` parameters, which replace their names.
struct Rewrite<'a> {
    lights: &'a [&'a Item],
    text: &'a [(String, String)],
}

fn rewrite_block(block: &mut ast::Block, rw: &Rewrite) {
    for s in &mut block.stmts {
        rewrite_stmt(s, rw);
    }
}

fn rewrite_stmt(s: &mut Stmt, rw: &Rewrite) {
    if let StmtKind::Illuminance { args, body } = &mut s.kind {
        let span = s.span;
        let mut blocks = vec![];
        for (i, l) in rw.lights.iter().enumerate() {
            if is_ambient(l) {
                continue;
            }
            let mut inner = body.clone();
            rewrite_block(&mut inner, rw);
            blocks.push(light_block(l, i, args, inner, span));
        }
        s.kind = StmtKind::Block(ast::Block { stmts: blocks, span });
        return;
    }
    match &mut s.kind {
        StmtKind::Decl { vars, .. } => {
            for v in vars {
                if let Some(init) = &mut v.init {
                    rewrite_expr(init, rw);
                }
            }
        }
        StmtKind::Assign { target, value, .. } => {
            rewrite_expr(target, rw);
            rewrite_expr(value, rw);
        }
        StmtKind::Expr(e) => rewrite_expr(e, rw),
        StmtKind::Return(Some(e)) => rewrite_expr(e, rw),
        StmtKind::If { cond, then, otherwise } => {
            rewrite_expr(cond, rw);
            rewrite_block(then, rw);
            if let Some(o) = otherwise {
                rewrite_block(o, rw);
            }
        }
        StmtKind::For { init, cond, step, body } => {
            if let Some(i) = init {
                rewrite_stmt(i, rw);
            }
            if let Some(c) = cond {
                rewrite_expr(c, rw);
            }
            if let Some(st) = step {
                rewrite_stmt(st, rw);
            }
            rewrite_block(body, rw);
        }
        StmtKind::While { cond, body } => {
            rewrite_expr(cond, rw);
            rewrite_block(body, rw);
        }
        StmtKind::Block(b) => rewrite_block(b, rw),
        _ => {}
    }
}

/// A call of a light-dependent built-in gets the surface point and every light argument.
fn rewrite_expr(e: &mut Expr, rw: &Rewrite) {
    match &mut e.kind {
        ExprKind::Call { callee, args } => {
            for a in args.iter_mut() {
                rewrite_expr(a, rw);
            }
            if MODELS.iter().any(|(m, _, _)| callee.name == *m) {
                callee.name = format!("__{}", callee.name);
                let span = callee.span;
                args.push(name_expr("P", span));
                for (i, l) in rw.lights.iter().enumerate() {
                    for p in &l.params {
                        args.push(name_expr(&format!("__l{i}_{}", p.name.name), span));
                    }
                }
            }
        }
        ExprKind::Unary { expr, .. } => rewrite_expr(expr, rw),
        ExprKind::Binary { lhs, rhs, .. } => {
            rewrite_expr(lhs, rw);
            rewrite_expr(rhs, rw);
        }
        ExprKind::Ternary { cond, then, otherwise } => {
            rewrite_expr(cond, rw);
            rewrite_expr(then, rw);
            rewrite_expr(otherwise, rw);
        }
        ExprKind::Index { base, index } => {
            rewrite_expr(base, rw);
            rewrite_expr(index, rw);
        }
        ExprKind::Field { base, .. } => rewrite_expr(base, rw),
        ExprKind::Name(n) => {
            if let Some((_, text)) = rw.text.iter().find(|(name, _)| *name == n.name) {
                e.kind = ExprKind::Str(text.clone());
            }
        }
        ExprKind::Construct { args, .. } | ExprKind::List(args) => {
            for a in args {
                rewrite_expr(a, rw);
            }
        }
        _ => {}
    }
}

fn name_expr(name: &str, span: Span) -> Expr {
    Expr {
        kind: ExprKind::Name(ast::Ident {
            name: name.to_string(),
            span,
        }),
        span,
    }
}

/// One light's turn of an `illuminance` loop:
/// `{ vector L = 0; color Cl = 0; __light_K(Ps, L, Cl, args); if (cone) { body } }`.
fn light_block(l: &Item, i: usize, args: &[Expr], body: ast::Block, span: Span) -> Stmt {
    let cone = if args.len() >= 3 {
        "dot(normalize(L), normalize(__axis)) >= cos(__angle)"
    } else {
        "true"
    };
    let text = format!(
        "void __t() {{ {{ vector L = 0; color Cl = 0; __light_{}(__ps, L, Cl{}); if ({cone}) {{}} }} }}",
        l.name.name,
        light_call_args(l, i)
    );
    let mut diags = Diagnostics::new();
    let module = crate::syntax::parse(GENERATED_FILE, &text, &mut diags);
    let Some(mut item) = module.items.into_iter().next() else {
        return Stmt {
            kind: StmtKind::Error,
            span,
        };
    };
    respan_item(&mut item, span);
    let mut stmt = item.body.stmts.remove(0);
    let subst = |e: &mut Expr| {
        if let ExprKind::Name(n) = &e.kind {
            let with = match n.name.as_str() {
                "__ps" => args.first(),
                "__axis" => args.get(1),
                "__angle" => args.get(2),
                _ => None,
            };
            if let Some(w) = with {
                *e = w.clone();
            }
        }
    };
    if let StmtKind::Block(b) = &mut stmt.kind {
        for s in &mut b.stmts {
            match &mut s.kind {
                StmtKind::Expr(Expr {
                    kind: ExprKind::Call { args, .. },
                    ..
                }) => args.iter_mut().for_each(subst),
                StmtKind::If { cond, then, .. } => {
                    walk_expr_mut(cond, &subst);
                    *then = body.clone();
                }
                _ => {}
            }
        }
    }
    stmt
}

fn walk_expr_mut(e: &mut Expr, f: &impl Fn(&mut Expr)) {
    f(e);
    match &mut e.kind {
        ExprKind::Call { args, .. } | ExprKind::Construct { args, .. } | ExprKind::List(args) => {
            args.iter_mut().for_each(|a| walk_expr_mut(a, f))
        }
        ExprKind::Unary { expr, .. } => walk_expr_mut(expr, f),
        ExprKind::Binary { lhs, rhs, .. } => {
            walk_expr_mut(lhs, f);
            walk_expr_mut(rhs, f);
        }
        _ => {}
    }
}

fn respan_item(item: &mut Item, span: Span) {
    item.span = span;
    item.name.span = span;
    for p in &mut item.params {
        p.span = span;
        p.name.span = span;
        p.ty.span = span;
        if let Some(d) = &mut p.default {
            respan_expr(d, span);
        }
        for d in &mut p.dims {
            match d {
                ast::ArrayDim::Sized(e) => respan_expr(e, span),
                ast::ArrayDim::Unsized(s) => *s = span,
            }
        }
        if let Some((_, s)) = &mut p.quals.variability {
            *s = span;
        }
        if let Some(s) = &mut p.quals.inout {
            *s = span;
        }
    }
    if let Some(r) = &mut item.ret {
        r.span = span;
    }
    respan_block(&mut item.body, span);
}

fn respan_block(b: &mut ast::Block, span: Span) {
    b.span = span;
    for s in &mut b.stmts {
        respan_stmt(s, span);
    }
}

fn respan_stmt(s: &mut Stmt, span: Span) {
    s.span = span;
    match &mut s.kind {
        StmtKind::Decl { quals, ty, vars } => {
            if let Some((_, sp)) = &mut quals.variability {
                *sp = span;
            }
            ty.span = span;
            for v in vars {
                v.span = span;
                v.name.span = span;
                if let Some(i) = &mut v.init {
                    respan_expr(i, span);
                }
                for d in &mut v.dims {
                    if let ast::ArrayDim::Sized(e) = d {
                        respan_expr(e, span);
                    }
                }
            }
        }
        StmtKind::Assign { target, value, .. } => {
            respan_expr(target, span);
            respan_expr(value, span);
        }
        StmtKind::Expr(e) | StmtKind::Return(Some(e)) | StmtKind::InterpolatorReturn(Some(e)) => respan_expr(e, span),
        StmtKind::If { cond, then, otherwise } => {
            respan_expr(cond, span);
            respan_block(then, span);
            if let Some(o) = otherwise {
                respan_block(o, span);
            }
        }
        StmtKind::For { init, cond, step, body } => {
            if let Some(i) = init {
                respan_stmt(i, span);
            }
            if let Some(c) = cond {
                respan_expr(c, span);
            }
            if let Some(st) = step {
                respan_stmt(st, span);
            }
            respan_block(body, span);
        }
        StmtKind::While { cond, body } => {
            respan_expr(cond, span);
            respan_block(body, span);
        }
        StmtKind::Interpolation { arms } => {
            for a in arms {
                a.span = span;
                if let ast::InterpArmKind::Named(n) = &mut a.kind {
                    n.span = span;
                }
                if let ast::InterpArmKind::Default(s) = &mut a.kind {
                    *s = span;
                }
                for s in &mut a.body {
                    respan_stmt(s, span);
                }
            }
        }
        StmtKind::Bound(args) => args.iter_mut().for_each(|e| respan_expr(e, span)),
        StmtKind::Illuminance { args, body } => {
            args.iter_mut().for_each(|e| respan_expr(e, span));
            respan_block(body, span);
        }
        StmtKind::Block(b) => respan_block(b, span),
        _ => {}
    }
}

fn respan_expr(e: &mut Expr, span: Span) {
    e.span = span;
    match &mut e.kind {
        ExprKind::Name(n) => n.span = span,
        ExprKind::Call { callee, args } => {
            callee.span = span;
            args.iter_mut().for_each(|a| respan_expr(a, span));
        }
        ExprKind::Construct { ty, args } => {
            ty.span = span;
            args.iter_mut().for_each(|a| respan_expr(a, span));
        }
        ExprKind::List(args) => args.iter_mut().for_each(|a| respan_expr(a, span)),
        ExprKind::Unary { expr, .. } => respan_expr(expr, span),
        ExprKind::Binary { lhs, rhs, .. } => {
            respan_expr(lhs, span);
            respan_expr(rhs, span);
        }
        ExprKind::Ternary { cond, then, otherwise } => {
            respan_expr(cond, span);
            respan_expr(then, span);
            respan_expr(otherwise, span);
        }
        ExprKind::Index { base, index } => {
            respan_expr(base, span);
            respan_expr(index, span);
        }
        ExprKind::Field { base, field } => {
            respan_expr(base, span);
            field.span = span;
        }
        _ => {}
    }
}
