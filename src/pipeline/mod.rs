//! The geometry pipeline math (seeds 000, 001, 002): what happens to a primitive's points
//! and normals between the scene calls and the kernels, which then run on points already
//! in homogeneous device coordinates. Pure functions and small types; no rendering.
//!
//! # Stages, in pipeline order
//! 1. [`transform`] — model stack M (`world_from_object`), view V (`clip_from_world`: look-at
//!    times perspective / orthographic / oblique, or an arbitrary 4x4), viewport D
//!    (`device_from_clip`); composites evaluated lazily and cached; normals by the
//!    cofactor (inverse-transpose direction) matrix.
//! 2. [`factor`] — V = G Q E (perspective) or S H E (parallel) for canonical views:
//!    lighting coordinates LC = E * WC, the sparse remainder to clip space, and the adapted
//!    W-clip (near/far clip in LC, which also removes w <= 0).
//! 3. [`face`] — front/back from the signed area in device space (front = counter-clockwise
//!    on screen, y down), for culling and for choosing the front or back material.
//! 4. [`lighting`] — Phong with directional and positional lights, in whichever one space the
//!    caller lights in (LC normally, WC as the fallback).
//! 5. [`clip`] — branch-free 7-bit clip codes, AND/OR trivial reject / accept, and
//!    Sutherland-Hodgman clipping in homogeneous clip space against only the planes crossed,
//!    plus a `w = epsilon` plane and model clip planes, carrying any number of attributes.
//!
//! Then the runtime divides by w (safe: clipped or accepted vertices have w > 0) and hands
//! the device-space points to the primitive's kernel.
//!
//! # Well-behaved and ill-behaved cases (seed 000 sections 4.2.2 and 9)
//! | case | detected by | handled by |
//! |---|---|---|
//! | well-behaved: M affine and invertible, V canonical, single pyramid, finite data | [`choose_pipeline`] | CC / LC pipelines, lighting in MC or LC (correct) |
//! | w <= 0 model data (9.2) | [`transform::sanitize_model_w`] | negative w: whole point negated (same projective point); w = 0: small positive w (expedient, [`Warning::NonPositiveModelW`]) |
//! | projective M (9.3) | [`transform::classify_model`] | full 4x4 transform, w assumed positive; normals by the cofactor matrix of M's upper 3x3 like an affine M's (not yet per point: [`transform::transform_normal_projective`] is written but not called); lighting in WC (expedient, [`Warning::ProjectiveModel`]) |
//! | singular M (9.4) | [`transform::NormalMatrix::of`] | the `N` shading parameter given under it is zeroed, which shading lights ambient-only as 9.4 suggests; `normal` parameters by the cofactor matrix, zero ones replaced by +z ([`Warning::SingularModel`], [`Warning::DegenerateNormal`]) |
//! | non-factorizable V (9.5) | [`factor::factor_view`] `Err` | E = I, GQ = V: LC pipelines run in WC (correct, [`Warning::NonFactorizableView`]) |
//! | singular V (9.1) | [`factor::NotFactorizable::Singular`] | no model clipping, no LC (expedient, [`Warning::SingularView`]) |
//! | double pyramid (9.6) | [`transform::normalise_pyramid`] | 7-bit codes with the W sign bit, two-piece clipping ([`clip::PyramidMode::Double`], correct, [`Warning::DoublePyramidView`]) |
//! | NaN / inf vertices | [`clip`] codes (`CLIP_ALL`) | trivially rejected or [`clip::ClipError::NonFinite`]: the primitive is dropped ([`Warning::NonFiniteVertex`]) |
//!
//! # Specialised pipelines
//! [`PipelineKind`] names the pipelines of seed 000 sections 5-7 and their world-coordinate
//! fallbacks (9.3-9.5); [`choose_pipeline`] picks one from the geometry type and the state
//! (M's class, V factorizable / invertible, single or double pyramid, lit or not, the do_*
//! clipping flags), with the warnings of the ill-behaved cases it had to accept. The
//! runtime prints the choice for `render --explain`.

pub mod clip;
pub mod face;
pub mod factor;
pub mod lighting;
pub mod real;
pub mod transform;

use std::fmt;

use clip::PyramidMode;
use factor::NotFactorizable;
use transform::{ModelClass, TransformState};

/// An ill-behaved case the pipeline handled, correctly or expediently (seed 000 section 9:
/// "wherever an expedient choice is made, a warning message should be generated").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Warning {
    /// M is singular (9.4).
    SingularModel,
    /// A normal transformed to zero and was replaced by +z.
    DegenerateNormal,
    /// M is projective (9.3).
    ProjectiveModel,
    /// Model data had w <= 0 (9.2).
    NonPositiveModelW,
    /// V is not in canonical form (9.5).
    NonFactorizableView(NotFactorizable),
    /// V (or D) is singular (9.1).
    SingularView,
    /// The view volume wraps around infinity (9.6).
    DoublePyramidView,
    /// A vertex had a NaN or infinite coordinate; its primitive was dropped.
    NonFiniteVertex,
}

impl fmt::Display for Warning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Warning::SingularModel => write!(
                f,
                "model transform is singular: `N` values given under it are zeroed, so the pixels they shade get ambient light only; `normal` parameters use its cofactor matrix"
            ),
            Warning::DegenerateNormal => {
                write!(f, "a normal transformed to the zero vector and was replaced by (0, 0, 1)")
            }
            Warning::ProjectiveModel => write!(
                f,
                "model transform is projective: w is assumed positive and lighting happens in world coordinates"
            ),
            Warning::NonPositiveModelW => write!(
                f,
                "model data has w <= 0: negative w negated, zero w set to a small positive value"
            ),
            Warning::NonFactorizableView(why) => {
                write!(f, "{why}; lighting happens in world coordinates instead of lighting coordinates")
            }
            Warning::SingularView => write!(
                f,
                "view transform is singular: no model clipping, lighting in world coordinates"
            ),
            Warning::DoublePyramidView => write!(
                f,
                "view volume wraps around infinity (double pyramid): 7-bit clip codes and two-piece clipping"
            ),
            Warning::NonFiniteVertex => write!(
                f,
                "a vertex has a NaN or infinite coordinate; its primitive is dropped (a line only its segments at that vertex)"
            ),
        }
    }
}

/// Seed 000's geometry types (table 1). Procedural primitives that cover an area (polygon,
/// sphere) go through the facet or surface pipelines.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum GeometryType {
    Point,
    PointWithExtent,
    Line,
    Curve,
    Facet,
    Surface,
}

/// The specialised pipelines of seed 000 sections 5-7, and the world-coordinate variants the
/// LC pipelines fall back to when LC is unavailable (9.3-9.5).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PipelineKind {
    /// 5.1: points, transformed by CVM, clip-tested in CC.
    CcPoint,
    /// 5.2: points with extent, front/back clip codes only.
    CcPointWithExtent,
    /// 6.1: lines, clipped in CC4.
    CcLine,
    /// 6.2: curves tessellated in LC.
    LcCurve,
    /// 6.2 with WC for LC (9.5).
    WcCurve,
    /// 7.1: facets lit in model coordinates (isotropic M, or no lighting).
    CcFacet,
    /// 7.2: facets lit in lighting coordinates (affine M, canonical V).
    LcFacet,
    /// 7.2 with WC for LC (9.3, 9.5).
    WcFacet,
    /// 7.3: curved surfaces tessellated and lit in LC.
    LcSurface,
    /// 7.3 with WC for LC (9.3-9.5).
    WcSurface,
}

impl PipelineKind {
    /// The seed 000 section this pipeline comes from.
    pub fn section(self) -> &'static str {
        match self {
            PipelineKind::CcPoint => "5.1",
            PipelineKind::CcPointWithExtent => "5.2",
            PipelineKind::CcLine => "6.1",
            PipelineKind::LcCurve => "6.2",
            PipelineKind::WcCurve => "6.2 + 9.5",
            PipelineKind::CcFacet => "7.1",
            PipelineKind::LcFacet => "7.2",
            PipelineKind::WcFacet => "7.2 + 9.5",
            PipelineKind::LcSurface => "7.3",
            PipelineKind::WcSurface => "7.3 + 9.5",
        }
    }
}

impl fmt::Display for PipelineKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let name = match self {
            PipelineKind::CcPoint => "CC point",
            PipelineKind::CcPointWithExtent => "CC point-with-extent",
            PipelineKind::CcLine => "CC line",
            PipelineKind::LcCurve => "LC curve",
            PipelineKind::WcCurve => "WC curve",
            PipelineKind::CcFacet => "CC facet",
            PipelineKind::LcFacet => "LC facet",
            PipelineKind::WcFacet => "WC facet",
            PipelineKind::LcSurface => "LC surface",
            PipelineKind::WcSurface => "WC surface",
        };
        write!(f, "{name} pipeline (seed 000 {})", self.section())
    }
}

/// The space lighting is computed in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LightingSpace {
    /// Nothing is lit (points, lines, unlit facets).
    None,
    /// Model coordinates, lights transformed to MC once per M (isotropic M).
    Model,
    /// Lighting coordinates (E * WC).
    Lighting,
    /// World coordinates (the fallback).
    World,
}

/// What [`choose_pipeline`] looks at.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PipelineState {
    pub geometry: GeometryType,
    pub model: ModelClass,
    /// `Ok` when V is in canonical form, else why not ([`factor::factor_view`]);
    /// `Err(Singular)` / `Err(NonFinite)` mean V itself is unusable (seed 000 9.1).
    pub view_factoring: Result<(), NotFactorizable>,
    pub pyramid: PyramidMode,
    /// The primitive needs lighting (normals and lights), not just interpolated colours.
    pub lit: bool,
    /// seed 000 4.2.9: the caller does not know the primitive is inside the view volume.
    pub do_view_clipping: bool,
    /// seed 000 4.2.9: model clip planes are active and may cut the primitive.
    pub do_model_clipping: bool,
}

impl PipelineState {
    /// The state of `transforms` for one primitive.
    pub fn from_transforms(
        transforms: &TransformState,
        geometry: GeometryType,
        lit: bool,
        do_view_clipping: bool,
        do_model_clipping: bool,
    ) -> PipelineState {
        PipelineState {
            geometry,
            model: transforms.model_class(),
            view_factoring: transforms.view_factors().map(|_| ()),
            pyramid: transforms.pyramid_mode(),
            lit,
            do_view_clipping,
            do_model_clipping,
        }
    }
}

/// The pipeline chosen for a state, and what it had to give up.
#[derive(Clone, Debug, PartialEq)]
pub struct PipelineChoice {
    pub kind: PipelineKind,
    pub lighting: LightingSpace,
    pub pyramid: PyramidMode,
    pub do_view_clipping: bool,
    /// False when requested but impossible (singular V, 9.1).
    pub do_model_clipping: bool,
    pub warnings: Vec<Warning>,
}

impl fmt::Display for PipelineChoice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.kind)?;
        let lighting = match self.lighting {
            LightingSpace::None => "unlit",
            LightingSpace::Model => "lit in model coordinates",
            LightingSpace::Lighting => "lit in lighting coordinates",
            LightingSpace::World => "lit in world coordinates",
        };
        write!(f, ", {lighting}")?;
        let pyramid = match self.pyramid {
            PyramidMode::Single => "single-pyramid",
            PyramidMode::Double => "double-pyramid",
        };
        write!(
            f,
            ", {pyramid} view, view clipping {}, model clipping {}",
            if self.do_view_clipping { "on" } else { "off" },
            if self.do_model_clipping { "on" } else { "off" }
        )?;
        for w in &self.warnings {
            write!(f, "\n  warning: {w}")?;
        }
        Ok(())
    }
}

/// Picks the specialised pipeline for a primitive (seed 000 sections 5-7, with the
/// section 9 fallbacks for whatever is ill-behaved).
pub fn choose_pipeline(state: &PipelineState) -> PipelineChoice {
    let mut warnings = vec![];
    let mut do_model_clipping = state.do_model_clipping;
    let view_invertible = !matches!(
        state.view_factoring,
        Err(NotFactorizable::Singular) | Err(NotFactorizable::NonFinite)
    );
    if !view_invertible {
        warnings.push(Warning::SingularView);
        do_model_clipping = false;
    }
    if state.pyramid == PyramidMode::Double {
        warnings.push(Warning::DoublePyramidView);
    }
    // LC needs a canonical V and an affine, invertible M (4.2.2 item 3).
    let lc_possible = state.view_factoring.is_ok();
    let m_affine = matches!(
        state.model,
        ModelClass::Euclidean | ModelClass::Isotropic | ModelClass::Affine
    );
    let note_model = |warnings: &mut Vec<Warning>| match state.model {
        ModelClass::Singular => warnings.push(Warning::SingularModel),
        ModelClass::Projective => warnings.push(Warning::ProjectiveModel),
        _ => {}
    };
    let lc_or_wc = |lc: PipelineKind, wc: PipelineKind, warnings: &mut Vec<Warning>| {
        if lc_possible && m_affine {
            (lc, LightingSpace::Lighting)
        } else {
            if let Err(why) = state.view_factoring {
                if view_invertible {
                    warnings.push(Warning::NonFactorizableView(why));
                }
            }
            (wc, LightingSpace::World)
        }
    };
    let (kind, lighting) = match state.geometry {
        GeometryType::Point => (PipelineKind::CcPoint, LightingSpace::None),
        GeometryType::PointWithExtent => (PipelineKind::CcPointWithExtent, LightingSpace::None),
        GeometryType::Line => (PipelineKind::CcLine, LightingSpace::None),
        GeometryType::Curve => {
            note_model(&mut warnings);
            let (k, _) = lc_or_wc(PipelineKind::LcCurve, PipelineKind::WcCurve, &mut warnings);
            (k, LightingSpace::None)
        }
        GeometryType::Facet if !state.lit => (PipelineKind::CcFacet, LightingSpace::None),
        GeometryType::Facet => match state.model {
            ModelClass::Euclidean | ModelClass::Isotropic if view_invertible => {
                (PipelineKind::CcFacet, LightingSpace::Model)
            }
            ModelClass::Singular => {
                note_model(&mut warnings);
                (PipelineKind::CcFacet, LightingSpace::Model)
            }
            _ => {
                note_model(&mut warnings);
                lc_or_wc(PipelineKind::LcFacet, PipelineKind::WcFacet, &mut warnings)
            }
        },
        GeometryType::Surface => {
            note_model(&mut warnings);
            let (k, space) = lc_or_wc(PipelineKind::LcSurface, PipelineKind::WcSurface, &mut warnings);
            (k, if state.lit { space } else { LightingSpace::None })
        }
    };
    PipelineChoice {
        kind,
        lighting,
        pyramid: state.pyramid,
        do_view_clipping: state.do_view_clipping,
        do_model_clipping,
        warnings,
    }
}
