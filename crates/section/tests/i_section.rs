//! The I section generator against closed forms: an isotropic I's extension and bending
//! stiffnesses (exact for a homogeneous section), its torsion against the thin-walled sum of
//! its three strips, its shear centre (doubly symmetric: at the centroid), a flange thickness
//! as a design variable, and a 0° composite I's axial stiffness.

mod common;
use common::*;
use section::{DesignMap, GeneratedSection, IWalls, PlySpec, analyse, analyse_with_derivatives};

const B: f64 = 0.05; // flange width
const H: f64 = 0.08; // outer height
const TF: f64 = 0.004; // flange thickness
const TW: f64 = 0.003; // web thickness

fn i_beam(material: laminate::OrthotropicMaterial, n: usize) -> GeneratedSection {
    let ply = |name: &str, t: f64| PlySpec::new(name, material, 0.0, t, 2);
    GeneratedSection::I {
        width: B,
        height: H,
        walls: IWalls {
            top: vec![ply("tf", TF)],
            bottom: vec![ply("bf", TF)],
            web: vec![ply("w", TW)],
        },
        n_side: n,
        n_web: 2 * n,
    }
}

#[test]
fn isotropic_i_section_against_closed_forms() {
    let (e, nu) = (70e9, 0.3);
    let g = e / (2.0 * (1.0 + nu));
    let m = isotropic(e, nu);
    let hw = H - 2.0 * TF;
    let area = 2.0 * B * TF + hw * TW;
    let i22 = (B * H.powi(3) - (B - TW) * hw.powi(3)) / 12.0;
    let i33 = (2.0 * TF * B.powi(3) + hw * TW.powi(3)) / 12.0;
    // thin strips with their end correction (1 − 0.63 t/b); the junctions add a little
    let strip = |b: f64, t: f64| b * t.powi(3) / 3.0 * (1.0 - 0.63 * t / b);
    let j = 2.0 * strip(B, TF) + strip(hw, TW);
    let mut gj = Vec::new();
    for n in [4, 8, 16] {
        let p = analyse(&i_beam(m, n).mesh().unwrap()).unwrap();
        let k = p.stiffness;
        for (got, exact, what) in [
            (k[(0, 0)], e * area, "EA"),
            (k[(4, 4)], e * i22, "EI22"),
            (k[(5, 5)], e * i33, "EI33"),
            (p.mass_per_length, m.density() * area, "mass per length"),
        ] {
            assert!(rel(got, exact) < 1e-9, "{n}: {what} {got:e} vs {exact:e}");
        }
        for c in [p.shear_centre, p.tension_centre] {
            assert!(c[0].abs() < 1e-12 && c[1].abs() < 1e-12, "{c:?}");
        }
        println!("{n}: GJ / thin-walled {:.4}", k[(3, 3)] / (g * j));
        gj.push(k[(3, 3)]);
    }
    // converging with the mesh (slowly: the re-entrant corners at the junctions), and a few
    // per cent above the strips' sum (the junctions' material)
    let (d1, d2) = (rel(gj[0], gj[1]), rel(gj[1], gj[2]));
    assert!(d2 < 0.7 * d1 && d2 < 5e-3, "{gj:?}");
    assert!(
        (1.0..1.06).contains(&(gj[2] / (g * j))),
        "{}",
        gj[2] / (g * j)
    );
}

/// The top flange thicker, growing inwards at a fixed outer size: its area grows by
/// `(B − TW) dt`, and the second moment about the origin by `(B − TW)(H/2 − TF)² dt` (a strip
/// of the web becomes flange at `x₃ = H/2 − TF`).
#[test]
fn flange_thickness_derivatives() {
    let (e, nu) = (70e9, 0.3);
    let m = isotropic(e, nu);
    let generated = i_beam(m, 4);
    let mesh = generated.mesh().unwrap();
    let v = generated
        .node_velocities(|p| f64::from(u8::from(p.name == "tf")))
        .unwrap();
    let design = DesignMap::new().with_geometry_variable("tf", &v);
    let d = &analyse_with_derivatives::<1>(&mesh, &design)
        .unwrap()
        .derivatives[0];
    let da = B - TW;
    let di22 = (B - TW) * (H / 2.0 - TF).powi(2);
    for (got, exact, what) in [
        (d.stiffness[(0, 0)], e * da, "dEA/dt"),
        (d.stiffness[(4, 4)], e * di22, "dEI22/dt"),
        (d.mass_per_length, m.density() * da, "dm/dt"),
    ] {
        assert!(rel(got, exact) < 1e-9, "{what}: {got:e} vs {exact:e}");
    }
}

/// Fibres along the beam axis in every wall: a uniaxial stress state is admissible, so
/// `EA = E₁ A` exactly.
#[test]
fn zero_degree_composite_i_section_axial_stiffness() {
    let c = composite();
    let p = analyse(&i_beam(c, 4).mesh().unwrap()).unwrap();
    let area = 2.0 * B * TF + (H - 2.0 * TF) * TW;
    assert!(rel(p.stiffness[(0, 0)], 128e9 * area) < 1e-9);
    // a web of its own lay-up is refused where it does not fit
    let ply = |t: f64| PlySpec::new("p", c, 0.0, t, 1);
    let too_thick = GeneratedSection::I {
        width: 0.01,
        height: H,
        walls: IWalls {
            top: vec![ply(TF)],
            bottom: vec![ply(TF)],
            web: vec![ply(0.02)],
        },
        n_side: 2,
        n_web: 4,
    };
    let e = too_thick.mesh().unwrap_err().to_string();
    assert!(e.contains("does not fit"), "{e}");
}

/// Flanges as thick as the height leave no web: the message names the web, the height and the
/// height it needs; a web as wide as the flanges names the width.
#[test]
fn walls_that_do_not_fit_are_named() {
    let mut s = i_beam(
        laminate::OrthotropicMaterial::isotropic(70e9, 0.3, 2700.0).unwrap(),
        2,
    );
    if let GeneratedSection::I { height, .. } = &mut s {
        *height = 2.0 * TF;
    }
    let e = s.mesh().unwrap_err().to_string();
    assert!(
        e.contains("no room for the web")
            && e.contains("height of 0.008 m")
            && e.contains("must exceed 0.008 m"),
        "{e}"
    );
    let mut s = i_beam(
        laminate::OrthotropicMaterial::isotropic(70e9, 0.3, 2700.0).unwrap(),
        2,
    );
    if let GeneratedSection::I { width, .. } = &mut s {
        *width = TW;
    }
    let e = s.mesh().unwrap_err().to_string();
    assert!(e.contains("web") && e.contains("width"), "{e}");
}
