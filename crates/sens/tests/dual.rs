//! Elementary-function derivatives of `Dual` against closed forms and central differences.

use sens::{Dual, Scalar};

type D1 = Dual<1>;

/// Central difference with a step scaled to the point.
fn central(f: impl Fn(f64) -> f64, x: f64) -> f64 {
    let h = 1e-6 * x.abs().max(1.0);
    (f(x + h) - f(x - h)) / (2.0 * h)
}

fn check(
    name: &str,
    fd: impl Fn(D1) -> D1,
    ff: impl Fn(f64) -> f64,
    exact: impl Fn(f64) -> f64,
    xs: &[f64],
) {
    for &x in xs {
        let y = fd(D1::variable(x, 0));
        assert_eq!(y.v, ff(x), "{name}: value at {x}");
        let e = exact(x);
        let rel = (y.d[0] - e).abs() / e.abs().max(1e-300);
        assert!(
            rel < 1e-14 || (y.d[0] - e).abs() < 1e-15,
            "{name}({x}): dual {} vs closed form {e}",
            y.d[0]
        );
        let c = central(&ff, x);
        let rel = (y.d[0] - c).abs() / c.abs().max(1.0);
        assert!(
            rel < 1e-7,
            "{name}({x}): dual {} vs central difference {c}",
            y.d[0]
        );
    }
}

#[test]
fn elementary_functions_match_closed_form_and_central_differences() {
    let pos = [0.3, 1.0, 2.7, 11.0];
    let any = [-2.1, -0.4, 0.3, 1.7];
    let unit = [-0.8, -0.2, 0.1, 0.7];
    check("sqrt", |x| x.sqrt(), f64::sqrt, |x| 0.5 / x.sqrt(), &pos);
    check("sin", |x| x.sin(), f64::sin, f64::cos, &any);
    check("cos", |x| x.cos(), f64::cos, |x| -x.sin(), &any);
    check(
        "tan",
        |x| x.tan(),
        f64::tan,
        |x| 1.0 / x.cos().powi(2),
        &unit,
    );
    check(
        "asin",
        |x| x.asin(),
        f64::asin,
        |x| 1.0 / (1.0 - x * x).sqrt(),
        &unit,
    );
    check(
        "acos",
        |x| x.acos(),
        f64::acos,
        |x| -1.0 / (1.0 - x * x).sqrt(),
        &unit,
    );
    check(
        "atan",
        |x| x.atan(),
        f64::atan,
        |x| 1.0 / (1.0 + x * x),
        &any,
    );
    check("exp", |x| x.exp(), f64::exp, f64::exp, &any);
    check("ln", |x| x.ln(), f64::ln, |x| 1.0 / x, &pos);
    check(
        "powi(3)",
        |x| x.powi(3),
        |x| x.powi(3),
        |x| 3.0 * x * x,
        &any,
    );
    check(
        "powi(-2)",
        |x| x.powi(-2),
        |x| x.powi(-2),
        |x| -2.0 / x.powi(3),
        &any,
    );
    check(
        "powf(const 2.5)",
        |x| x.powf(D1::constant(2.5)),
        |x| x.powf(2.5),
        |x| 2.5 * x.powf(1.5),
        &pos,
    );
    check(
        "x^x",
        |x| x.powf(x),
        |x| x.powf(x),
        |x| x.powf(x) * (x.ln() + 1.0),
        &pos,
    );
    check("abs", |x| x.abs(), f64::abs, f64::signum, &any);
    check(
        "atan2(x, 0.7)",
        |x| x.atan2(D1::constant(0.7)),
        |x| x.atan2(0.7),
        |x| 0.7 / (0.49 + x * x),
        &any,
    );
    check(
        "atan2(-1.3, x)",
        |x| D1::constant(-1.3).atan2(x),
        |x| (-1.3f64).atan2(x),
        |x| 1.3 / (1.69 + x * x),
        &any,
    );
    check(
        "hypot(x, 2)",
        |x| x.hypot(D1::constant(2.0)),
        |x| x.hypot(2.0),
        |x| x / x.hypot(2.0),
        &any,
    );
    check("1/x", |x| 1.0 / x, |x| 1.0 / x, |x| -1.0 / (x * x), &any);
    check(
        "quotient",
        |x| (x * x + 1.0) / (x - 3.0),
        |x| (x * x + 1.0) / (x - 3.0),
        |x| (2.0 * x * (x - 3.0) - (x * x + 1.0)) / (x - 3.0).powi(2),
        &any,
    );
    check(
        "3 - x·sin x",
        |x| 3.0 - x * x.sin(),
        |x| 3.0 - x * x.sin(),
        |x| -x.sin() - x * x.cos(),
        &any,
    );
}

#[test]
fn sqrt_at_zero_of_a_constant_has_no_nan() {
    let x = Dual::<2>::new(0.0, [0.0, 0.0]);
    assert!(x.sqrt().is_finite());
    let y = Dual::<2>::new(0.0, [1.0, 0.0]);
    assert!(
        !y.sqrt().is_finite(),
        "an infinite slope must show, not be hidden"
    );
}

#[test]
fn comparisons_look_at_the_value_only() {
    let a = Dual::<2>::new(1.0, [5.0, 0.0]);
    let b = Dual::<2>::new(1.0, [0.0, -3.0]);
    assert!(a == b);
    assert!(a < Dual::constant(1.5));
    assert_eq!(a.max(Dual::constant(0.5)).d, [5.0, 0.0]);
}

#[test]
fn duals_work_in_nalgebra_products() {
    use nalgebra::{Matrix3, Vector3};
    let t = Dual::<1>::variable(0.4, 0);
    let (s, c) = t.sin_cos();
    let z = Dual::constant(0.0);
    let o = Dual::constant(1.0);
    let r = Matrix3::new(c, -s, z, s, c, z, z, z, o);
    let v = Vector3::new(o, Dual::constant(2.0), Dual::constant(-1.0));
    let w = r.transpose() * (r * v);
    for i in 0..3 {
        assert!((w[i].v - v[i].v).abs() < 1e-15);
        assert!(
            w[i].d[0].abs() < 1e-15,
            "RᵀR = I does not depend on the angle"
        );
    }
    // d(R v)/dθ = R' v
    let rv = r * v;
    let expect = [
        -0.4f64.sin() - 2.0 * 0.4f64.cos(),
        0.4f64.cos() - 2.0 * 0.4f64.sin(),
    ];
    assert!((rv[0].d[0] - expect[0]).abs() < 1e-15);
    assert!((rv[1].d[0] - expect[1]).abs() < 1e-15);
}

#[test]
fn f64_implements_scalar_consistently() {
    fn generic<S: Scalar>(x: S) -> S {
        (x.sin() * x.exp() + x.powi(2)).sqrt() / (S::one() + x.abs())
    }
    let x = 0.73;
    let y = generic(x);
    let d = generic(Dual::<1>::variable(x, 0));
    assert_eq!(y, d.v);
    assert_eq!(<f64 as Scalar>::TANGENTS, 0);
    assert!(x.tangents().is_empty());
    let c = central(generic::<f64>, x);
    assert!((d.d[0] - c).abs() < 1e-8);
}

#[test]
fn from_parts_builds_values_with_given_tangents() {
    let x = <Dual<3> as Scalar>::from_parts(2.0, &[1.0, -4.0]);
    assert_eq!((x.v, x.d), (2.0, [1.0, -4.0, 0.0]));
    let y = <Dual<1> as Scalar>::from_parts(2.0, &[1.0, -4.0]);
    assert_eq!(y.d, [1.0], "extra tangents are ignored");
    assert_eq!(<f64 as Scalar>::from_parts(2.0, &[1.0]), 2.0);
    // chain rule: g(f(b)) with f's Jacobian precomputed equals the direct evaluation
    let b = Dual::<2>::variable(0.25, 0);
    let direct = (b * 3.0).sin();
    let f = Dual::<2>::from_parts(0.75, &[3.0, 0.0]);
    assert_eq!(direct.d, f.sin().d);
}
