//! The Phong lighting model (ambient + diffuse + specular) with directional and positional
//! lights, distance attenuation and front/back materials, generic over `f32` / `f64`.
//!
//! Every input — point, normal, eye, lights — must be in ONE coordinate system, whichever the
//! caller picks: lighting coordinates (LC, the normal case), world coordinates (the
//! fallback when V is not factorizable), or even device coordinates (which is *wrong* under
//! perspective, seed 001 figure 2, and is offered only so that error can be measured).
//! Because LC is a rigid image of WC, the same scene lit in LC and in WC gives the same
//! colours; the tests check that, and that "DC lighting" does not.
//!
//! The model, per light with colour `C` and unit vector `L` towards it:
//! `colour = ka * ambient + sum( att * C * (kd * max(N.L, 0) + ks * max(R.V, 0)^shininess) )`
//! where `R = 2 (N.L) N - L` is L mirrored about N, `V` the unit vector towards the eye
//! (for a parallel view, the fixed direction towards the viewer), specular only where
//! `N.L > 0`, and `att = 1 / (c0 + c1 d + c2 d^2)` for positional lights at distance d
//! (1 for directional ones; a non-positive or non-finite denominator counts as 1, so bad
//! coefficients cannot produce inf or NaN).
//!
//! Facing: the side of the surface the eye is on, `N.V >= 0` being front (seed 000 3.0 step 5:
//! "positive or zero" is front). Back-facing points use the back material and the flipped
//! normal, so a two-sided surface lights the same from either side. A caller that already
//! determined facing in device space ([`super::face`]) passes it in instead.

use super::face::Facing;
use super::real::{add3, dot3, length3, normalize3, scale3, sub3, Real, V3};

/// Reflectance of one side of a surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material<T> {
    pub ambient: V3<T>,
    pub diffuse: V3<T>,
    pub specular: V3<T>,
    pub shininess: T,
}

/// Where a light is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightKind<T> {
    /// At infinity; `towards_light` need not be unit length.
    Directional { towards_light: V3<T> },
    /// At `position`, attenuated by `1 / (c0 + c1 d + c2 d^2)`.
    Positional { position: V3<T>, attenuation: [T; 3] },
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light<T> {
    pub kind: LightKind<T>,
    pub colour: V3<T>,
}

/// Where the viewer is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Eye<T> {
    /// A perspective eye point.
    Point(V3<T>),
    /// A parallel view: the direction towards the viewer.
    Direction(V3<T>),
}

/// One shading sample: a point with its normal, in the lighting space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample<T> {
    pub point: V3<T>,
    pub normal: V3<T>,
}

/// Everything but the sample: materials, lights, ambient light, eye.
#[derive(Clone, Debug, PartialEq)]
pub struct LightingSetup<T> {
    pub front: Material<T>,
    pub back: Material<T>,
    pub ambient_light: V3<T>,
    pub lights: Vec<Light<T>>,
    pub eye: Eye<T>,
}

impl<T: Real> LightingSetup<T> {
    /// The unit vector from `point` towards the viewer (`None` if the point is the eye).
    pub fn towards_eye(&self, point: V3<T>) -> Option<V3<T>> {
        match self.eye {
            Eye::Point(e) => normalize3(sub3(e, point)),
            Eye::Direction(d) => normalize3(d),
        }
    }

    /// Which side of the surface the eye sees at this sample.
    pub fn facing(&self, s: &Sample<T>) -> Facing {
        match (self.towards_eye(s.point), normalize3(s.normal)) {
            (Some(v), Some(n)) if dot3(n, v) < T::ZERO => Facing::Back,
            _ => Facing::Front,
        }
    }

    /// The Phong colour at `s`, with facing determined here from the normal and the eye.
    pub fn shade(&self, s: &Sample<T>) -> V3<T> {
        self.shade_facing(s, self.facing(s))
    }

    /// The Phong colour at `s` for a facing already known. A zero or non-finite normal
    /// gets ambient light only (the case seed 000 9.4 prescribes for singular M).
    pub fn shade_facing(&self, s: &Sample<T>, facing: Facing) -> V3<T> {
        let material = match facing {
            Facing::Front => &self.front,
            Facing::Back => &self.back,
        };
        let mut colour = mul3(material.ambient, self.ambient_light);
        let Some(mut n) = normalize3(s.normal) else {
            return colour;
        };
        if facing == Facing::Back {
            n = scale3(n, -T::ONE);
        }
        let v = self.towards_eye(s.point);
        for light in &self.lights {
            let (l, att) = match light.kind {
                LightKind::Directional { towards_light } => (normalize3(towards_light), T::ONE),
                LightKind::Positional { position, attenuation } => {
                    let to_light = sub3(position, s.point);
                    let d = length3(to_light);
                    let denom = attenuation[0] + attenuation[1] * d + attenuation[2] * d * d;
                    let att = if denom > T::ZERO && denom.is_finite() {
                        T::ONE / denom
                    } else {
                        T::ONE
                    };
                    (normalize3(to_light), att)
                }
            };
            let Some(l) = l else { continue };
            let n_dot_l = dot3(n, l);
            if n_dot_l <= T::ZERO {
                continue;
            }
            let mut term = scale3(material.diffuse, n_dot_l);
            if let Some(v) = v {
                let r = sub3(scale3(n, (T::ONE + T::ONE) * n_dot_l), l);
                let r_dot_v = dot3(r, v);
                if r_dot_v > T::ZERO {
                    term = add3(term, scale3(material.specular, r_dot_v.powf(material.shininess)));
                }
            }
            colour = add3(colour, scale3(mul3(term, light.colour), att));
        }
        colour
    }
}

impl LightingSetup<f64> {
    /// The same setup rounded to f32 (what an f32 shading path is handed).
    pub fn to_f32(&self) -> LightingSetup<f32> {
        let v = |a: [f64; 3]| a.map(|c| c as f32);
        let m = |m: &Material<f64>| Material {
            ambient: v(m.ambient),
            diffuse: v(m.diffuse),
            specular: v(m.specular),
            shininess: m.shininess as f32,
        };
        LightingSetup {
            front: m(&self.front),
            back: m(&self.back),
            ambient_light: v(self.ambient_light),
            lights: self
                .lights
                .iter()
                .map(|l| Light {
                    kind: match l.kind {
                        LightKind::Positional { position, attenuation } => LightKind::Positional {
                            position: v(position),
                            attenuation: v(attenuation),
                        },
                        LightKind::Directional { towards_light } => LightKind::Directional {
                            towards_light: v(towards_light),
                        },
                    },
                    colour: v(l.colour),
                })
                .collect(),
            eye: match self.eye {
                Eye::Point(p) => Eye::Point(v(p)),
                Eye::Direction(d) => Eye::Direction(v(d)),
            },
        }
    }
}

#[inline]
fn mul3<T: Real>(a: V3<T>, b: V3<T>) -> V3<T> {
    [a[0] * b[0], a[1] * b[1], a[2] * b[2]]
}
