//! Ply strengths and failure criteria (docs/failure-criteria.md).
//!
//! Every criterion is stated on the stress (and, for the maximum strain, the strain) of a ply
//! in its material axes, Voigt order `[11, 22, 33, 23, 13, 12]`, and reported as a **failure
//! index** `FI = 1/R`, where `R` is the reserve factor: the factor on the stress state at which
//! the criterion is first met. So every index fails at 1 and is proportional to the load, and
//! a safety factor `n` reads `FI ≤ 1/n` whatever the criterion. For the quadratic criteria this
//! is not the polynomial's value: Tsai–Hill's index is the square root of its polynomial,
//! Tsai–Wu's and Hashin's matrix compression (which have linear terms) solve
//! `a R² + b R = 1`.
//!
//! Generic over [`Scalar`]: on dual numbers the index carries the derivatives of the stress
//! (the active branch's, where a criterion takes a maximum or depends on signs).

use sens::Scalar;

use crate::{LaminateError, OrthotropicMaterial};

/// The strengths of a ply in its material axes (Pa; compressive strengths as positive
/// magnitudes): fibre direction `X`, in-plane transverse `Y`, through-thickness `Z`, shear
/// `S12`, `S13`, `S23`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlyStrength {
    pub xt: f64,
    pub xc: f64,
    pub yt: f64,
    pub yc: f64,
    pub zt: f64,
    pub zc: f64,
    pub s12: f64,
    pub s13: f64,
    pub s23: f64,
}

impl PlyStrength {
    /// The strengths of a transversely isotropic ply from its five in-plane ones: the
    /// through-thickness ones as the in-plane transverse (`Z = Y`), `S13 = S12`, and
    /// `S23 = S12` until [`PlyStrength::with_transverse`] states them.
    pub fn new(xt: f64, xc: f64, yt: f64, yc: f64, s12: f64) -> Result<Self, LaminateError> {
        let s = Self {
            xt,
            xc,
            yt,
            yc,
            zt: yt,
            zc: yc,
            s12,
            s13: s12,
            s23: s12,
        };
        s.validated()
    }

    /// The through-thickness strengths given.
    pub fn with_transverse(
        self,
        zt: f64,
        zc: f64,
        s13: f64,
        s23: f64,
    ) -> Result<Self, LaminateError> {
        Self {
            zt,
            zc,
            s13,
            s23,
            ..self
        }
        .validated()
    }

    fn validated(self) -> Result<Self, LaminateError> {
        for (constant, value) in [
            ("Xt", self.xt),
            ("Xc", self.xc),
            ("Yt", self.yt),
            ("Yc", self.yc),
            ("Zt", self.zt),
            ("Zc", self.zc),
            ("S12", self.s12),
            ("S13", self.s13),
            ("S23", self.s23),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(LaminateError::NotPositive { constant, value });
            }
        }
        Ok(self)
    }
}

/// A failure criterion.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Criterion {
    /// Each stress component against its strength (by sign), the largest ratio.
    MaxStress,
    /// Each strain component against its allowable, the strength over the modulus
    /// (`Xt/E1`, `Xc/E1`, `Yt/E2`, …, `S12/G12`), the largest ratio.
    MaxStrain,
    /// Tsai–Wu with the interaction terms `F_ij = −½ √(F_ii F_jj)` (Tsai–Hahn).
    TsaiWu,
    /// Tsai–Hill (Hill's anisotropic von Mises, transversely isotropic, with the strengths
    /// of the stresses' signs).
    TsaiHill,
    /// Hashin (1980), the larger of the fibre and matrix modes.
    Hashin,
    /// Hashin's fibre mode (tension or compression by the sign of `σ11`).
    HashinFibre,
    /// Hashin's matrix mode (tension or compression by the sign of `σ22 + σ33`).
    HashinMatrix,
}

/// The Tsai–Wu interaction coefficient `F*_ij` of `F_ij = F*_ij √(F_ii F_jj)`.
pub const TSAI_WU_INTERACTION: f64 = -0.5;

impl Criterion {
    /// Every criterion, in the order of [`Criterion::name`]'s documentation.
    pub const ALL: [Criterion; 7] = [
        Criterion::MaxStress,
        Criterion::MaxStrain,
        Criterion::TsaiWu,
        Criterion::TsaiHill,
        Criterion::Hashin,
        Criterion::HashinFibre,
        Criterion::HashinMatrix,
    ];

    /// The criterion's name in decks and outputs.
    pub fn name(self) -> &'static str {
        match self {
            Criterion::MaxStress => "max-stress",
            Criterion::MaxStrain => "max-strain",
            Criterion::TsaiWu => "tsai-wu",
            Criterion::TsaiHill => "tsai-hill",
            Criterion::Hashin => "hashin",
            Criterion::HashinFibre => "hashin-fibre",
            Criterion::HashinMatrix => "hashin-matrix",
        }
    }

    /// The criterion named `name` ([`Criterion::name`]).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.name() == name)
    }

    /// The failure index `1/R` of the ply stress `stress` (material axes, Pa) of a ply of
    /// `material` with strengths `strength`.
    pub fn index<S: Scalar>(
        self,
        material: &OrthotropicMaterial,
        strength: &PlyStrength,
        stress: &[S; 6],
    ) -> S {
        match self {
            Criterion::MaxStress => max_stress(strength, stress),
            Criterion::MaxStrain => max_strain(material, strength, stress),
            Criterion::TsaiWu => tsai_wu(strength, stress),
            Criterion::TsaiHill => tsai_hill(strength, stress),
            Criterion::Hashin => {
                hashin_fibre(strength, stress).max(hashin_matrix(strength, stress))
            }
            Criterion::HashinFibre => hashin_fibre(strength, stress),
            Criterion::HashinMatrix => hashin_matrix(strength, stress),
        }
    }
}

/// `x / t` for `x ≥ 0`, `−x / c` otherwise.
fn ratio<S: Scalar>(x: S, t: f64, c: f64) -> S {
    if x.value() >= 0.0 {
        x * (1.0 / t)
    } else {
        -x * (1.0 / c)
    }
}

fn largest<S: Scalar>(values: impl IntoIterator<Item = S>) -> S {
    values.into_iter().fold(S::zero(), |m, x| m.max(x))
}

fn max_stress<S: Scalar>(f: &PlyStrength, s: &[S; 6]) -> S {
    largest([
        ratio(s[0], f.xt, f.xc),
        ratio(s[1], f.yt, f.yc),
        ratio(s[2], f.zt, f.zc),
        s[3].abs() * (1.0 / f.s23),
        s[4].abs() * (1.0 / f.s13),
        s[5].abs() * (1.0 / f.s12),
    ])
}

fn max_strain<S: Scalar>(m: &OrthotropicMaterial, f: &PlyStrength, s: &[S; 6]) -> S {
    let compliance = m.compliance();
    let e: Vec<S> = (0..6)
        .map(|i| (0..6).fold(S::zero(), |acc, j| acc + s[j] * compliance[(i, j)]))
        .collect();
    let [e1, e2, e3] = m.young_moduli();
    let [g12, g13, g23] = m.shear_moduli();
    largest([
        ratio(e[0], f.xt / e1, f.xc / e1),
        ratio(e[1], f.yt / e2, f.yc / e2),
        ratio(e[2], f.zt / e3, f.zc / e3),
        e[3].abs() * (g23 / f.s23),
        e[4].abs() * (g13 / f.s13),
        e[5].abs() * (g12 / f.s12),
    ])
}

/// `1/R` of `a R² + b R = 1` (`a ≥ 0`): the index of a criterion with a quadratic part `a` and
/// a linear part `b` of the stress.
fn quadratic_index<S: Scalar>(a: S, b: S) -> S {
    // R = 2 / (b + √(b² + 4a)), so 1/R = (b + √(b² + 4a)) / 2 (no cancellation for b > 0; for
    // b < 0 the root dominates as long as a > 0)
    (b + (b * b + a * 4.0).sqrt()) * 0.5
}

fn tsai_wu<S: Scalar>(f: &PlyStrength, s: &[S; 6]) -> S {
    let lin = [
        1.0 / f.xt - 1.0 / f.xc,
        1.0 / f.yt - 1.0 / f.yc,
        1.0 / f.zt - 1.0 / f.zc,
    ];
    let diag = [
        1.0 / (f.xt * f.xc),
        1.0 / (f.yt * f.yc),
        1.0 / (f.zt * f.zc),
    ];
    let mut a = S::zero();
    let mut b = S::zero();
    for i in 0..3 {
        b += s[i] * lin[i];
        a += s[i] * s[i] * diag[i];
        for j in i + 1..3 {
            let fij = TSAI_WU_INTERACTION * (diag[i] * diag[j]).sqrt();
            a += s[i] * s[j] * (2.0 * fij);
        }
    }
    a += s[3] * s[3] * (1.0 / (f.s23 * f.s23))
        + s[4] * s[4] * (1.0 / (f.s13 * f.s13))
        + s[5] * s[5] * (1.0 / (f.s12 * f.s12));
    quadratic_index(a, b)
}

fn tsai_hill<S: Scalar>(f: &PlyStrength, s: &[S; 6]) -> S {
    let pick = |x: S, t: f64, c: f64| if x.value() >= 0.0 { t } else { c };
    let x = pick(s[0], f.xt, f.xc);
    // one transverse strength for both transverse directions, by the sign of σ22 + σ33: Hill's
    // form is then F(σ22 − σ33)² + G(σ33 − σ11)² + H(σ11 − σ22)² + … with F, G, H ≥ 0 (for
    // X ≥ Y/√2), never negative, and in plane stress the classical Tsai–Hill
    let y = pick(s[1] + s[2], f.yt, f.yc);
    let (ix, iy) = (1.0 / (x * x), 1.0 / (y * y));
    let p = (s[0] * s[0] - s[0] * s[1] - s[0] * s[2]) * ix + (s[1] * s[1] + s[2] * s[2]) * iy
        - s[1] * s[2] * (2.0 * iy - ix)
        + s[3] * s[3] * (1.0 / (f.s23 * f.s23))
        + s[4] * s[4] * (1.0 / (f.s13 * f.s13))
        + s[5] * s[5] * (1.0 / (f.s12 * f.s12));
    p.max(S::zero()).sqrt()
}

/// The axial shear `(τ12² + τ13²)/S12²` of Hashin's criteria (the axial shear strength `S12`).
fn axial_shear<S: Scalar>(f: &PlyStrength, s: &[S; 6]) -> S {
    (s[5] * s[5] + s[4] * s[4]) * (1.0 / (f.s12 * f.s12))
}

fn hashin_fibre<S: Scalar>(f: &PlyStrength, s: &[S; 6]) -> S {
    if s[0].value() >= 0.0 {
        (s[0] * s[0] * (1.0 / (f.xt * f.xt)) + axial_shear(f, s)).sqrt()
    } else {
        -s[0] * (1.0 / f.xc)
    }
}

fn hashin_matrix<S: Scalar>(f: &PlyStrength, s: &[S; 6]) -> S {
    let n = s[1] + s[2];
    let transverse = (s[3] * s[3] - s[1] * s[2]) * (1.0 / (f.s23 * f.s23));
    let quad = transverse + axial_shear(f, s);
    if n.value() >= 0.0 {
        (n * n * (1.0 / (f.yt * f.yt)) + quad).max(S::zero()).sqrt()
    } else {
        // [(Yc / 2S23)² − 1] (σ22 + σ33)/Yc + (σ22 + σ33)²/(4 S23²) + …
        let b = n * (((f.yc / (2.0 * f.s23)).powi(2) - 1.0) / f.yc);
        let a = n * n * (1.0 / (4.0 * f.s23 * f.s23)) + quad;
        quadratic_index(a.max(S::zero()), b)
    }
}
