//! The fast shading kernel's builds (AVX-512 or AVX2 as `Simd`, AVX2 forced, portable loops)
//! give the same bits on G-buffer rows no scene produces: random lights (directional and
//! positional, attenuation zero or negative), materials (integer and fractional shininess,
//! a back side of its own), fog, texture, lighting space, and per pixel random depth
//! (unwritten, nearest, any), normals (zero, tiny, huge, NaN, infinite), colours (NaN,
//! negative) and texture coordinates, in rows whose width is no multiple of the vector (two
//! in three rows of a plane hold ordinary values only, so that the fast path runs: one
//! non-finite normal sends its whole vector to the exact one). Every colour is finite, and an unwritten pixel is black. (The scene tests,
//! tests/runtime/shading_fast.rs and tests/runtime/shading_rows.rs, hold the builds to the f64 reference.)

use glam::{DMat4, DVec3};
use primflow::pipeline::transform::{device_from_clip, orthographic_matrix, perspective_matrix, Viewport};
use primflow::runtime::shading::{
    Fog, LightingSpaceChoice, RowInputs, SceneLight, Shader, ShadingKernel, ShadingSetup, ShadingSpaces,
    SurfaceMaterial, Texture,
};
use proptest::prelude::*;

/// Floats a G-buffer may hold: ordinary values and the ones kernels trip on.
fn any_float() -> impl Strategy<Value = f32> {
    prop_oneof![
        6 => -2.0f32..2.0,
        1 => Just(0.0f32),
        1 => Just(-0.0f32),
        1 => Just(f32::NAN),
        1 => Just(f32::INFINITY),
        1 => Just(f32::NEG_INFINITY),
        1 => Just(1e-30f32),
        1 => Just(3e38f32),
        1 => Just(1e-40f32),
    ]
}

/// A plane's row: mostly ordinary values, so that whole vectors take the fast path (one
/// non-finite normal sends its vector to the exact one), or values from [`any_float`].
fn plane() -> impl Strategy<Value = Vec<f32>> {
    prop_oneof![
        2 => prop::collection::vec(-2.0f32..2.0, WIDTH),
        1 => prop::collection::vec(any_float(), WIDTH),
    ]
}

fn depth() -> impl Strategy<Value = u32> {
    prop_oneof![
        2 => Just(0u32),
        1 => Just(u32::MAX),
        1 => Just(1u32),
        6 => any::<u32>(),
    ]
}

fn light() -> impl Strategy<Value = SceneLight> {
    let v3 = || prop::array::uniform3(-3.0f64..3.0);
    let colour = prop::array::uniform3(0.0f64..1.5);
    prop_oneof![
        (v3(), colour.clone()).prop_map(|(towards_light, colour)| SceneLight::Directional { towards_light, colour }),
        (v3(), colour, prop::array::uniform3(-1.0f64..1.0)).prop_map(|(position, colour, attenuation)| {
            SceneLight::Positional {
                position,
                colour,
                attenuation,
            }
        }),
    ]
}

fn material() -> impl Strategy<Value = SurfaceMaterial> {
    let shininess = prop_oneof![(1u32..=128).prop_map(f64::from), 1.0f64..300.0];
    (
        0.0f64..1.0,
        0.0f64..1.0,
        0.0f64..1.0,
        shininess,
        prop::array::uniform3(0.0f64..1.0),
    )
        .prop_map(|(ka, kd, ks, shininess, specular_colour)| SurfaceMaterial {
            ka,
            kd,
            ks,
            shininess,
            specular_colour,
        })
}

fn setup() -> impl Strategy<Value = ShadingSetup> {
    (
        prop::collection::vec(light(), 0..4),
        material(),
        prop::option::of(material()),
        any::<bool>(),
        any::<bool>(),
        0..3usize,
    )
        .prop_map(|(lights, front, back, fog, texture, space)| ShadingSetup {
            lights,
            front,
            back,
            fog: fog.then_some(Fog {
                colour: [0.6, 0.7, 0.9],
                start: 2.0,
                end: 9.0,
            }),
            texture: texture.then(|| Texture {
                param: "st".into(),
                scale: 3.0,
                dark: 0.4,
            }),
            space: [
                LightingSpaceChoice::Lighting,
                LightingSpaceChoice::World,
                LightingSpaceChoice::Device,
            ][space],
            ..ShadingSetup::default()
        })
}

/// A 70 x 4 view: perspective or parallel (the pipeline's own projections and viewport),
/// lighting coordinates turned and scaled from world.
fn spaces(perspective: bool, turn: f64) -> ShadingSpaces {
    let (w, h) = (70.0, 4.0);
    let clip_from_lighting = if perspective {
        perspective_matrix(1.2, w / h, 0.5, 50.0)
    } else {
        orthographic_matrix([-4.0, 4.0, -1.0, 1.0], 0.5, 50.0)
    }
    .expect("valid projection");
    let device_from_clip = device_from_clip(Viewport {
        x0: 0.0,
        y0: 0.0,
        width: w,
        height: h,
    });
    ShadingSpaces {
        device_from_lighting: device_from_clip * clip_from_lighting,
        lighting_from_world: DMat4::from_scale_rotation_translation(
            DVec3::new(1.0, 2.0, 0.5),
            glam::DQuat::from_rotation_y(turn),
            DVec3::new(0.3, -0.2, -4.0),
        ),
        device_from_clip,
    }
}

const WIDTH: usize = 70;

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    #[test]
    fn every_build_shades_random_rows_to_the_same_bits(
        setup in setup(),
        perspective in any::<bool>(),
        turn in -3.0f64..3.0,
        depth in prop::collection::vec(depth(), WIDTH),
        planes in prop::collection::vec(plane(), 7),
        facing in prop::option::of(plane()),
        gray in any::<bool>(),
        y in 0u32..4,
    ) {
        let spaces = spaces(perspective, turn);
        let shade = |kernel: ShadingKernel| -> Option<Vec<[f32; 3]>> {
            let shader = Shader::new(&ShadingSetup { kernel, ..setup.clone() }, &spaces)?;
            let lit = shader.effects().lit;
            let row = RowInputs {
                y,
                depth: &depth,
                cs: Some(if gray { [&planes[0][..]; 3] } else { [&planes[0][..], &planes[1], &planes[2]] }),
                normal: lit.then(|| [&planes[3][..], &planes[4], &planes[5]]),
                facing: facing.as_deref().filter(|_| lit),
                st: shader.effects().texture.then(|| [&planes[6][..], &planes[1]]),
            };
            // Stale colours in the buffer: the kernel must overwrite every pixel.
            let mut out = vec![[f32::NAN; 3]; WIDTH];
            shader.shade_row(&row, &mut out);
            Some(out)
        };
        let simd = shade(ShadingKernel::Simd);
        prop_assume!(simd.is_some());
        let simd = simd.unwrap();
        let bits = |c: &[[f32; 3]]| -> Vec<u32> { c.iter().flatten().map(|v| v.to_bits()).collect() };
        prop_assert_eq!(bits(&shade(ShadingKernel::Avx2).unwrap()), bits(&simd), "AVX2 vs Simd");
        prop_assert_eq!(bits(&shade(ShadingKernel::Portable).unwrap()), bits(&simd), "portable vs Simd");
        for (x, c) in simd.iter().enumerate() {
            prop_assert!(c.iter().all(|v| v.is_finite()), "non-finite colour {:?} at {}", c, x);
            if depth[x] == 0 {
                prop_assert_eq!(*c, [0.0; 3], "unwritten pixel {} not black", x);
            }
        }
    }
}
