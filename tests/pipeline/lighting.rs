//! Phong lighting: exact single-light values, facing, and seed 001's figure 2 experiment —
//! lighting in LC equals lighting in WC, lighting in (perspective) device space does not.

use glam::{DMat4, DVec3, DVec4};
use primflow::pipeline::face::Facing;
use primflow::pipeline::factor::factor_view;
use primflow::pipeline::lighting::*;
use primflow::pipeline::transform::{look_at_matrix, perspective_matrix};

fn material(kd: f64, ks: f64) -> Material<f64> {
    Material {
        ambient: [0.1, 0.1, 0.1],
        diffuse: [kd, kd * 0.8, kd * 0.6],
        specular: [ks, ks, ks],
        shininess: 20.0,
    }
}

fn v3(v: DVec3) -> [f64; 3] {
    v.to_array()
}

#[test]
fn single_positional_light_gives_the_textbook_value() {
    let setup = LightingSetup {
        front: material(0.7, 0.0),
        back: material(0.2, 0.0),
        ambient_light: [0.5, 0.5, 0.5],
        lights: vec![Light {
            kind: LightKind::Positional {
                position: [0.0, 0.0, 2.0],
                attenuation: [1.0, 0.5, 0.25],
            },
            colour: [1.0, 1.0, 1.0],
        }],
        eye: Eye::Point([0.0, 0.0, 10.0]),
    };
    let s = Sample {
        point: [0.0, 0.0, 0.0],
        normal: [0.0, 0.0, 3.0], // not unit: normalised inside
    };
    let c = setup.shade(&s);
    // d = 2: attenuation 1 / (1 + 1 + 1); N.L = 1.
    let expected = 0.1 * 0.5 + 0.7 / 3.0;
    assert!((c[0] - expected).abs() < 1e-15, "{c:?}");
    // Seen from behind: back material and flipped normal (the light is then behind too).
    let mut behind = setup.clone();
    behind.eye = Eye::Point([0.0, 0.0, -10.0]);
    assert_eq!(behind.facing(&s), Facing::Back);
    assert!((behind.shade(&s)[0] - 0.05).abs() < 1e-15);
    // A zero normal gets ambient only, bad attenuation coefficients stay finite.
    assert_eq!(
        setup.shade(&Sample {
            point: [0.0; 3],
            normal: [0.0; 3]
        }),
        [0.05, 0.05, 0.05]
    );
    let mut bad = setup.clone();
    bad.lights[0].kind = LightKind::Positional {
        position: [0.0, 0.0, 2.0],
        attenuation: [0.0, 0.0, 0.0],
    };
    assert!(bad.shade(&s).iter().all(|c| c.is_finite()));
}

#[test]
fn specular_peaks_at_the_mirror_direction() {
    let setup = LightingSetup {
        front: material(0.0, 0.5),
        back: material(0.0, 0.5),
        ambient_light: [0.0; 3],
        lights: vec![Light {
            kind: LightKind::Directional {
                towards_light: [1.0, 0.0, 1.0],
            },
            colour: [1.0, 1.0, 1.0],
        }],
        eye: Eye::Direction([-1.0, 0.0, 1.0]),
    };
    let s = Sample {
        point: [0.0; 3],
        normal: [0.0, 0.0, 1.0],
    };
    let peak = setup.shade(&s)[1];
    assert!((peak - 0.5).abs() < 1e-12, "{peak}");
    let mut off = setup.clone();
    off.eye = Eye::Direction([-1.0, 0.0, 2.0]);
    assert!(off.shade(&s)[1] < 0.5);
}

/// The sphere of seed 001 figure 2 under a strong perspective.
struct Experiment {
    clip_from_world: DMat4,
    eye: DVec3,
    light: DVec3,
    samples: Vec<(DVec3, DVec3)>,
}

fn experiment() -> Experiment {
    let eye = DVec3::new(2.0, 1.0, 3.0);
    let clip_from_world = perspective_matrix(110f64.to_radians(), 1.0, 0.2, 20.0).unwrap()
        * look_at_matrix(eye, DVec3::ZERO, DVec3::new(0.1, 1.0, 0.0));
    let mut samples = vec![];
    for i in 0..60 {
        for j in 0..120 {
            let theta = (i as f64 + 0.5) / 60.0 * std::f64::consts::PI;
            let phi = j as f64 / 120.0 * std::f64::consts::TAU;
            let n = DVec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin());
            let p = n; // unit sphere at the origin
            if n.dot(eye - p) > 0.0 {
                samples.push((p, n));
            }
        }
    }
    Experiment {
        clip_from_world,
        eye,
        light: DVec3::new(2.5, 3.0, 1.5),
        samples,
    }
}

fn setup(eye: Eye<f64>, light: DVec3, directional: Option<DVec3>) -> LightingSetup<f64> {
    let mut lights = vec![Light {
        kind: LightKind::Positional {
            position: v3(light),
            attenuation: [1.0, 0.05, 0.01],
        },
        colour: [1.0, 0.9, 0.8],
    }];
    if let Some(d) = directional {
        lights.push(Light {
            kind: LightKind::Directional { towards_light: v3(d) },
            colour: [0.3, 0.3, 0.4],
        });
    }
    LightingSetup {
        front: material(0.6, 0.4),
        back: material(0.3, 0.0),
        ambient_light: [0.2, 0.2, 0.2],
        lights,
        eye,
    }
}

#[test]
fn lighting_in_lc_equals_wc_and_lighting_in_dc_does_not() {
    let ex = experiment();
    let directional = DVec3::new(-1.0, 0.5, 0.3);
    let e = factor_view(&ex.clip_from_world).unwrap().lighting_from_world();
    assert_ne!(e, DMat4::IDENTITY);
    let rotate = |v: DVec3| e.transform_vector3(v);
    let wc = setup(Eye::Point(v3(ex.eye)), ex.light, Some(directional));
    let lc = setup(
        Eye::Point(v3(e.transform_point3(ex.eye))),
        e.transform_point3(ex.light),
        Some(rotate(directional)),
    );
    // The same in f32, in LC.
    let to32 = |v: [f64; 3]| v.map(|c| c as f32);
    let lc32 = lc.to_f32();
    let (mut worst_lc, mut worst_lc32) = (0.0f64, 0.0f64);
    for &(p, n) in &ex.samples {
        let c_wc = wc.shade(&Sample {
            point: v3(p),
            normal: v3(n),
        });
        let s_lc = Sample {
            point: v3(e.transform_point3(p)),
            normal: v3(rotate(n)),
        };
        let c_lc = lc.shade(&s_lc);
        let c_lc32 = lc32.shade(&Sample {
            point: to32(s_lc.point),
            normal: to32(s_lc.normal),
        });
        for k in 0..3 {
            worst_lc = worst_lc.max((c_wc[k] - c_lc[k]).abs());
            worst_lc32 = worst_lc32.max((c_wc[k] - c_lc32[k] as f64).abs());
        }
    }
    assert!(worst_lc <= 1e-5, "LC vs WC differ by {worst_lc}");
    assert!(worst_lc32 <= 1e-5, "f32 LC vs f64 WC differ by {worst_lc32}");

    // "Lighting in DC": push points, normals (as tangent planes) and the light through V and
    // the divide, with the eye gone to infinity along +z; only the positional light, since a
    // directional one has no DC direction.
    let wc_positional = setup(Eye::Point(v3(ex.eye)), ex.light, None);
    let v = ex.clip_from_world;
    let v_inv_t = v.inverse().transpose();
    let to_dc = |p: DVec3| {
        let h = v.mul_vec4(p.extend(1.0));
        assert!(h.w > 0.0);
        h.truncate() / h.w
    };
    let dc = setup(Eye::Direction([0.0, 0.0, 1.0]), to_dc(ex.light), None);
    let mut worst_dc = 0.0f64;
    for &(p, n) in &ex.samples {
        let c_wc = wc_positional.shade(&Sample {
            point: v3(p),
            normal: v3(n),
        });
        let plane = v_inv_t.mul_vec4(DVec4::new(n.x, n.y, n.z, -n.dot(p)));
        let c_dc = dc.shade(&Sample {
            point: v3(to_dc(p)),
            normal: v3(plane.truncate()),
        });
        for k in 0..3 {
            worst_dc = worst_dc.max((c_wc[k] - c_dc[k]).abs());
        }
    }
    eprintln!(
        "figure 2 experiment over {} samples: LC-WC {worst_lc:.1e} (f32 {worst_lc32:.1e}), DC-WC {worst_dc:.3}",
        ex.samples.len()
    );
    assert!(worst_dc > 1e-2, "lighting in DC should visibly differ, got {worst_dc}");
}
