//! One value repeated over an array (`ir::ExprKind::Splat`): the zero of a declaration
//! without initialiser, a scalar assigned to an array, `color(s)`, and a scalar argument of
//! a component-wise built-in beside arrays. Pinned against an f64 reference (every value a
//! multiple of 1/8, so f32 and the fixed<32,32> depth are exact) at both tiers, with loop
//! unrolling on and off; uniform splats in the setup code, varying ones (`X`) and zero
//! arrays that later turn varying in the pixel code, 1-D and 2-D, float, int and fixed.

use crate::support;

use primflow::diag::SourceMap;
use primflow::runtime::{Renderer, Value};

const PRIM: &str = r#"
primitive splats(float k; int at; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(0, 0, 16, 2);
    float a[5] = k;
    a[2] = 1;
    float m[2][3] = 0.5;
    m[1][2] = k * 2;
    int n[3] = 2;
    fixed<16,8> g[3];
    float big[200];
    big[at] = k;
    color u = color(k);
    float setup_sum = a[0] + a[1] + a[2] + a[3] + a[4] + m[0][0] + m[0][1] + m[0][2] + m[1][0]
                      + m[1][1] + m[1][2] + n[0] + n[1] + n[2] + float(g[1]) + big[at - 1] + big[at]
                      + u[0] + u[1] + u[2];
    float v[3] = X;
    v[1] = v[1] + 1;
    float c[3] = clamp(v, 0, 8);
    float w[3] = mix(v, c, 0.25);
    float p[4];
    p[1] = X;
    Z = (setup_sum + w[0] + w[1] + w[2] + p[0] + p[1] + p[2] + p[3] + 64) / 1024;
}
"#;

/// What the language says `splats` writes at pixel column `x`, as fixed<32,32> raw bits.
fn reference_depth(k: f64, x: u32) -> u32 {
    let setup_sum = (4.0 * k + 1.0) + (2.5 + 2.0 * k) + 6.0 + 0.0 + (0.0 + k) + 3.0 * k;
    let px = f64::from(x) + 0.5;
    let v = [px, px + 1.0, px];
    let w: f64 = v.iter().map(|&vi| vi + (vi.clamp(0.0, 8.0) - vi) * 0.25).sum();
    let z = (setup_sum + w + px + 64.0) / 1024.0;
    (z * 4294967296.0) as u32
}

#[test]
fn splats_give_every_element_the_value() {
    let mut sources = SourceMap::new();
    let program = support::library_with(&mut sources, &[("splats.prim", PRIM)]);
    for (k, at) in [(0.5, 7), (3.25, 199), (-1.75, 1)] {
        let mut r = Renderer::new(program.clone());
        r.set_image_size(16, 2).unwrap();
        r.begin("splats").unwrap();
        r.rast_param("k", &Value(vec![k])).unwrap();
        r.rast_param("at", &Value(vec![at as f32])).unwrap();
        r.end().unwrap();
        support::assert_depth_in_every_jit(&r, &format!("k={k} at={at}"), |x, _| reference_depth(f64::from(k), x));
    }
}
