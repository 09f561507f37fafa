//! The finite-difference driver on a function with known derivatives: forward differences are
//! off by their first-order truncation `f''δ/2`, central ones by `f'''δ²/6`; and the split form
//! (the designs first, evaluated in any order or in parallel, then the derivatives from their
//! values) gives exactly the driver's result.

use mbs::{
    FdScheme, Perturbation, finite_difference_designs, finite_differences, finite_differences_from,
};

/// `f(b) = [b₀³, b₀ b₁, sin b₁]`.
fn f(b: &[f64]) -> Result<Vec<f64>, String> {
    Ok(vec![b[0].powi(3), b[0] * b[1], b[1].sin()])
}

/// `∂f_i/∂b_j` at `b`.
fn exact(b: &[f64]) -> [[f64; 2]; 3] {
    [[3.0 * b[0] * b[0], 0.0], [b[1], b[0]], [0.0, b[1].cos()]]
}

#[test]
fn differences_converge_at_their_order_and_the_split_form_is_the_same() {
    let b = [1.3, 0.7];
    let sizes = [Perturbation::Absolute(1e-2), Perturbation::Absolute(1e-3)];
    for scheme in [FdScheme::Forward, FdScheme::Central] {
        let whole = finite_differences(&b, scheme, &sizes, f).unwrap();
        // the split form, its designs evaluated in reverse order and put back in place
        let designs = finite_difference_designs(&b, scheme, &sizes);
        let per_design = match scheme {
            FdScheme::Forward => 1 + 2 * sizes.len(),
            FdScheme::Central => 2 * 2 * sizes.len(),
        };
        assert_eq!(designs.len(), per_design);
        let mut values: Vec<Vec<f64>> = designs.iter().rev().map(|d| f(d).unwrap()).collect();
        values.reverse();
        let split = finite_differences_from(&b, scheme, &sizes, &values);
        assert_eq!(whole, split, "{scheme:?}");
        // the error against the exact derivative falls with δ (forward) or δ² (central)
        let error = |k: usize| {
            let d = &whole[k].derivative;
            let e = exact(&b);
            (0..3)
                .flat_map(|i| (0..2).map(move |j| (i, j)))
                .map(|(i, j)| (d[(i, j)] - e[i][j]).abs())
                .fold(0.0, f64::max)
        };
        let (coarse, fine) = (error(0), error(1));
        let expected_ratio = match scheme {
            FdScheme::Forward => 10.0,
            FdScheme::Central => 100.0,
        };
        let ratio = coarse / fine;
        assert!(
            (ratio / expected_ratio - 1.0).abs() < 0.05,
            "{scheme:?}: errors {coarse:e} → {fine:e}, ratio {ratio}"
        );
        // the leading truncation term of b₀³ in b₀: forward 3 b₀ δ, central δ²
        let lead = match scheme {
            FdScheme::Forward => 3.0 * b[0] * 1e-2,
            FdScheme::Central => 1e-4,
        };
        assert!(
            (coarse / lead - 1.0).abs() < 0.02,
            "{scheme:?}: {coarse:e} vs {lead:e}"
        );
    }
}

#[test]
fn the_first_failing_design_is_reported() {
    let g = |b: &[f64]| -> Result<Vec<f64>, String> {
        if b[0] > 1.0 {
            Err(format!("failed at {}", b[0]))
        } else {
            Ok(vec![b[0]])
        }
    };
    let err = finite_differences(&[1.0], FdScheme::Central, &[Perturbation::Absolute(0.1)], g)
        .unwrap_err();
    assert_eq!(err, "failed at 1.1");
}
