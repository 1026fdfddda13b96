//! `inout` helper parameters (docs/language.md section 2): copied in and written back, except
//! that a whole variable no other argument names *is* the parameter in the inlined body
//! (src/check/lower.rs `inout_alias`). Either way a call must give what copy-in, copy-out
//! gives. Pinned against an exact reference, at both tiers with unrolling on and off:
//! writes read back through the parameter, a nested call passing the parameter on, an early
//! `return` under a uniform `if` (before and after the writes it skips), a varying variable
//! in the pixel code, and the two cases that keep their copies: the variable also passed by
//! value (the copy holds its value from before the call) and passed for two inout
//! parameters (the last write-back wins).

use crate::support;

use primflow::diag::SourceMap;
use primflow::runtime::{Renderer, Value};

const PRIM: &str = r#"
// Adds `by` to each element; then, unless a[0] went past 100, a[2] = a[0] + a[1].
void bump_all(inout float a[3]; float by)
{
    for (int i = 0; i < 3; i++)
        a[i] += by;
    if (a[0] > 100)
        return;
    a[2] = a[0] + a[1];
}

void bump_twice(inout float a[3])
{
    bump_all(a, 1);
    bump_all(a, 2);
}

void copy_then_write(inout float a[3]; float b[3])
{
    a[0] = 5;
    a[1] = b[0];
}

// With copies, f(x, x) leaves x = b = 2; as one variable it would end at 20.
void write_both(inout float a; inout float b)
{
    a = 1;
    b = a + 1;
    a = b * 10;
}

primitive inouts(float d[3]; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(0, 0, 40, 4);
    float s[3] = d;
    bump_twice(s);
    float c[3] = d;
    copy_then_write(c, c);
    float e = 0;
    write_both(e, e);
    float px[3] = {X, 0, 0};
    bump_all(px, 1);
    Z = (s[0] + s[1] + s[2] + c[0] + c[1] + c[2] + e + px[2]) / 512;
}
"#;

/// `bump_all` on f64s.
fn bump_all(a: &mut [f64; 3], by: f64) {
    for v in a.iter_mut() {
        *v += by;
    }
    if a[0] <= 100.0 {
        a[2] = a[0] + a[1];
    }
}

/// The depth copy-in, copy-out semantics give at pixel column `x` (every value is a multiple
/// of 1/2 below 512, so the f32 sums and the fixed<32,32> depth are exact).
fn reference_depth(d: [f32; 3], x: u32) -> u32 {
    let d = d.map(f64::from);
    let mut s = d;
    bump_all(&mut s, 1.0);
    bump_all(&mut s, 2.0);
    let c = [5.0, d[0], d[2]];
    let e = 2.0;
    let mut px = [f64::from(x) + 0.5, 0.0, 0.0];
    bump_all(&mut px, 1.0);
    let z = (s.iter().sum::<f64>() + c.iter().sum::<f64>() + e + px[2]) / 512.0;
    (z * 4294967296.0) as u32
}

#[test]
fn inout_parameters_give_what_copies_give() {
    let mut sources = SourceMap::new();
    let program = support::library_with(&mut sources, &[("inouts.prim", PRIM)]);
    // Small values, and d[0] past 100 after the first bump (both early returns taken).
    for d in [[1.0, 2.0, 3.0], [-4.5, 0.5, 7.0], [99.5, 0.5, 1.0]] {
        let mut r = Renderer::new(program.clone());
        r.set_image_size(40, 4).unwrap();
        r.begin("inouts").unwrap();
        r.rast_param("d", &Value(d.to_vec())).unwrap();
        r.end().unwrap();
        support::assert_depth_in_every_jit(&r, &format!("d={d:?}"), |x, _| reference_depth(d, x));
    }
}
