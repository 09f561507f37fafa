//! A ply thickness as a design variable, against closed forms: the derivatives of an
//! isotropic tube's and box's axial, bending and torsional stiffnesses and mass per length with
//! respect to a wall thickness.

mod common;
use common::*;
use section::{BoxWalls, DesignMap, GeneratedSection, PlySpec, analyse_with_derivatives};
use std::f64::consts::PI;

/// Tube of inner radius `ri`, wall `t`: `EA = Eπ(ro² − ri²)`, `EI = Eπ(ro⁴ − ri⁴)/4`,
/// `GJ = Gπ(ro⁴ − ri⁴)/2`, `m = ρπ(ro² − ri²)` with `ro = ri + t`; the inner ply's thickness
/// moves the outer ply out, so the derivative with respect to either is the same:
/// `dEA/dt = 2πE ro`, `dEI/dt = πE ro³`, `dGJ/dt = 2πG ro³`, `dm/dt = 2πρ ro`.
#[test]
fn isotropic_tube_wall_thickness() {
    let (e, nu) = (70e9, 0.33);
    let g = e / (2.0 * (1.0 + nu));
    let m = isotropic(e, nu);
    let rho = m.density();
    let (ri, t1, t2) = (0.02, 0.001, 0.0015);
    let ro = ri + t1 + t2;
    for around in [24, 48, 96] {
        let generated = GeneratedSection::Tube {
            inner_radius: ri,
            plies: vec![
                PlySpec::new("inner", m, 0.0, t1, 1),
                PlySpec::new("outer", m, 0.0, t2, 2),
            ],
            circumferential: around,
        };
        let mesh = generated.mesh().unwrap();
        let mut design = DesignMap::new();
        for ply in ["inner", "outer"] {
            let v = generated
                .node_velocities(|p| f64::from(u8::from(p.name == ply)))
                .unwrap();
            design = design.with_geometry_variable(ply, &v);
        }
        let s = analyse_with_derivatives::<2>(&mesh, &design).unwrap();
        let mut worst: f64 = 0.0;
        for d in &s.derivatives {
            let k = &d.stiffness;
            for (value, exact, what) in [
                (k[(0, 0)], 2.0 * PI * e * ro, "dEA/dt"),
                (k[(4, 4)], PI * e * ro.powi(3), "dEI22/dt"),
                (k[(5, 5)], PI * e * ro.powi(3), "dEI33/dt"),
                (k[(3, 3)], 2.0 * PI * g * ro.powi(3), "dGJ/dt"),
                (d.mass_per_length, 2.0 * PI * rho * ro, "dm/dt"),
            ] {
                let err = rel(value, exact);
                worst = worst.max(err);
                // the quadratic mesh's circles: fourth order (2.0e-5 at 24 around, 7.6e-8 at 96)
                let bound = 3e-5 * (24.0 / around as f64).powi(4);
                assert!(
                    err < bound,
                    "{around} around, {what}: {value:e} against {exact:e}"
                );
            }
        }
        println!("{around} around: worst relative error {worst:e}");
    }
}

/// An isotropic box `W × H` with one ply of thickness `t` on all walls:
/// `A = WH − (W − 2t)(H − 2t)`, `I₂₂ = (WH³ − (W − 2t)(H − 2t)³)/12`, so
/// `dA/dt = 2(W − 2t) + 2(H − 2t)` and
/// `dI₂₂/dt = (2(H − 2t)³ + 6(W − 2t)(H − 2t)²)/12`; `EA` and `EI` of a homogeneous section
/// are exact.
#[test]
fn isotropic_box_wall_thickness() {
    let (e, nu) = (70e9, 0.33);
    let m = isotropic(e, nu);
    let rho = m.density();
    let (w, h, t) = (0.04, 0.03, 0.002);
    let generated = GeneratedSection::Walled {
        width: w,
        height: h,
        walls: BoxWalls::uniform(vec![PlySpec::new("wall", m, 0.0, t, 2)]),
        n_width: 8,
        n_height: 6,
        open: false,
    };
    let mesh = generated.mesh().unwrap();
    let v = generated.node_velocities(|_| 1.0).unwrap();
    let design = DesignMap::new().with_geometry_variable("t", &v);
    let s = analyse_with_derivatives::<1>(&mesh, &design).unwrap();
    let d = &s.derivatives[0];
    let (wi, hi) = (w - 2.0 * t, h - 2.0 * t);
    let da = 2.0 * wi + 2.0 * hi;
    let di22 = (2.0 * hi.powi(3) + 6.0 * wi * hi * hi) / 12.0;
    let di33 = (2.0 * wi.powi(3) + 6.0 * hi * wi * wi) / 12.0;
    for (value, exact, what) in [
        (d.stiffness[(0, 0)], e * da, "dEA/dt"),
        (d.stiffness[(4, 4)], e * di22, "dEI22/dt"),
        (d.stiffness[(5, 5)], e * di33, "dEI33/dt"),
        (d.mass_per_length, rho * da, "dm/dt"),
    ] {
        assert!(
            rel(value, exact) < 1e-9,
            "{what}: {value:e} against {exact:e}"
        );
    }
}
