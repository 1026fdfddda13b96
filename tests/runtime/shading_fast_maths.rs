//! The fast shading kernels' own maths (src/runtime/shading/fast.rs): the polynomial and
//! integer powers stay within their stated error bounds (the integer one never subnormal),
//! and the filtered facing test agrees with the exact path wherever it decides a chunk and
//! declines near grazing. `shading_fast` checks whole kernels against the f64 pass.

use glam::{DMat4, DVec3};
use primflow::runtime::shading::fast::{
    integer_power_floor, pow_integer, pow_positive, RowInputs, MAX_INTEGER_SHININESS,
};
use primflow::runtime::shading::lanes::{F32s, F64s, Mask, Portable, LANES};
use primflow::runtime::shading::{SceneLight, Shader, ShadingSetup, ShadingSpaces};

#[test]
fn polynomial_power_is_within_its_stated_bound() {
    // Relative error <= 1e-5 over bases in (0, 1.001] and exponents in [1, 16384] (the f32
    // rounding of y = s log2 x, |y| <= 126, dominates), absolute 1e-30 where flushed.
    let mut worst = 0f64;
    for si in 0..=60 {
        let s = 2f64.powf(14.0 * si as f64 / 60.0);
        for xi in 1..=2000 {
            let x = (1.001 * xi as f64 / 2000.0).powf(4.0);
            let (xf, sf) = (x as f32, s as f32);
            let exact = f64::from(xf).powf(f64::from(sf));
            let got = f64::from(pow_positive(xf, sf));
            let err = (got - exact).abs();
            worst = worst.max(err / exact.max(1e-30));
            assert!(err <= 1e-5 * exact + 1e-30, "{xf}^{sf}: {got} vs {exact}");
        }
    }
    println!("worst relative error of pow_positive: {worst:.2e}");
    assert!(worst > 0.0);
}

#[test]
fn integer_power_is_within_its_stated_bound_and_never_subnormal() {
    // Relative error <= 1e-5 against f64 powf for every integer exponent the fast path
    // takes; where x^n would fall below the floor the result is about 2^-120 (absolute
    // error < 1e-36) and no step is subnormal.
    let mut worst = 0f64;
    for n in 1..=MAX_INTEGER_SHININESS {
        let floor = integer_power_floor(n);
        assert!(f64::from(floor).powi(n as i32) >= 2f64.powi(-121), "n = {n}");
        for xi in (1..=4000).step_by(8) {
            let x: [f32; LANES] = std::array::from_fn(|j| ((1.001 * (xi + j) as f64 / 4000.0).powf(3.0)) as f32);
            let got = pow_integer(F32s::<Portable>::new(x), n, floor).lanes();
            for j in 0..LANES {
                assert!(got[j].is_normal(), "{}^{n} = {}", x[j], got[j]);
                let exact = f64::from(x[j]).powi(n as i32);
                let err = (f64::from(got[j]) - exact).abs();
                assert!(err <= 1e-5 * exact + 1e-36, "{}^{n}: {} vs {exact}", x[j], got[j]);
                if exact > 1e-30 {
                    worst = worst.max(err / exact);
                }
            }
        }
    }
    println!("worst relative error of pow_integer: {worst:.2e}");
    assert!(worst > 0.0);
}

/// A shader over a 64 x 64 perspective view in LC, lit by one light, for the geometry
/// tests; `back` gives the back side its own material.
fn geometry_shader() -> Shader {
    // OpenGL's perspective: 90 degrees, near 0.5, far 50.
    let (near, far) = (0.5, 50.0);
    let clip_from_lighting = DMat4::from_cols_array(&[
        1.0,
        0.0,
        0.0,
        0.0,
        0.0,
        1.0,
        0.0,
        0.0,
        0.0,
        0.0,
        (far + near) / (near - far),
        -1.0,
        0.0,
        0.0,
        2.0 * far * near / (near - far),
        0.0,
    ]);
    let device_from_clip = DMat4::from_cols_array(&[
        32.0, 0.0, 0.0, 0.0, 0.0, 32.0, 0.0, 0.0, 0.0, 0.0, -0.5, 0.0, 32.0, 32.0, 0.5, 1.0,
    ]);
    let setup = ShadingSetup {
        lights: vec![SceneLight::Directional {
            towards_light: [0.3, 0.5, 1.0],
            colour: [1.0; 3],
        }],
        ..ShadingSetup::default()
    };
    let spaces = ShadingSpaces {
        device_from_lighting: device_from_clip * clip_from_lighting,
        lighting_from_world: DMat4::IDENTITY,
        device_from_clip,
    };
    Shader::new(&setup, &spaces).expect("an invertible view")
}

#[test]
fn filtered_facing_agrees_with_the_exact_path_and_declines_near_grazing() {
    // Random normals (and some within a hair of the view plane) at random depths: where
    // the filtered path decides a chunk, its facing masks equal the exact path's and its
    // f32 normal and eye vector are within 1e-6 of the exact ones; chunks with a pixel
    // closer to grazing than the margin go to the exact path.
    let shader = geometry_shader();
    let mut seed = 0x2545f4914f6cdd1du64;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let (mut decided, mut declined) = (0, 0);
    for case in 0..400 {
        let y = (case % 64) as u32;
        let depth: Vec<u32> = (0..LANES)
            .map(|_| (0.2 + 0.7 * next()) as f32)
            .map(|d| (f64::from(d) * 4294967296.0) as u32)
            .collect();
        let mut normal: [Vec<f32>; 3] = Default::default();
        for j in 0..LANES {
            let n = [next() * 2.0 - 1.0, next() * 2.0 - 1.0, next() * 2.0 - 1.0];
            for k in 0..3 {
                normal[k].push(n[k] as f32);
            }
            // Every fifth vector, pixel 3 is perpendicular to its eye vector (after
            // rounding the normal to f32 the cosine is a few 1e-8 at most, under the
            // margin: declined); every other one has pixels tilted just past the margin
            // (cosine +-2e-5 and +-3e-5: decided, and their facing must be right).
            let tilt = match (case % 5, j) {
                (0, 3) => Some(0.0f64),
                (1 | 3, 5) => Some(2.0e-5),
                (1 | 3, 9) => Some(-2.0e-5),
                (2 | 4, 6) => Some(3.0e-5),
                (2 | 4, 11) => Some(-3.0e-5),
                _ => None,
            };
            if let Some(cosine) = tilt {
                let x = (LANES * (case % 2)) as f64 + j as f64 + 0.5;
                let p = shader.position(x as u32, y, f64::from(depth[j]) / 4294967296.0);
                let v = (-p).normalize();
                let across = DVec3::new(v.y, -v.x, 0.0).normalize();
                let n = across * (1.0 - cosine * cosine).sqrt() + v * cosine;
                for k in 0..3 {
                    normal[k][j] = n[k] as f32;
                }
            }
        }
        let x0 = LANES * (case % 2);
        let mut depth_row = vec![0u32; 64];
        depth_row[x0..x0 + LANES].copy_from_slice(&depth);
        let mut planes: [Vec<f32>; 3] = Default::default();
        for k in 0..3 {
            planes[k] = vec![0.0; 64];
            planes[k][x0..x0 + LANES].copy_from_slice(&normal[k]);
        }
        let row = RowInputs {
            y,
            depth: &depth_row,
            cs: None,
            normal: Some([&planes[0], &planes[1], &planes[2]]),
            facing: None,
            st: None,
        };
        let p: [F64s<Portable>; 3] = std::array::from_fn(|k| {
            F64s::new(std::array::from_fn(|j| {
                shader.position((x0 + j) as u32, y, f64::from(depth[j]) / 4294967296.0)[k]
            }))
        });
        let exact = shader.chunk_geometry_exact(&row, x0, &p);
        match shader.chunk_geometry_filtered(&row, x0, &p, Mask::all()) {
            Some(fast) => {
                decided += 1;
                assert_eq!(fast.back.lanes(), exact.back.lanes(), "case {case}");
                for k in 0..3 {
                    let (n, exact_n) = (fast.n[k].lanes(), exact.n[k].lanes());
                    let (v, exact_v) = (fast.v[k].lanes(), exact.v[k].lanes());
                    for j in 0..LANES {
                        assert!((n[j] - exact_n[j]).abs() <= 1e-6, "case {case}");
                        assert!((v[j] - exact_v[j]).abs() <= 1e-6, "case {case}");
                    }
                }
            }
            None => declined += 1,
        }
    }
    println!("filtered path decided {decided} chunks, declined {declined}");
    // All 320 tilted ones decided, all 80 perpendicular ones declined.
    assert_eq!((decided, declined), (320, 80));
}
