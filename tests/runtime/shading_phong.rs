//! The fused Phong evaluation of the deferred shading pass (src/runtime/shading/mod.rs):
//! `phong_and_specular_share` is bit for bit the two calls it replaces, on random setups
//! with both eye kinds, directional and positional lights and zero normals.

use primflow::pipeline::face::Facing;
use primflow::pipeline::lighting::{Eye, Light, LightKind, LightingSetup, Material, Sample};
use primflow::runtime::shading::phong_and_specular_share;

/// The specular share as the two-call path computes it: `shade_facing` on a copy of the
/// setup whose materials keep only the specular term.
fn specular_share_reference(setup: &LightingSetup<f64>, s: &Sample<f64>, facing: Facing) -> [f64; 3] {
    let material = match facing {
        Facing::Front => setup.front,
        Facing::Back => setup.back,
    };
    if material.specular == [0.0; 3] {
        return [0.0; 3];
    }
    let m = Material {
        ambient: [0.0; 3],
        diffuse: [0.0; 3],
        ..material
    };
    LightingSetup {
        front: m,
        back: m,
        ..setup.clone()
    }
    .shade_facing(s, facing)
}

#[test]
fn fused_phong_is_bit_identical_to_two_shade_calls() {
    let mut seed = 0x9e3779b97f4a7c15u64;
    let mut next = move || {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64 * 4.0 - 2.0
    };
    let mut v3 = || [next(), next(), next()];
    let mut checked = 0;
    for case in 0..400 {
        let material = |spec: bool, v: &mut dyn FnMut() -> [f64; 3]| Material {
            ambient: v().map(f64::abs),
            diffuse: v().map(f64::abs),
            specular: if spec { v().map(f64::abs) } else { [0.0; 3] },
            shininess: 1.0 + v()[0].abs() * 20.0,
        };
        let lights = (0..case % 9)
            .map(|i| Light {
                kind: if i % 2 == 0 {
                    LightKind::Directional { towards_light: v3() }
                } else {
                    LightKind::Positional {
                        position: v3(),
                        attenuation: [1.0, v3()[0].abs(), if i % 3 == 0 { -5.0 } else { 0.1 }],
                    }
                },
                colour: v3().map(f64::abs),
            })
            .collect();
        let setup = LightingSetup {
            front: material(case % 4 != 0, &mut v3),
            back: material(case % 5 != 0, &mut v3),
            ambient_light: v3().map(f64::abs),
            lights,
            eye: if case % 3 == 0 {
                Eye::Direction(v3())
            } else {
                Eye::Point(v3())
            },
        };
        let normal = if case % 17 == 0 { [0.0; 3] } else { v3() };
        let sample = Sample { point: v3(), normal };
        for facing in [Facing::Front, Facing::Back] {
            let (lit, spec) = phong_and_specular_share(&setup, &sample, facing);
            let expected_lit = setup.shade_facing(&sample, facing);
            let expected_spec = specular_share_reference(&setup, &sample, facing);
            assert_eq!(
                lit.map(f64::to_bits),
                expected_lit.map(f64::to_bits),
                "case {case} {facing:?}"
            );
            assert_eq!(
                spec.map(f64::to_bits),
                expected_spec.map(f64::to_bits),
                "case {case} {facing:?}"
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 800);
}
