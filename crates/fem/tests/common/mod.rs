//! Test problems with known answers (oracles independent of the element code).
#![allow(dead_code)]

use fem::{
    Assembly, BeamSection, Constraints, ElementOptions, MassKind, Mesh, ModalBody, ModalStresses,
    Properties,
};
use laminate::{LaminateStiffness, OrthotropicMaterial, Ply, PlyStack};
use nalgebra::{DMatrix, Matrix4, Vector3};
use sens::{Dual, Scalar};

/// An isotropic rectangular section, `hy` along x₂, `hz` along x₃; shear correction `kappa`.
pub struct Rect {
    pub e: f64,
    pub nu: f64,
    pub rho: f64,
    pub hy: f64,
    pub hz: f64,
    pub kappa: f64,
}

impl Rect {
    pub fn g(&self) -> f64 {
        self.e / (2.0 * (1.0 + self.nu))
    }
    pub fn area(&self) -> f64 {
        self.hy * self.hz
    }
    /// ∫ x₂² dA (bending about x₃).
    pub fn i3(&self) -> f64 {
        self.hz * self.hy.powi(3) / 12.0
    }
    pub fn i2(&self) -> f64 {
        self.hy * self.hz.powi(3) / 12.0
    }
    pub fn section(&self) -> BeamSection<f64> {
        let (a, g) = (self.area(), self.g());
        let j = self.i2() + self.i3();
        BeamSection::diagonal(
            [
                self.e * a,
                self.kappa * g * a,
                self.kappa * g * a,
                g * j,
                self.e * self.i2(),
                self.e * self.i3(),
            ],
            self.rho * a,
            self.rho * self.i2(),
            self.rho * self.i3(),
        )
    }
    pub fn props(&self) -> Properties<f64> {
        Properties {
            sections: vec![self.section()],
            laminates: vec![],
        }
    }
}

/// Simply supported Timoshenko beam (bending in one plane, rotary inertia included): the
/// bending eigenvalue ω² of mode `n`, the lower root of the 2×2 Navier system.
pub fn timoshenko_ss(ei: f64, kga: f64, rho_a: f64, rho_i: f64, l: f64, n: usize) -> f64 {
    let k = n as f64 * std::f64::consts::PI / l;
    // K = [[kGA k², −kGA k], [−kGA k, kGA + EI k²]], M = diag(ρA, ρI)
    let (k11, k12, k22) = (kga * k * k, -kga * k, kga + ei * k * k);
    // det(K − λM) = 0 : (k11 − λ m1)(k22 − λ m2) − k12² = 0
    let a = rho_a * rho_i;
    let b = -(k11 * rho_i + k22 * rho_a);
    let c = k11 * k22 - k12 * k12;
    let disc = (b * b - 4.0 * a * c).sqrt();
    (-b - disc) / (2.0 * a)
}

/// Clamped–free Timoshenko beam eigenvalues ω² (lowest `count`) by the exact transfer matrix
/// of the state `[w, φ, M, Q]` and bisection on `det` of the free-end block.
pub fn timoshenko_cantilever(
    ei: f64,
    kga: f64,
    rho_a: f64,
    rho_i: f64,
    l: f64,
    count: usize,
) -> Vec<f64> {
    let whole = Stretch {
        ei,
        kga,
        rho_a,
        rho_i,
        l,
    };
    timoshenko_stepped_cantilever(&[whole], count)
}

/// A uniform stretch of a stepped Timoshenko beam: bending and shear stiffness, mass and
/// rotary inertia per length, length.
#[derive(Clone, Copy)]
pub struct Stretch {
    pub ei: f64,
    pub kga: f64,
    pub rho_a: f64,
    pub rho_i: f64,
    pub l: f64,
}

/// The transfer matrix `exp(A l)` of the state `[w, φ, M, Q]` over a uniform stretch at the
/// circular frequency `omega`, by scaling and squaring of a Taylor series.
fn stretch_transfer(s: &Stretch, omega: f64) -> Matrix4<f64> {
    let w2 = omega * omega;
    #[rustfmt::skip]
    let a = Matrix4::new(
        0.0, 1.0, 0.0, 1.0 / s.kga,
        0.0, 0.0, 1.0 / s.ei, 0.0,
        0.0, -w2 * s.rho_i, 0.0, -1.0,
        -w2 * s.rho_a, 0.0, 0.0, 0.0,
    );
    let steps = 24;
    let h = a * (s.l / f64::powi(2.0, steps));
    let mut e = Matrix4::<f64>::identity();
    let mut term = Matrix4::<f64>::identity();
    for k in 1..30 {
        term = term * h / k as f64;
        e += term;
    }
    for _ in 0..steps {
        e = e * e;
    }
    e
}

/// Clamped–free eigenvalues ω² (lowest `count`) of a beam of uniform `stretches` in order from
/// the clamp: the product of their exact transfer matrices (state and section forces continuous
/// where two stretches meet), bisection on `det` of the free-end block.
pub fn timoshenko_stepped_cantilever(stretches: &[Stretch], count: usize) -> Vec<f64> {
    let det = |omega: f64| -> f64 {
        let e = stretches.iter().fold(Matrix4::<f64>::identity(), |e, s| {
            stretch_transfer(s, omega) * e
        });
        // s(0) = [0, 0, M0, Q0]; free end: M(L) = Q(L) = 0
        let d = e[(2, 2)] * e[(3, 3)] - e[(2, 3)] * e[(3, 2)];
        // scale-free sign function
        d / (e[(2, 2)].abs() + e[(3, 3)].abs() + e[(2, 3)].abs() + e[(3, 2)].abs()).powi(2)
    };
    let l: f64 = stretches.iter().map(|s| s.l).sum();
    // the lowest root is above 3.5 of the softest stretch's scale: start below it
    let soft = stretches
        .iter()
        .map(|s| s.ei / s.rho_a)
        .fold(f64::INFINITY, f64::min);
    let mut out = Vec::new();
    let w0 = (soft / l.powi(4)).sqrt();
    let mut lo = 0.1 * w0;
    let step = 0.05 * w0;
    let mut flo = det(lo);
    while out.len() < count {
        let hi = lo + step;
        let fhi = det(hi);
        if flo.signum() != fhi.signum() {
            let (mut a, mut b, mut fa) = (lo, hi, flo);
            for _ in 0..200 {
                let c = 0.5 * (a + b);
                let fc = det(c);
                if fc.signum() == fa.signum() {
                    a = c;
                    fa = fc;
                } else {
                    b = c;
                }
            }
            out.push((0.5 * (a + b)).powi(2));
        }
        lo = hi;
        flo = fhi;
    }
    out
}

/// The composite of the paper (docs/design.md §4).
pub fn paper_material() -> OrthotropicMaterial {
    OrthotropicMaterial::new(
        [128e9, 10.1e9, 10.1e9],
        [5.36e9, 5.36e9, 5.36e9],
        [0.23, 0.23, 0.23],
        1586.0,
    )
    .unwrap()
}

/// A stack of equal-thickness plies of one material at the given angles (degrees).
pub fn stack(mat: OrthotropicMaterial, total: f64, angles_deg: &[f64]) -> PlyStack<f64> {
    let t = total / angles_deg.len() as f64;
    PlyStack::new(
        angles_deg
            .iter()
            .map(|a| Ply {
                material: mat,
                thickness: t,
                angle: a.to_radians(),
            })
            .collect(),
    )
    .unwrap()
}

/// Navier first-order shear deformation solution for a simply supported rectangular plate
/// `a × b`: the lowest eigenvalue ω² over modes `m, n ≤ max_mn`, from a Ritz projection on the
/// exact Navier trial functions of the five fields (u, v, w, φx, φy), integrated numerically.
/// `ss2`: the SS-2 in-plane conditions of antisymmetric angle-ply plates (normal in-plane
/// displacement fixed, u ∝ sin·cos); otherwise SS-1 (tangential fixed, cross-ply).
pub fn navier_fsdt(lam: &LaminateStiffness<f64>, a: f64, b: f64, max_mn: usize, ss2: bool) -> f64 {
    let mut best = f64::INFINITY;
    for m in 1..=max_mn {
        for n in 1..=max_mn {
            let l = navier_mode(lam, a, b, m, n, ss2);
            best = best.min(l);
        }
    }
    best
}

/// Lowest ω² of Navier mode (m, n).
pub fn navier_mode(
    lam: &LaminateStiffness<f64>,
    a: f64,
    b: f64,
    m: usize,
    n: usize,
    ss2: bool,
) -> f64 {
    use std::f64::consts::PI;
    let al = m as f64 * PI / a;
    let be = n as f64 * PI / b;
    // fields: value and derivatives (d/dx, d/dy) of each trial function at (x, y)
    // u: SS-1 cos·sin, SS-2 sin·cos ; v: SS-1 sin·cos, SS-2 cos·sin; w sin·sin; φx cos·sin; φy sin·cos
    let f = |kind: u8, x: f64, y: f64| -> [f64; 3] {
        let (sx, cx, sy, cy) = (
            (al * x).sin(),
            (al * x).cos(),
            (be * y).sin(),
            (be * y).cos(),
        );
        match kind {
            0 => [sx * sy, al * cx * sy, be * sx * cy],  // sin sin
            1 => [cx * sy, -al * sx * sy, be * cx * cy], // cos sin
            _ => [sx * cy, al * cx * cy, -be * sx * sy], // sin cos
        }
    };
    let (ku, kv) = if ss2 { (2u8, 1u8) } else { (1u8, 2u8) };
    let kinds = [ku, kv, 0, 1, 2]; // u, v, w, φx, φy
    // Gauss–Legendre on [0, a] × [0, b], 24 points each (exact enough for these trig products)
    let (gp, gw) = gauss_legendre(24);
    let mut kk = DMatrix::<f64>::zeros(5, 5);
    let mut mm = DMatrix::<f64>::zeros(5, 5);
    let abd = lam.abd();
    for (i, &xi) in gp.iter().enumerate() {
        for (j, &yj) in gp.iter().enumerate() {
            let x = 0.5 * a * (xi + 1.0);
            let y = 0.5 * b * (yj + 1.0);
            let w = gw[i] * gw[j] * 0.25 * a * b;
            let vals: Vec<[f64; 3]> = kinds.iter().map(|&k| f(k, x, y)).collect();
            // generalised strain of unit amplitude of each field: [ε0(3); κ(3)] and γ(2)
            let mut e = DMatrix::<f64>::zeros(6, 5);
            let mut g = DMatrix::<f64>::zeros(2, 5);
            // u
            e[(0, 0)] = vals[0][1];
            e[(2, 0)] = vals[0][2];
            // v
            e[(1, 1)] = vals[1][2];
            e[(2, 1)] = vals[1][1];
            // w
            g[(0, 2)] = vals[2][1];
            g[(1, 2)] = vals[2][2];
            // φx
            e[(3, 3)] = vals[3][1];
            e[(5, 3)] = vals[3][2];
            g[(0, 3)] = vals[3][0];
            // φy
            e[(4, 4)] = vals[4][2];
            e[(5, 4)] = vals[4][1];
            g[(1, 4)] = vals[4][0];
            kk += (e.transpose() * abd * &e + g.transpose() * lam.shear * &g) * w;
            let (i0, i1, i2) = (lam.mass_per_area, lam.first_moment, lam.rotary_inertia);
            let v: Vec<f64> = vals.iter().map(|q| q[0]).collect();
            for p in 0..3 {
                mm[(p, p)] += i0 * v[p] * v[p] * w;
            }
            mm[(3, 3)] += i2 * v[3] * v[3] * w;
            mm[(4, 4)] += i2 * v[4] * v[4] * w;
            mm[(0, 3)] += i1 * v[0] * v[3] * w;
            mm[(3, 0)] += i1 * v[0] * v[3] * w;
            mm[(1, 4)] += i1 * v[1] * v[4] * w;
            mm[(4, 1)] += i1 * v[1] * v[4] * w;
        }
    }
    let l = mm.clone().cholesky().unwrap().l();
    let li = l.try_inverse().unwrap();
    let c = &li * kk * li.transpose();
    let c = (&c + c.transpose()) * 0.5;
    c.symmetric_eigenvalues()
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min)
}

/// Gauss–Legendre nodes and weights on [−1, 1] (Newton on P_n).
pub fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut x = vec![0.0; n];
    let mut w = vec![0.0; n];
    for i in 0..n {
        let mut z = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, z);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * z * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            let dp = n as f64 * (z * p1 - p0) / (z * z - 1.0);
            let dz = p1 / dp;
            z -= dz;
            if dz.abs() < 1e-16 {
                break;
            }
        }
        let (mut p0, mut p1) = (1.0, z);
        for k in 2..=n {
            let p2 = ((2 * k - 1) as f64 * z * p1 - (k - 1) as f64 * p0) / k as f64;
            p0 = p1;
            p1 = p2;
        }
        let dp = n as f64 * (z * p1 - p0) / (z * z - 1.0);
        x[i] = z;
        w[i] = 2.0 / ((1.0 - z * z) * dp * dp);
    }
    (x, w)
}

/// Relative difference.
pub fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// A slender aluminium bar, 20 × 10 mm (weak axis: bending in x–z, about x₂ = y).
pub fn slender() -> Rect {
    Rect {
        e: 70e9,
        nu: 0.3,
        rho: 2700.0,
        hy: 0.02,
        hz: 0.01,
        kappa: 5.0 / 6.0,
    }
}

/// A 1 m beam along x from x = 0.2 (section x₂ = y), `n` elements, nodes `0..=n`.
pub fn beam(n: usize) -> fem::Mesh {
    fem::Mesh::straight_beam(
        Vector3::new(0.2, 0.0, 0.0),
        Vector3::new(1.2, 0.0, 0.0),
        n,
        0,
        Vector3::y(),
    )
    .unwrap()
}

/// A body whose "modes" are the given nodal fields (6 per node, mesh axes).
pub fn body_of<S: Scalar>(mesh: &Mesh, modes: DMatrix<S>) -> ModalBody<S> {
    let n = mesh.nodes.len();
    let nm = modes.ncols();
    ModalBody {
        node_positions: mesh.nodes.clone(),
        node_masses: vec![S::one(); n],
        node_inertias: vec![Vector3::zeros(); n],
        modes,
        eigenvalues: vec![S::one(); nm],
        modal_damping: vec![S::zero(); nm],
        stiffness_matrix: None,
        damping_matrix: None,
    }
}

/// Every stress of `dual` at the modal coordinates `w` with its tangent `j` and the central
/// difference of the same stress in `plus` and `minus` (the design moved by `±h`):
/// `((element, point, component), tangent, difference)`.
#[allow(clippy::type_complexity)]
pub fn stress_derivative_pairs<const N: usize>(
    dual: &ModalStresses<Dual<N>>,
    (plus, minus): (&ModalStresses<Dual<N>>, &ModalStresses<Dual<N>>),
    w: &[Dual<N>],
    (j, h): (usize, f64),
) -> Vec<((usize, usize, usize), f64, f64)> {
    let mut pairs = Vec::new();
    for i in 0..dual.elements.len() {
        let (dd, dp, dm) = (
            dual.deformation(i, w),
            plus.deformation(i, w),
            minus.deformation(i, w),
        );
        let points = dual.laminates[dual.elements[i].laminate].points.len();
        for k in 0..points {
            let (s, sp, sm) = (
                dual.stress(i, k, &dd),
                plus.stress(i, k, &dp),
                minus.stress(i, k, &dm),
            );
            for r in 0..6 {
                pairs.push(((i, k, r), s[r].d[j], (sp[r].v - sm[r].v) / (2.0 * h)));
            }
        }
    }
    pairs
}

/// The static displacements (6 per node, mesh axes; zero where `constraints` fix them) of
/// `mesh` with `props` under the nodal loads `f` (6 per node), by a dense solve.
pub fn static_displacements(
    mesh: &Mesh,
    props: &Properties<f64>,
    constraints: &Constraints,
    f: &[f64],
) -> Vec<f64> {
    let asm = Assembly::new(mesh, constraints).unwrap();
    let (kv, _) = asm
        .values(mesh, props, &ElementOptions::default(), MassKind::Lumped)
        .unwrap();
    let k = asm.matrix(kv);
    let nf = asm.n_free();
    let mut kd = DMatrix::<f64>::zeros(nf, nf);
    let (cp, ri) = (k.symbolic().col_ptr(), k.symbolic().row_idx());
    for j in 0..nf {
        for q in cp[j]..cp[j + 1] {
            kd[(ri[q], j)] = k.val()[q];
        }
    }
    let u = kd.lu().solve(&asm.restrict(f)).unwrap();
    asm.expand(u.as_slice())
}
