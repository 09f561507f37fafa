//! Algebraic identities of dual arithmetic on random operands.

use proptest::prelude::*;
use sens::{Dual, Scalar};

fn dual() -> impl Strategy<Value = Dual<3>> {
    (-10.0f64..10.0, prop::array::uniform3(-5.0f64..5.0)).prop_map(|(v, d)| Dual::new(v, d))
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * (1.0 + a.abs().max(b.abs()))
}

proptest! {
    #[test]
    fn product_and_quotient_rules(x in dual(), y in dual()) {
        prop_assume!(y.v.abs() > 0.1);
        let p = x * y;
        let q = x / y;
        for k in 0..3 {
            prop_assert!(close(p.d[k], x.d[k] * y.v + x.v * y.d[k]));
            prop_assert!(close(q.d[k], (x.d[k] * y.v - x.v * y.d[k]) / (y.v * y.v)));
        }
        prop_assert_eq!(p.v, x.v * y.v);
        prop_assert_eq!(q.v, x.v / y.v);
    }

    #[test]
    fn pythagoras_has_no_tangent(x in dual()) {
        let one = x.sin().powi(2) + x.cos().powi(2);
        prop_assert!(close(one.v, 1.0));
        for k in 0..3 {
            prop_assert!(one.d[k].abs() < 1e-12);
        }
    }

    #[test]
    fn exp_ln_round_trip(x in dual()) {
        let y = x.exp().ln();
        for k in 0..3 {
            prop_assert!(close(y.d[k], x.d[k]));
        }
    }

    #[test]
    fn mixed_f64_arithmetic_agrees_with_constants(x in dual(), c in -4.0f64..4.0) {
        prop_assume!(c.abs() > 1e-3);
        let k = Dual::<3>::constant(c);
        for (a, b) in [(x + c, x + k), (x - c, x - k), (x * c, x * k), (x / c, x / k),
                       (c - x, k - x), (c * x, k * x)] {
            prop_assert!(close(a.v, b.v));
            for i in 0..3 {
                prop_assert!(close(a.d[i], b.d[i]));
            }
        }
    }
}
