//! Mesh input: the simple text format, Gmsh 4.1 ASCII, 6-node triangles and 9-node
//! quadrilaterals, and the errors for bad meshes and bad text.

mod common;
use common::*;
use section::{
    Element, ElementKind, Region, RegionSpec, SectionError, SectionMesh, WallFrame, analyse,
    parse_gmsh, parse_simple, rectangle, write_simple,
};
use std::f64::consts::PI;

/// A `b × h` rectangle on a Lagrange grid, as 9-node quadrilaterals or pairs of 6-node
/// triangles.
fn lagrange_rectangle(b: f64, h: f64, n: usize, m: usize, kind: ElementKind) -> SectionMesh {
    let (cols, rows) = (2 * n + 1, 2 * m + 1);
    let id = |i: usize, j: usize| j * cols + i;
    let mut nodes = Vec::new();
    for j in 0..rows {
        for i in 0..cols {
            nodes.push([
                -0.5 * b + b * i as f64 / (2 * n) as f64,
                -0.5 * h + h * j as f64 / (2 * m) as f64,
            ]);
        }
    }
    let mut elements = Vec::new();
    for cj in 0..m {
        for ci in 0..n {
            let (i, j) = (2 * ci, 2 * cj);
            match kind {
                ElementKind::Quad9 => elements.push(Element {
                    kind,
                    nodes: vec![
                        id(i, j),
                        id(i + 2, j),
                        id(i + 2, j + 2),
                        id(i, j + 2),
                        id(i + 1, j),
                        id(i + 2, j + 1),
                        id(i + 1, j + 2),
                        id(i, j + 1),
                        id(i + 1, j + 1),
                    ],
                    region: 0,
                }),
                _ => {
                    elements.push(Element {
                        kind: ElementKind::Tri6,
                        nodes: vec![
                            id(i, j),
                            id(i + 2, j),
                            id(i + 2, j + 2),
                            id(i + 1, j),
                            id(i + 2, j + 1),
                            id(i + 1, j + 1),
                        ],
                        region: 0,
                    });
                    elements.push(Element {
                        kind: ElementKind::Tri6,
                        nodes: vec![
                            id(i, j),
                            id(i + 2, j + 2),
                            id(i, j + 2),
                            id(i + 1, j + 1),
                            id(i + 1, j + 2),
                            id(i, j + 1),
                        ],
                        region: 0,
                    });
                }
            }
        }
    }
    let regions = vec![Region::new(
        "solid",
        isotropic(70e9, 0.3),
        0.0,
        WallFrame::Tangent(0.0),
    )];
    SectionMesh {
        nodes,
        elements,
        regions,
    }
}

#[test]
fn triangles_and_nine_node_quads_agree_with_eight_node_quads() {
    let (b, h) = (0.02, 0.01);
    let q8 = analyse(&rectangle(b, h, 16, 8, isotropic(70e9, 0.3), 0.0).unwrap()).unwrap();
    for kind in [ElementKind::Quad9, ElementKind::Tri6] {
        let p = analyse(&lagrange_rectangle(b, h, 16, 8, kind)).unwrap();
        for i in [0, 4, 5] {
            assert!(
                rel(p.stiffness[(i, i)], q8.stiffness[(i, i)]) < 1e-10,
                "{kind:?} K[{i}][{i}]"
            );
        }
        for i in [1, 2, 3] {
            assert!(
                rel(p.stiffness[(i, i)], q8.stiffness[(i, i)]) < 2e-3,
                "{kind:?} K[{i}][{i}]"
            );
        }
    }
}

#[test]
fn simple_format_round_trip() {
    let deg = std::f64::consts::PI / 180.0;
    let plies = [
        section::PlySpec::new("in", composite(), 20.0 * deg, 0.0005, 1),
        section::PlySpec::new("out", composite(), -50.0 * deg, 0.0005, 1),
    ];
    let mesh = section::tube(0.01, &plies, 16).unwrap();
    let text = write_simple(&mesh);
    let back = parse_simple(&text, &[]).unwrap();
    assert_eq!(back.elements, mesh.elements);
    let (p, q) = (analyse(&mesh).unwrap(), analyse(&back).unwrap());
    assert!(scaled_diff(&p.stiffness, &q.stiffness, &p.stiffness) < 1e-12);
    // element-aligned wall frames survive the round trip too (regression: `xi`/`eta` were
    // written but not read)
    let mut along = mesh.clone();
    along.regions[0].frame = section::WallFrame::AlongElement(section::ElementDirection::Xi);
    along.regions[1].frame = section::WallFrame::AlongElement(section::ElementDirection::Eta);
    let back = parse_simple(&write_simple(&along), &[]).unwrap();
    assert_eq!(
        back.regions.iter().map(|r| r.frame).collect::<Vec<_>>(),
        along.regions.iter().map(|r| r.frame).collect::<Vec<_>>()
    );
}

/// Entity counts whose sum overflows are an error, not a panic (debug) or a misleading error.
#[test]
fn gmsh_entity_counts_that_overflow_are_an_error() {
    let text = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Entities\n18446744073709551615 1 0 0\n\
                $EndEntities\n";
    assert!(section::parse_gmsh(text, &[]).is_err());
}

#[test]
fn a_gmsh_header_with_an_absurd_node_count_is_an_error_not_an_abort() {
    let text = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 100000000000 1 100000000000\n2 1 0 100000000000\n1\n$EndNodes\n";
    assert!(section::parse_gmsh(text, &[]).is_err());
}

#[test]
fn simple_format_errors_name_the_line() {
    let base = "material al isotropic 70e9 0.3 2700\nregion solid al 0 tangent 0\n\
                node 1 0 0\nnode 2 1 0\nnode 3 0 1\nnode 4 0.5 0\nnode 5 0.5 0.5\nnode 6 0 0.5\n";
    let ok = format!("{base}element tri6 solid 1 2 3 4 5 6\n");
    let mesh = parse_simple(&ok, &[]).unwrap();
    assert_eq!(mesh.elements.len(), 1);
    let err = parse_simple(&ok.replace("region solid al", "region solid steel"), &[]).unwrap_err();
    assert_eq!(
        err,
        SectionError::UnknownMaterial {
            name: "steel".into(),
            line: Some(2)
        }
    );
    // A material supplied by the caller is found.
    let steel = isotropic(210e9, 0.3);
    assert!(
        parse_simple(
            &ok.replace("region solid al", "region solid steel"),
            &[("steel", steel)]
        )
        .is_ok()
    );
    let err = parse_simple(&format!("{base}element tri6 skin 1 2 3 4 5 6\n"), &[]).unwrap_err();
    assert_eq!(
        err,
        SectionError::UnknownRegion {
            name: "skin".into(),
            line: Some(9)
        }
    );
    let err = parse_simple(&format!("{base}element tri3 solid 1 2 3\n"), &[]).unwrap_err();
    assert!(matches!(err, SectionError::Parse { line: 9, .. }), "{err}");
    let err = parse_simple(&format!("{base}element tri6 solid 1 2 3 4 5 7\n"), &[]).unwrap_err();
    assert!(err.to_string().contains("node 7 is not defined"), "{err}");
    // angles are degrees, as in the deck: 90 turns the material axes a quarter turn
    let turned = parse_simple(&ok.replace("al 0 tangent 0", "al 90 tangent 0"), &[]).unwrap();
    assert!((turned.regions[0].ply_angle - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
    let turned = parse_simple(&ok.replace("al 0 tangent 0", "al 0 tangent 45"), &[]).unwrap();
    assert_eq!(
        turned.regions[0].frame,
        section::WallFrame::Tangent(std::f64::consts::FRAC_PI_4)
    );
    // and a non-finite one is named in that unit, with its line
    for bad in ["al nan tangent 0", "al 0 tangent inf"] {
        let err = parse_simple(&ok.replace("al 0 tangent 0", bad), &[]).unwrap_err();
        assert!(matches!(err, SectionError::Parse { line: 2, .. }), "{err}");
        assert!(err.to_string().contains("(degrees)"), "{err}");
    }
}

/// The rectangle mesh written as Gmsh 4.1 text (one surface in physical group "web").
fn gmsh_text(mesh: &SectionMesh) -> String {
    let mut s = String::from("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n");
    s += "$PhysicalNames\n1\n2 7 \"web\"\n$EndPhysicalNames\n";
    s += "$Entities\n0 0 1 0\n3 -1 -1 0 1 1 0 1 7 0\n$EndEntities\n";
    let n = mesh.nodes.len();
    s += &format!("$Nodes\n1 {n} 1 {n}\n2 3 0 {n}\n");
    for i in 0..n {
        s += &format!("{}\n", i + 1);
    }
    for p in &mesh.nodes {
        s += &format!("{:e} {:e} 0\n", p[0], p[1]);
    }
    s += "$EndNodes\n";
    let m = mesh.elements.len();
    s += &format!(
        "$Elements\n2 {} 1 {}\n1 5 1 1\n1 1 2\n2 3 16 {m}\n",
        m + 1,
        m + 1
    );
    for (k, e) in mesh.elements.iter().enumerate() {
        let ids: Vec<String> = e.nodes.iter().map(|i| (i + 1).to_string()).collect();
        s += &format!("{} {}\n", k + 2, ids.join(" "));
    }
    s + "$EndElements\n"
}

#[test]
fn gmsh_mesh_gives_the_same_section() {
    let mesh = rectangle(0.02, 0.01, 8, 4, isotropic(70e9, 0.3), 0.0).unwrap();
    let text = gmsh_text(&mesh);
    let spec = RegionSpec {
        name: "web".into(),
        material: isotropic(70e9, 0.3),
        ply_angle: 0.0,
        frame: WallFrame::Tangent(0.0),
    };
    let parsed = parse_gmsh(&text, std::slice::from_ref(&spec)).unwrap();
    assert_eq!(parsed.elements.len(), mesh.elements.len());
    let (p, q) = (analyse(&mesh).unwrap(), analyse(&parsed).unwrap());
    assert!(scaled_diff(&p.stiffness, &q.stiffness, &p.stiffness) < 1e-12);

    let other = RegionSpec {
        name: "flange".into(),
        ..spec
    };
    let err = parse_gmsh(&text, &[other]).unwrap_err();
    assert!(
        matches!(err, SectionError::UnknownRegion { ref name, .. } if name == "web"),
        "{err}"
    );
    let linear = text.replace("2 3 16 ", "2 3 3 ");
    assert!(
        parse_gmsh(&linear, &[])
            .unwrap_err()
            .to_string()
            .contains("second-order")
    );
    let old = text.replace("4.1 0 8", "2.2 0 8");
    assert!(
        parse_gmsh(&old, &[])
            .unwrap_err()
            .to_string()
            .contains("need 4.1")
    );
}

#[test]
fn bad_meshes_give_clear_errors() {
    let good = rectangle(0.02, 0.01, 2, 2, isotropic(70e9, 0.3), 0.0).unwrap();
    assert!(good.validate().is_ok());

    // Clockwise element.
    let mut m = good.clone();
    let n = m.elements[1].nodes.clone();
    m.elements[1].nodes = vec![n[0], n[3], n[2], n[1], n[7], n[6], n[5], n[4]];
    assert!(matches!(
        analyse(&m),
        Err(SectionError::InvertedElement { element: 1, .. })
    ));

    // Zero area: all nodes of element 0 moved onto a line.
    let mut m = good.clone();
    for &k in &m.elements[0].nodes.clone() {
        m.nodes[k][1] = -0.005;
    }
    let err = analyse(&m).unwrap_err();
    assert!(
        matches!(err, SectionError::DegenerateElement { element: 0, .. }),
        "{err}"
    );

    // Two pieces.
    let mut m = good.clone();
    let shifted = good.translated([0.05, 0.0]);
    let off = m.nodes.len();
    m.nodes.extend(shifted.nodes);
    for e in shifted.elements {
        m.elements.push(Element {
            nodes: e.nodes.iter().map(|i| i + off).collect(),
            ..e
        });
    }
    let err = analyse(&m).unwrap_err();
    assert!(
        matches!(
            err,
            SectionError::Disconnected {
                parts: 2,
                element: 4
            }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("not connected"));

    // Dangling indices.
    let mut m = good.clone();
    m.elements[2].nodes[3] = 999;
    assert!(matches!(
        analyse(&m),
        Err(SectionError::NodeOutOfRange {
            element: 2,
            node: 999,
            ..
        })
    ));
    let mut m = good.clone();
    m.elements[3].region = 4;
    assert!(matches!(
        analyse(&m),
        Err(SectionError::RegionOutOfRange { element: 3, .. })
    ));
    let mut m = good.clone();
    m.elements[0].nodes.pop();
    assert!(matches!(
        analyse(&m),
        Err(SectionError::WrongNodeCount { element: 0, .. })
    ));
    assert!(matches!(
        analyse(&SectionMesh::default()),
        Err(SectionError::Empty)
    ));

    // A design map naming an unknown ply.
    let err = section::DesignMap::new()
        .with_named_variable(&good, "t", &[("skin", 1.0)])
        .unwrap_err();
    assert_eq!(
        err,
        SectionError::UnknownRegion {
            name: "skin".into(),
            line: None
        }
    );
}

/// Real Gmsh 4.1 output (tests/data/make_tube_meshes.py): a two-ply tube meshed with curved
/// 6-node triangles, and with mixed 8-node quadrilaterals and 6-node triangles.
#[test]
fn real_gmsh_tube_meshes() {
    let deg = std::f64::consts::PI / 180.0;
    let radial = WallFrame::Radial { centre: [0.0, 0.0] };
    let specs = |mat: laminate::OrthotropicMaterial, a: f64| {
        [
            RegionSpec {
                name: "inner".into(),
                material: mat,
                ply_angle: a,
                frame: radial,
            },
            RegionSpec {
                name: "outer".into(),
                material: mat,
                ply_angle: -a,
                frame: radial,
            },
        ]
    };
    let (ri, ro) = (0.010_f64, 0.011_f64);
    let (area, i) = (
        PI * (ro * ro - ri * ri),
        PI * (ro.powi(4) - ri.powi(4)) / 4.0,
    );
    let reference = section::tube(
        ri,
        &[
            section::PlySpec::new("inner", composite(), 30.0 * deg, 0.0005, 2),
            section::PlySpec::new("outer", composite(), -30.0 * deg, 0.0005, 2),
        ],
        96,
    )
    .unwrap();
    let reference = analyse(&reference).unwrap();
    for text in [
        include_str!("data/tube_t6.msh"),
        include_str!("data/tube_q8.msh"),
    ] {
        // Isotropic: closed forms.
        let mesh = parse_gmsh(text, &specs(isotropic(70e9, 0.3), 0.0)).unwrap();
        assert_eq!(mesh.regions.len(), 2);
        let p = analyse(&mesh).unwrap();
        let g = 70e9 / 2.6;
        assert!(rel(p.stiffness[(0, 0)], 70e9 * area) < 1e-3);
        assert!(rel(p.stiffness[(4, 4)], 70e9 * i) < 1e-3);
        assert!(rel(p.stiffness[(3, 3)], g * 2.0 * i) < 1e-3);
        // Composite [30/−30]: the generator's structured mesh.
        let mesh = parse_gmsh(text, &specs(composite(), 30.0 * deg)).unwrap();
        let p = analyse(&mesh).unwrap();
        let d = scaled_diff(&p.stiffness, &reference.stiffness, &reference.stiffness);
        assert!(d < 2e-3, "Gmsh vs generated tube: {d:e}");
    }
}

#[test]
fn a_non_finite_wall_frame_is_rejected_by_validation() {
    let plies = [section::PlySpec::new("p", composite(), 0.3, 0.0005, 1)];
    let mut mesh = section::tube(0.01, &plies, 8).unwrap();
    mesh.regions[0].frame = section::WallFrame::Radial {
        centre: [f64::NAN, 0.0],
    };
    let e = mesh.validate().unwrap_err();
    assert!(
        e.to_string().contains("region 'p'") && e.to_string().contains("not finite"),
        "{e}"
    );
}

/// A half tube (an open section) from a Gmsh file whose regions take their wall frame along the
/// elements (`ξ` or `η`): the same stiffness as the generator's radial frame, and the thin-wall
/// closed forms `EA = E₁ A` and the open-section torsion of an orthotropic strip,
/// `GJ = G₁₂ s t³/3 (1 − 0.630 (t/s) √(G₁₂/G₁₃))` (Lekhnitskii; the end correction of the
/// isotropic strip stretched by the ratio of the wall's shear moduli).
#[test]
fn open_half_tube_from_gmsh_with_element_frames_matches_the_thin_wall_closed_form() {
    // shear moduli far apart, so that a wrong wall frame shows
    let mat = laminate::OrthotropicMaterial::new(
        [128e9, 10e9, 10e9],
        [5e9, 2e9, 3e9],
        [0.25, 0.25, 0.3],
        1600.0,
    )
    .unwrap();
    let (ri, t) = (0.01, 0.001);
    let full = section::tube(ri, &[section::PlySpec::new("wall", mat, 0.0, t, 2)], 96).unwrap();
    // the upper half (x₃ > 0), nodes renumbered
    let mut keep: Vec<Element> = full
        .elements
        .iter()
        .filter(|e| e.nodes.iter().map(|&n| full.nodes[n][1]).sum::<f64>() > 0.0)
        .cloned()
        .collect();
    let mut index = vec![usize::MAX; full.nodes.len()];
    let mut nodes = Vec::new();
    for e in &mut keep {
        for n in &mut e.nodes {
            if index[*n] == usize::MAX {
                index[*n] = nodes.len();
                nodes.push(full.nodes[*n]);
            }
            *n = index[*n];
        }
    }
    let half = SectionMesh {
        nodes,
        elements: keep,
        regions: full.regions.clone(),
    };
    let text = gmsh_text(&half);
    let with = |frame: WallFrame| {
        let spec = RegionSpec {
            name: "web".into(),
            material: mat,
            ply_angle: 0.0,
            frame,
        };
        analyse(&parse_gmsh(&text, &[spec]).unwrap()).unwrap()
    };
    let radial = with(WallFrame::Radial { centre: [0.0, 0.0] });
    let along = [
        section::ElementDirection::Xi,
        section::ElementDirection::Eta,
    ]
    .map(|d| with(WallFrame::AlongElement(d)));
    // one of ξ, η runs round the wall (the other through it)
    let diff = along
        .iter()
        .map(|p| scaled_diff(&p.stiffness, &radial.stiffness, &radial.stiffness))
        .fold(f64::INFINITY, f64::min);
    assert!(diff < 1e-9, "{diff:e}");
    let p = along
        .iter()
        .find(|p| scaled_diff(&p.stiffness, &radial.stiffness, &radial.stiffness) < 1e-9)
        .unwrap();
    // closed forms of the thin open wall
    let area = PI * ((ri + t).powi(2) - ri * ri) / 2.0;
    // (quadratic edges on the circles: 4e-8)
    assert!(rel(p.area, area) < 1e-6, "{} {area}", p.area);
    let ea = p.classical_stiffness[(0, 0)];
    assert!(rel(ea, 128e9 * p.area) < 1e-9, "EA {ea:e}");
    let s = PI * (ri + t / 2.0);
    let gj_closed = 5e9 * s * t.powi(3) / 3.0 * (1.0 - 0.630 * t / s * (5.0f64 / 2.0).sqrt());
    let gj = p.classical_stiffness[(1, 1)];
    // measured: 4e-4
    assert!(rel(gj, gj_closed) < 3e-3, "GJ {gj:e} against {gj_closed:e}");
    // the x₂-aligned frame of a solid section puts G₁₃ into part of the wall's shear
    let wrong = with(WallFrame::Tangent(0.0)).classical_stiffness[(1, 1)];
    assert!(
        rel(wrong, gj_closed) > 0.1,
        "GJ with the wrong frame {wrong:e}"
    );
}
